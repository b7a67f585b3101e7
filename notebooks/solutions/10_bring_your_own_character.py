"""Reference answers of notebook 10's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 10.K` to the next, is what the student cell of
exercise 10.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 10 --solutions` put it in.
"""

# exercise 10.1
def fold_weights(weights, parents, joint_map):
    """Skin weights of a rig's joints folded onto the canonical 22.

    Args:
        weights: (V, J) skin weights over the rig's J joints (each row sums to one).
        parents: J parent indices (-1 for the root; a parent comes before its children).
        joint_map: {rig joint index: canonical index} of the rig's canonical joints.

    Returns:
        (V, 22) weights in canonical order (CANONICAL22); each row still sums to one.
    """
    weights = np.asarray(weights, dtype=np.float64)
    hips = CANONICAL22.index("Hips")
    into = []  # the canonical joint each rig joint folds into; a parent's is known before its children's
    for j, p in enumerate(parents):
        if j in joint_map:
            into.append(joint_map[j])
        else:
            into.append(into[p] if p >= 0 else hips)
    folded = np.zeros((len(weights), 22))
    for j, c in enumerate(into):
        folded[:, c] += weights[:, j]
    return folded

# exercise 10.2
finger_weights_change = "same"  # a finger keeps its rest pose relative to the hand: it moves exactly as the hand

# exercise 10.3
last_keyframe = (motion_back.num_frames - 1) / motion_back.fps  # frame k is keyed at k / fps, from zero
exported_times = (last_keyframe, motion_back.duration)  # Motion.duration: n frames of 1 / fps each, n / fps
