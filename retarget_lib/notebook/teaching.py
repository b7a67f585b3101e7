"""Prose rendered from computed values, shared by every notebook.

Numbers in a notebook's prose must come from the cells, never be typed by hand (a typed number goes
stale the day a checkpoint changes). :func:`prose` renders a Markdown paragraph from an f-string of
computed values::

    prose(f"Copy's mean error is **{copy_err:.2f} m**, {ratio:.0f}x the network's.")

Exercises are :mod:`retarget_lib.notebook.exercises` (docs/notebooks.md, "Writing an exercise").
"""

from __future__ import annotations

import textwrap

from IPython.display import Markdown

__all__ = ["prose"]


def prose(text: str) -> Markdown:
    """Markdown rendered from a (usually f-) string: dedented, so triple-quoted blocks read
    naturally.

    Args:
        text: Markdown; put computed values in with an f-string.

    Returns:
        an ``IPython.display.Markdown`` (the last expression of a cell shows it).
    """
    return Markdown(textwrap.dedent(text).strip())
