"""Reference answers of notebook 09's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 09.K` to the next, is what the student cell of
exercise 09.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 09 --solutions` put it in.
Every value is computed from the tables the notebook loads, never typed in: they stay right when
`make tables` recomputes `results/`.
"""

# exercise 09.1
def ratio_to_ours(per_case, row, length):
    """A row's Table 4 average divided by that of "ours".

    Args:
        per_case: a DataFrame, one line per (method, pair): columns method, scenario, short, long, ...
        row: the method compared with "ours", e.g. "A3".
        length: "short" or "long", the column to average.

    Returns:
        a float: avg(row) / avg("ours"), each the mean over the scenarios of the scenario means.
    """

    def average(method):
        lines = per_case[per_case["method"] == method]
        return lines.groupby("scenario")[length].mean().mean()  # the scenarios present, each once

    return float(average(row) / average("ours"))

# exercise 09.2
interpenetration = contact_per_case.groupby(["body", "method"])["interpenetration"].mean()
eint_ratio = np.array([interpenetration[body, "Eskel+Efoot+Eint"] / interpenetration[body, "Eskel+Efoot"]
                       for body in ("skinny", "bulky")])

# exercise 09.3
pairs = per_case.pivot_table(index=["scenario", "source", "target", "clip"], columns="method", values="long")
a3_median_ratio = float((pairs["A3"] / pairs["ours"]).median())

# exercise 09.4
without_w = "up"  # w <= 1 only lowers a pair's penalty: with every pair weighted 1, the score can only grow
