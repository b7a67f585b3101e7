"""Reference answers of notebook 07's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 07.K` to the next, is what the student cell of
exercise 07.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 07 --solutions` put it in.
"""

# exercise 07.1
def eee_lab(pos_b, pos_a, height_b, height_a):
    """Eq. 9, the end-effector term, at every frame.

    Args:
        pos_b: (..., T, 22, 3) the output's global joint positions g^B (metres, torch).
        pos_a: (..., T, 22, 3) the source's global joint positions g^A.
        height_b, height_a: the characters' heights h_B, h_A (metres, floats).

    Returns:
        (..., T) E_ee(t), zero at the first frame.
    """
    hands_and_feet = list(END_EFFECTOR_IDS)

    def velocity(g):
        """Backward differences along the frames, zero at the first one."""
        moved = g[..., 1:, :, :] - g[..., :-1, :, :]
        return torch.cat([torch.zeros_like(g[..., :1, :, :]), moved], dim=-3)

    scaled_b = velocity(pos_b[..., hands_and_feet, :]) / height_b
    scaled_a = velocity(pos_a[..., hands_and_feet, :]) / height_a
    return (scaled_b - scaled_a).square().sum(dim=(-1, -2))

# exercise 07.2
walks_further = "up"  # Eq. 9 wants the height ratio, larger than dex's leg ratio: a longer stride

# exercise 07.3
def eweak_lab(rot_b, rot_a, vel_b, vel_a, leg_ratio, rho):
    """Eq. 8, the weak supervision term, at every frame.

    Args:
        rot_b: (..., 22, 4) the output's local rotations theta^B, unit quaternions wxyz (torch).
        rot_a: (..., 22, 4) the source's local rotations theta^A.
        vel_b: (..., 3) the output's root velocity o^B (metres per frame).
        vel_a: (..., 3) the source's root velocity o^A.
        leg_ratio: h_legs_B / h_legs_A (float).
        rho: the weight of the rotation term (float).

    Returns:
        (...) E_weak of each frame.
    """
    matrix_gap = quat_to_matrix(rot_b) - quat_to_matrix(rot_a)  # (..., 22, 3, 3): q and -q agree
    rotation_term = matrix_gap.square().sum(dim=(-1, -2, -3))
    root_term = (vel_b - leg_ratio * vel_a).square().sum(dim=-1)
    return rho * rotation_term + root_term

# exercise 07.4
def pointnet_lab(vertices, weights):
    """e^B of Eq. 19 with the shipped network's MLP `mlp`.

    Args:
        vertices: (B, V, 3) rest vertices (metres, +Y up), torch float32.
        weights: (B, V, 22) their skinning weights.

    Returns:
        (B, G) one code per mesh.
    """
    low, high = vertices.amin(dim=1, keepdim=True), vertices.amax(dim=1, keepdim=True)  # (B, 1, 3)
    footprint = torch.cat(
        [(low[..., :1] + high[..., :1]) / 2, low[..., 1:2], (low[..., 2:] + high[..., 2:]) / 2], dim=-1
    )
    standing = (high[..., 1:2] - low[..., 1:2]).clamp_min(1e-6)
    per_vertex = torch.cat([(vertices - footprint) / standing, weights], dim=-1)  # (B, V, 25)
    return mlp(per_vertex).amax(dim=1)  # the max-pool over the vertices
