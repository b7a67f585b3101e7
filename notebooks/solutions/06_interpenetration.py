"""Reference answers of notebook 06's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 06.K` to the next, is what the student cell of
exercise 06.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 06 --solutions` put it in.
"""

# exercise 06.1
def eint_pair(tri_r, tri_i):
    """Eq. 4's bracket for each colliding triangle pair, with w = 1 and unit normals.

    Args:
        tri_r: (P, 3, 3) the first triangle of each pair (vertex, xyz), metres, torch float64.
        tri_i: (P, 3, 3) the second triangle of each pair.

    Returns:
        (P,) psi_i(v_j)^2 summed over the vertices v_j of tri_r, plus psi_r(v_k)^2 summed over
        the vertices v_k of tri_i (cone field with SIGMA and CONE_HEIGHT), square metres.
    """

    def psi(points, triangles):
        """The cone field of `triangles` (..., 3, 3) at `points` (..., 3)."""
        c, big_r, n = circumcircle(triangles)
        to_point = points - c
        height_above = (to_point * n).sum(-1)  # > 0 in front of the triangle
        rho_sq = (to_point - height_above[..., None] * n).square().sum(-1)
        d = (-height_above).clamp(min=0.0)  # depth behind the plane
        u = torch.where(d < SIGMA, d.square() / (2 * SIGMA), d - SIGMA / 2)
        r_at_d = big_r * (1 + d / CONE_HEIGHT)
        return u * (1 - rho_sq / r_at_d.square()).clamp(min=0.0)

    # the vertices of f_r (P, 3, 3) in the field of f_i (P, 1, 3, 3), and the other way round
    in_i = psi(tri_r, tri_i[:, None])
    in_r = psi(tri_i, tri_r[:, None])
    return in_i.square().sum(-1) + in_r.square().sum(-1)

# exercise 06.2
taller_cone = "down"  # r(d) = R (1 + d / height) widens more slowly: a smaller radial factor

# exercise 06.3
def pair_weights_lab(pairs, faces, table, eta):
    """Eq. 5's weights of colliding face pairs.

    Args:
        pairs: (P, 2) int face pairs (r, i), NumPy.
        faces: (F, 3) int triangles (vertex ids).
        table: (V, V) geodesic distances D between the vertices (metres, float32).
        eta: the largest geodesic distance on the mesh (metres).

    Returns:
        (P,) w_ri, NumPy.
    """
    pairs = np.asarray(pairs)
    corners_r, corners_i = faces[pairs[:, 0]], faces[pairs[:, 1]]  # (P, 3) vertex ids each
    nearest = table[corners_r[:, :, None], corners_i[:, None, :]].min(axis=(1, 2))  # (P,)
    return nearest.astype(np.float64) / eta

# exercise 06.4
above = sweep.index[sweep["left arm inside"] > 0.35]
first_above = int(above.min())
angle_35 = next(
    a
    for a in range(first_above - 4, first_above + 1)
    if arm_inside(forearm_in_torso_pose(ada, forearm_deg=float(a), dtype=torch.float64)) > 0.35
)
