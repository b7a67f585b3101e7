"""Grouped horizontal bars for the evaluation notebooks (08, 09) and the training-budget reader."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest

from retarget_lib.viz.plots import plot_grouped_barh  # noqa: E402

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def test_grouped_barh_log_axis_legend_readable_labels_and_zero_marked():
    values = pd.DataFrame(
        {"measured": [10.0, 0.0, 0.01], "paper": [2.0, np.nan, 1.0]},
        index=["copy", "copy-rest", "Eskel+Efoot+Eint w/o w"],
    )
    ax = plot_grouped_barh(
        values, log=True, xlabel="error (log scale)", reference=1.0, reference_label="ratio 1"
    )
    assert ax.get_xscale() == "log"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:2] == ["measured", "paper"] and "ratio 1" in labels
    # 4 bars: the zero (log axis) and the NaN draw none; the zero is marked with a "0"
    assert len(ax.patches) == 4
    assert [t.get_text().strip() for t in ax.texts] == ["0"]
    ax.figure.canvas.draw()
    ticks = ax.get_yticklabels()
    assert [t.get_text() for t in ticks] == list(values.index)  # top to bottom in row order...
    assert ax.get_ylim()[0] > ax.get_ylim()[1]  # ...because the y axis is inverted
    assert all(t.get_fontsize() >= 9 and t.get_rotation() == 0 for t in ticks)
    assert all(t.get_fontsize() >= 9 for t in ax.get_xticklabels())
    # every drawn bar starts at the same left edge, below the smallest positive value
    lefts = {round(p.get_x(), 12) for p in ax.patches}
    assert len(lefts) == 1 and lefts.pop() < 0.01
    plt.close(ax.figure)


def test_grouped_barh_linear_draws_every_finite_value_from_zero():
    ax = plot_grouped_barh({"a": pd.Series([1.0, -0.5], index=["x", "y"])}, legend=False)
    assert ax.get_xscale() == "linear"
    assert [p.get_width() for p in ax.patches] == [1.0, -0.5]
    assert ax.get_legend() is None
    plt.close(ax.figure)


def test_grouped_barh_ratio_bars_start_at_the_base():
    ratios = pd.DataFrame({"here": [2.0, 0.5]}, index=["A1", "A3"])
    ax = plot_grouped_barh(ratios, log=True, base=1.0)
    assert [p.get_x() for p in ax.patches] == [1.0, 1.0]
    assert [p.get_width() for p in ax.patches] == [1.0, -0.5]  # right when worse, left when better
    lo, hi = ax.get_xlim()
    assert lo < 0.5 and hi > 2.0
    ax.figure.canvas.draw()
    assert (
        len([t for t in ax.get_xticklabels() if t.get_text()]) >= 3
    )  # 1-2-5 labels on a short log axis
    plt.close(ax.figure)


def test_training_budget_reads_each_checkpoint():
    from retarget_lib.data.checkpoints import load_state
    from retarget_lib.data.manifest import table_checkpoints
    from retarget_lib.evaluation.budget import training_budget

    budget = training_budget("contact")
    entries = table_checkpoints("contact")
    assert list(budget.index) == list(entries)
    row = budget.index[0]
    state = load_state(entries[row].id)
    assert budget.loc[row, "steps"] == state["step"]
    assert (budget["windows"] == budget["steps"] * budget["batch"]).all()
