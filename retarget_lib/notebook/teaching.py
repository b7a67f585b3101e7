"""Teaching helpers shared by every notebook: prose rendered from computed values, and exercise checks.

Numbers in a notebook's prose must come from the cells, never be typed by hand (a typed number goes
stale the day a checkpoint changes). :func:`prose` renders a Markdown paragraph from an f-string of
computed values; :func:`check_answer` is the assert at the end of every exercise's solution cell::

    prose(f"Copy's mean error is **{copy_err:.2f} m**, {ratio:.0f}x the network's.")
    check_answer("1.2", my_height, expected=1.71, atol=0.01)
"""

from __future__ import annotations

import textwrap

import numpy as np
from IPython.display import Markdown

__all__ = ["prose", "check_answer"]


def prose(text: str) -> Markdown:
    """Markdown rendered from a (usually f-) string: dedented, so triple-quoted blocks read naturally.

    Args:
        text: Markdown; put computed values in with an f-string.

    Returns:
        an ``IPython.display.Markdown`` (the last expression of a cell shows it).
    """
    return Markdown(textwrap.dedent(text).strip())


def check_answer(exercise: str, answer, expected, rtol: float = 0.0, atol: float = 1e-6) -> bool:
    """Assert that an exercise's answer matches the expected value, and say so.

    Args:
        exercise: the exercise's label, e.g. ``"3.2"`` (named in the message).
        answer: the student's value: a number, array, bool or string.
        expected: the right value, computed independently in the solution cell.
        rtol, atol: tolerances for numbers and arrays (``numpy.allclose``).

    Returns:
        ``True`` (prints a one-line confirmation).

    Raises:
        AssertionError: naming the exercise, the answer and the expected value.
    """
    if isinstance(expected, (str, bool)) or expected is None:
        ok = answer == expected
    else:
        a, e = np.asarray(answer, dtype=float), np.asarray(expected, dtype=float)
        ok = a.shape == e.shape and bool(np.allclose(a, e, rtol=rtol, atol=atol))
    if not ok:
        raise AssertionError(f"exercise {exercise}: got {answer!r}, expected {expected!r}"
                             f" (rtol={rtol}, atol={atol})")
    print(f"exercise {exercise}: correct")
    return True
