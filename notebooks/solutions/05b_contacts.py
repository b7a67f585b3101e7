"""Reference answers of notebook 05b's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 05b.K` to the next, is what the student cell of
exercise 05b.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 05b --solutions` put it in.
"""

# exercise 05b.1
def contact_lab(positions, skeleton, character_height):
    """Foot contacts with the ground, by Villegas et al.'s thresholds (Sec. 3.4).

    Args:
        positions: (T, J, 3) global joint positions (numpy, metres, ground at y = 0), T >= 2.
        skeleton: their Skeleton (skeleton.index(name) finds a joint).
        character_height: the character's standing height in metres.

    Returns:
        (T, 4) bool: left heel, right heel, left toe, right toe in contact.
    """
    scale = character_height / 1.80  # the paper states its thresholds for a 180 cm character
    feet = positions[:, [skeleton.index(name) for name in FOOT_JOINTS]]  # (T, 4, 3)
    moved = np.linalg.norm(feet[1:] - feet[:-1], axis=-1)  # (T - 1, 4)
    moved = np.concatenate([moved[:1], moved])  # frame 0 takes its displacement to frame 1
    raw = moved <= 0.01 * scale  # heels and toes: still
    toe_height = feet[:, 2:, 1] - foot_rest_heights(skeleton)[2:]
    raw[:, 2:] &= toe_height <= 0.03 * scale  # toes: still and low
    return fill_contacts(raw, 5)

# exercise 05b.2
flights_when_doubled = "same"  # a flight lifts the feet far above 6 cm and moves them fast: the
# jumps are found at either threshold

# exercise 05b.3
touch = ds.clip("touch_head_000")
touch_body = ds.characters[touch.performer]
touch_verts = touch_body.skinned(touch.motion.rotations, touch.motion.root_positions)
touching_only = detect_self_contacts(touch_verts, touch_body.faces, touch_body.weights,
                                     estimated_standing_height(touch_body.skeleton), cosine=1.1)
touching_only_frames = int(touching_only.frame_mask().sum())

# exercise 05b.4
pairs_now = moved.at(frame)  # (P, 2) vertex ids of gus at that frame
gap_at_frame = float(100 * np.linalg.norm(tgt_verts[frame, pairs_now[:, 0]]
                                          - tgt_verts[frame, pairs_now[:, 1]], axis=1).mean())
