"""Teaching helpers shared by every notebook: prose rendered from computed values, and the old
exercise check.

Numbers in a notebook's prose must come from the cells, never be typed by hand (a typed number goes
stale the day a checkpoint changes). :func:`prose` renders a Markdown paragraph from an f-string of
computed values; :func:`check_answer` (the **old** exercise API, kept until every notebook is
converted to :mod:`retarget_lib.notebook.exercises`) judges the student's ``answer`` at the end of
every exercise's solution cell::

    prose(f"Copy's mean error is **{copy_err:.2f} m**, {ratio:.0f}x the network's.")
    check_answer("01.4", answer, expected, solution=solution, hint="H counts spine and one leg",
    atol=1e-9)
"""

from __future__ import annotations

import textwrap

import numpy as np
from IPython.display import Markdown

__all__ = ["prose", "check_answer", "NO_ANSWER"]


def prose(text: str) -> Markdown:
    """Markdown rendered from a (usually f-) string: dedented, so triple-quoted blocks read
    naturally.

    Args:
        text: Markdown; put computed values in with an f-string.

    Returns:
        an ``IPython.display.Markdown`` (the last expression of a cell shows it).
    """
    return Markdown(textwrap.dedent(text).strip())


#: what ``check_answer`` is given when the student has not answered (the student cell's ``answer =
#: None``)
NO_ANSWER = None


def _matches(value, expected, rtol: float, atol: float) -> bool:
    """Whether ``value`` is ``expected``: equal for strings, bools and None, else the same shape and
    ``numpy.allclose``; a value that is not a number where one is expected does not match."""
    if isinstance(expected, (bool, np.bool_)):
        return isinstance(value, (bool, np.bool_)) and bool(value) == bool(expected)
    if isinstance(expected, str) or expected is None:
        return (
            isinstance(value, str) and value == expected if expected is not None else value is None
        )
    if isinstance(value, (str, bool, np.bool_)) or value is None:
        return False
    try:
        a, e = np.asarray(value, dtype=float), np.asarray(expected, dtype=float)
    except (TypeError, ValueError):
        return False
    return a.shape == e.shape and bool(np.allclose(a, e, rtol=rtol, atol=atol, equal_nan=False))


def _short(value) -> str:
    """A value as the message shows it: arrays rounded to 6 significant digits, at most 200
    characters."""
    if isinstance(value, (np.ndarray, list, tuple)) and not isinstance(value, str):
        with np.printoptions(precision=6, suppress=True, threshold=20):
            text = repr(np.asarray(value))
    elif isinstance(value, (float, np.floating)):
        text = f"{float(value):.6g}"
    elif isinstance(value, np.integer):
        text = str(int(value))
    else:
        text = repr(value)
    return text if len(text) <= 200 else text[:197] + "..."


def check_answer(
    exercise: str,
    answer,
    expected,
    solution=NO_ANSWER,
    hint: str = "",
    rtol: float = 0.0,
    atol: float = 1e-6,
) -> bool:
    """Check the student's answer to an exercise against a value computed independently.

    The **old** exercise API: its solution cells show the answer in the book. New and converted
    exercises use :mod:`retarget_lib.notebook.exercises` (``check_function``, ``check_value``,
    ``check_prediction``; docs/notebooks.md, "Writing an exercise"); this stays until the notebooks
    still calling it are converted.

    The student cell ends with ``answer = None`` until the student computes ``answer``; the
    exercise's collapsed solution cell computes ``solution`` (the reference solution, in the
    library's terms) and ``expected`` (the same value by another route) and calls this. With no
    answer the reference solution is checked and shown, so the notebook runs top to bottom as
    shipped; with an answer, the answer alone is judged.

    Args:
        exercise: the exercise's label, e.g. ``"03.2"`` (named in every message).
        answer: the student's value (a number, array, bool or string), or ``None`` (not answered).
        expected: the right value, computed independently in the solution cell.
        solution: the reference solution's value, checked and shown when ``answer`` is None.
        hint: one sentence that helps a student whose answer is wrong.
        rtol, atol: tolerances for numbers and arrays (``numpy.allclose``).

    Returns:
        ``True`` (prints one line: correct, or the reference solution when there is no answer).

    Raises:
        AssertionError: a wrong answer (or a wrong reference solution), naming the exercise, the
            answer, the expected value and the hint.
    """
    tolerance = f" (rtol={rtol}, atol={atol})" if not isinstance(expected, (str, bool)) else ""
    if answer is NO_ANSWER:
        if solution is NO_ANSWER:
            raise AssertionError(
                f"exercise {exercise}: no answer and no reference solution to show"
            )
        if not _matches(solution, expected, rtol, atol):
            raise AssertionError(
                f"exercise {exercise}: the reference solution gives {_short(solution)}, expected "
                f"{_short(expected)}{tolerance}"
            )
        print(
            f"exercise {exercise}: no answer yet; the reference solution (the hidden cell) gives "
            f"{_short(solution)}, as expected. Write yours in the cell above and run both."
        )
        return True
    if not _matches(answer, expected, rtol, atol):
        raise AssertionError(
            f"exercise {exercise}: your answer {_short(answer)} is not the expected "
            f"{_short(expected)}{tolerance}" + (f". Hint: {hint}" if hint else "")
        )
    print(f"exercise {exercise}: correct")
    return True
