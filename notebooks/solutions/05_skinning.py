"""Reference answers of notebook 05's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 05.K` to the next, is what the student cell of
exercise 05.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 05 --solutions` put it in.
"""

# exercise 05.1
def lbs_lab(rest_vertices, weights, rest_joint_positions, joint_rotations, joint_positions):
    """Linear blend skinning: the rest mesh posed by its joints' global transforms.

    Args:
        rest_vertices: (V, 3) rest-pose vertices (torch, float64, metres).
        weights: (V, J) skinning weights, each row summing to 1.
        rest_joint_positions: (J, 3) the joints' rest positions.
        joint_rotations: (T, J, 4) the posed joints' global rotations, unit wxyz.
        joint_positions: (T, J, 3) the posed joints' global positions.

    Returns:
        (T, V, 3) posed vertices.
    """
    # sum_j w_vj (R_j (v - x̄_j) + x_j) = (sum_j w_vj R_j) v + sum_j w_vj (x_j - R_j x̄_j):
    # blend each joint's affine map first, then apply one blended map per vertex
    matrices = quat_to_matrix(joint_rotations)  # (T, J, 3, 3)
    shifts = joint_positions - (matrices @ rest_joint_positions[..., None])[..., 0]  # (T, J, 3)
    blended_matrices = torch.einsum("vj,tjab->tvab", weights, matrices)  # (T, V, 3, 3)
    blended_shifts = torch.einsum("vj,tja->tva", weights, shifts)  # (T, V, 3)
    return (blended_matrices @ rest_vertices[..., None])[..., 0] + blended_shifts

# exercise 05.2
blend_zone_distance = "down"  # a weighted mean of two points of a sphere lies inside it (LBS's
# "collapsing elbow": the blend zone thins as the joint bends)

# exercise 05.3
share_no_group = float((mannequin.weights.max(axis=1) < 0.5).mean())

# exercise 05.4
within_2cm = float((errors["weights + T-pose offsets"] < 2.0).mean())
