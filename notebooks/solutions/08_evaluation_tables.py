"""Reference answers of notebook 08's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 08.K` to the next, is what the student cell of
exercise 08.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 08 --solutions` put it in.
Every value is computed from the tables the notebook loads, never typed in: they stay right when
`make tables` recomputes `results/`.
"""

# exercise 08.1
def table4_nmse(pred, truth, height):
    """Table 4's normalised MSE of one comparison.

    Args:
        pred: (T, J, 3) predicted global joint positions, metres.
        truth: (T, J, 3) ground-truth global joint positions, metres.
        height: the target's height H, metres.

    Returns:
        a float, cm² / (H in cm).
    """
    d_cm = 100.0 * (np.asarray(pred, dtype=np.float64) - np.asarray(truth, dtype=np.float64))
    squared = (d_cm**2).sum(axis=-1)  # (T, J) squared distances, cm²
    return float(squared.mean() / (100.0 * height))

# exercise 08.2
bigger_target = "up"  # a distance scales with the body: cm² / cm is a length, so the nMSE grows with it

# exercise 08.3
ours_long = per_case.loc[per_case["method"] == "ours", "long"]
top10_share = ours_long.nlargest(10).sum() / ours_long.sum()

# exercise 08.4
by_case = contact_per_case.pivot_table(index=["clip", "target"], columns="method", values="interpenetration")
residual_wins = int((by_case["Ours (residual)"] < by_case["copy-rest"]).sum())
