"""Reference answers of notebook 04's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 04.K` to the next, is what the student cell of
exercise 04.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 04 --solutions` put it in.
"""

# exercise 04.1
def align_lab(rotations, align, parents):
    """Local rotations re-expressed with per-joint alignments C (the residual variant's output).

    Args:
        rotations: (T, J, 4) local rotations q_j, unit wxyz (torch, float64).
        align: (T, J, 4) alignments C_j, unit wxyz.
        parents: J parent indices (parents[0] = -1).

    Returns:
        (T, J, 4) local rotations: C_p(j)^-1 q_j C_j, with C = identity for the root's parent.
    """
    out = quat_mul(rotations, align)  # q_j C_j
    for j, p in enumerate(parents):
        if p >= 0:  # the root's parent is the identity: nothing to undo
            out[:, j] = quat_mul(quat_conjugate(align[:, p]), out[:, j])
    return out

# exercise 04.2
cosine = np.abs((walk.rotations * jittered.rotations).sum(axis=-1))  # (T, J): q and -q are one
rotation_change_deg = float(np.degrees(2 * np.arccos(np.clip(cosine, 0.0, 1.0))).mean())

# exercise 04.3
root_error_without_lh = "up"  # Lh is what scales the root to the target; without it nothing ties
# the path to the target's size (the cycle term only asks for the way back)
