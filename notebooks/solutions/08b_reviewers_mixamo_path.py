"""Reference answers of notebook 08b's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 08b.K` to the next, is what the student cell of
exercise 08b.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 08b --solutions` put it in.
The exercises run on the folder the notebook loads (the library's fixture without a download).
"""

# exercise 08b.1
def pose_only_nmse(pred, truth, height):
    """The normalised MSE of the root-relative joint positions.

    Args:
        pred: (T, J, 3) predicted global joint positions, metres; joint 0 is the root.
        truth: (T, J, 3) ground-truth global joint positions, metres.
        height: the target's height H, metres.

    Returns:
        a float, cm² / (H in cm).
    """
    pred, truth = np.asarray(pred, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    relative_pred = pred - pred[:, :1]  # every joint of a frame minus that frame's root
    relative_truth = truth - truth[:, :1]
    d_cm = 100.0 * (relative_pred - relative_truth)
    return float((d_cm**2).sum(axis=-1).mean() / (100.0 * height))

# exercise 08b.2
def scenario_average(nmse, scenario):
    """Table 4's average of per-case values.

    Args:
        nmse: (N,) the cases' values.
        scenario: (N,) each case's scenario, an integer from 1 to 4.

    Returns:
        a float: the mean, over the scenarios that have cases, of each scenario's mean.
    """
    nmse, scenario = np.asarray(nmse, dtype=np.float64), np.asarray(scenario)
    means = [nmse[scenario == s].mean() for s in np.unique(scenario)]  # the scenarios present
    return float(np.mean(means))

# exercise 08b.3
unscaled_root_pose_error = "same"  # the pose-only error subtracts the root: its path cannot change it
