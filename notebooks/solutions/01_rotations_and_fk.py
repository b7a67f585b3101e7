"""Reference answers of notebook 01's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 01.K` to the next, is what the student cell of
exercise 01.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 01 --solutions` put it in.
"""

# exercise 01.1
identity = R.quat_identity((), torch.float64)
only_elbow = torch.stack([identity, bend, identity])  # shoulder, elbow, wrist
origin = torch.zeros(3, dtype=torch.float64)
wrist = forward_kinematics(only_elbow, offsets, parents, origin).positions[2].numpy()

# exercise 01.2
def fk_lab(rotations, offsets, parents, root_positions):
    """Forward kinematics with rotation matrices (column vectors: v' = M @ v).

    Args:
        rotations: (T, J, 4) local rotations, wxyz.
        offsets: (J, 3) rest offsets.
        parents: J parent indices (parents[0] = -1).
        root_positions: (T, 3).

    Returns:
        (T, J, 3) global joint positions.
    """
    local = R.quat_to_matrix(rotations)  # (T, J, 3, 3)
    G = [local[:, 0]]  # global rotation matrices, (T, 3, 3) each
    x = [root_positions]  # global positions, (T, 3) each
    for j in range(1, len(parents)):
        p = parents[j]
        x.append(x[p] + G[p] @ offsets[j])
        G.append(G[p] @ local[:, j])
    return torch.stack(x, dim=1)

# exercise 01.3
hand_moves_power = -2  # a few millimetres: about 10**-2 m (arc = radius x angle in radians)

# exercise 01.4
def two_bone_lab(rotations, offsets, parents, root_positions, chain, target, pole):
    """Two-bone IK: the end joint of `chain` on `target`, the middle joint bending towards `pole`.

    Args:
        rotations: (T, J, 4) local rotations, wxyz.
        offsets: (J, 3) rest offsets.
        parents: J parent indices.
        root_positions: (T, 3).
        chain: (upper, middle, end) joint indices; the upper joint is not the root.
        target: (T, 3) where the end joint goes.
        pole: (T, 3) the world direction the middle joint bends towards.

    Returns:
        (T, J, 4) local rotations: only the upper and middle joints' change.
    """
    upper, middle, end = chain
    positions, global_rotations = forward_kinematics(rotations, offsets, parents, root_positions)
    a, b, c = positions[:, upper], positions[:, middle], positions[:, end]
    l1 = (b - a).norm(dim=-1, keepdim=True)
    l2 = (c - b).norm(dim=-1, keepdim=True)
    to_target = target - a
    n = to_target / to_target.norm(dim=-1, keepdim=True)
    d = to_target.norm(dim=-1, keepdim=True).clamp((l1 - l2).abs(), l1 + l2)
    m = pole - (pole * n).sum(-1, keepdim=True) * n
    m = m / m.norm(dim=-1, keepdim=True)
    cos_a = ((l1**2 + d**2 - l2**2) / (2 * l1 * d)).clamp(-1.0, 1.0)
    sin_a = (1 - cos_a**2).sqrt()
    b_new = a + l1 * (cos_a * n + sin_a * m)
    c_new = a + d * n
    # turn the upper bone onto its new direction, then the (turned) lower bone onto its own
    turn_upper = R.quat_between(b - a, b_new - a)
    g_upper = R.quat_mul(turn_upper, global_rotations[:, upper])
    lower_turned = R.quat_rotate(turn_upper, c - b)
    turn_middle = R.quat_between(lower_turned, c_new - b_new)
    g_middle = R.quat_mul(turn_middle, R.quat_mul(turn_upper, global_rotations[:, middle]))
    g_parent = global_rotations[:, parents[upper]]
    out = rotations.clone()
    out[:, upper] = R.quat_mul(R.quat_conjugate(g_parent), g_upper)
    out[:, middle] = R.quat_mul(R.quat_conjugate(g_upper), g_middle)
    return out

# exercise 01.5
spine_to_head = ["Spine", "Spine1", "Spine2", "Neck", "Head"]  # the bones ending at these joints
left_leg = ["LeftLeg", "LeftFoot", "LeftToeBase"]
kato_height = lengths.loc[spine_to_head + left_leg, "kato"].sum()
