"""The notebooks' teaching helpers: prose from values, exercise checks, offline knobs."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from retarget_lib.notebook.teaching import check_answer, prose  # noqa: E402
from retarget_lib.viz import knob  # noqa: E402


def test_prose_renders_values_dedented():
    x = 0.123
    md = prose(f"""
        The error is **{x:.2f} m**.
        """)
    assert md.data == "The error is **0.12 m**."


def test_check_answer_accepts_within_tolerance_and_names_the_exercise():
    assert check_answer("1.1", np.array([1.0, 2.0 + 1e-9]), [1.0, 2.0])
    assert check_answer("1.2", "tdcn", "tdcn")
    with pytest.raises(
        AssertionError, match="exercise 1.3: your answer 1.1 is not the expected 1 .*Hint: rad"
    ):
        check_answer("1.3", 1.1, 1.0, hint="radians, not degrees", atol=0.05)
    with pytest.raises(AssertionError):  # a shape mismatch is wrong, not broadcast
        check_answer("1.4", [1.0, 1.0], 1.0)
    for wrong in (
        "1.0",
        True,
        [[1.0]],
        object(),
        float("nan"),
    ):  # never an error other than the check's
        with pytest.raises(AssertionError, match="exercise 1.5"):
            check_answer("1.5", wrong, 1.0)


def test_with_no_answer_the_reference_solution_is_checked_and_shown(capsys):
    assert check_answer("2.1", None, 3.0, solution=3.0 + 1e-9)
    assert "no answer yet" in capsys.readouterr().out
    with pytest.raises(
        AssertionError, match="exercise 2.2: the reference solution gives 4, expected 3"
    ):
        check_answer("2.2", None, 3.0, solution=4.0)
    with pytest.raises(AssertionError, match="exercise 2.3: no answer and no reference"):
        check_answer("2.3", None, 3.0)
    # an answer is judged alone: a right solution does not rescue a wrong answer
    with pytest.raises(AssertionError, match="exercise 2.4: your answer"):
        check_answer("2.4", 5.0, 3.0, solution=3.0)


def test_knob_is_offline_html_with_a_png_fallback():
    def draw(a):
        fig, ax = plt.subplots(figsize=(2, 1.5))
        ax.plot([0, 1], [0, a])
        return fig

    k = knob(draw, "alpha", [1, 2, 3], default=2)
    bundle = k._repr_mimebundle_()
    assert bundle["image/png"][:8] == b"\x89PNG\r\n\x1a\n"
    html = bundle["text/html"]
    assert html.count("data:image/png;base64,") == 3 + 1  # the three pictures + the one shown first
    assert "http" not in html  # nothing loads from the network
    assert 'value="1"' in html and "alpha = 2" in html
    assert k.pngs[1] == bundle["image/png"]
    with pytest.raises(ValueError):
        knob(draw, "alpha", [])
