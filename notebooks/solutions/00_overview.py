"""Reference answers of notebook 00's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 00.K` to the next, is what the student cell of
exercise 00.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 00 --solutions` put it in.
"""

# exercise 00.1
height_ratio = characters["H (m)"].max() / characters["H (m)"].min()

# exercise 00.2
both_planted = walk.foot_contacts[:, 0] & walk.foot_contacts[:, 1]  # (T,) booleans
double_support = int(both_planted.sum())

# exercise 00.3
run_clips = ds.family("run")
steps = [np.diff(c.motion.root_positions[:, [0, 2]], axis=0) for c in run_clips]  # (T-1, 2) each
run_metres = sum(float(np.hypot(s[:, 0], s[:, 1]).sum()) for s in steps)
run_speed = run_metres / sum(c.motion.duration for c in run_clips)

# exercise 00.4
# the 30 fps frames are every fourth frame of the file, and a path through more points of the same
# curve is never shorter (the triangle inequality); between two 30 fps frames the root sways
path_at_file_rate = "up"  # longer: more samples of the same swaying path
