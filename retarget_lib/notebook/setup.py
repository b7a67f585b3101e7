"""``setup_notebook()``: the one call at the top of every notebook."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
import torch

from .. import viz
from ..config import active_profile
from ..files import REPO_ROOT
from ..training.loop import seed_everything


@dataclass(frozen=True)
class NotebookContext:
    """What :func:`setup_notebook` set up.

    Attributes:
        seed: the seed given to ``random``, NumPy and torch.
        profile: ``"fast"`` (CI, workshops) or ``"paper"`` (``$RETARGET_PROFILE``).
        rng: a NumPy ``Generator`` seeded with ``seed`` for the notebook's own sampling.
        figures: folder for files a notebook writes (GIFs, MP4s): ``<repo>/build/figures``.
    """

    seed: int
    profile: str
    rng: np.random.Generator
    figures: Path


def setup_notebook(seed: int = 0, threads: int | None = None) -> NotebookContext:
    """Seed everything, configure offscreen rendering and display options.

    Args:
        seed: seed for ``random``, NumPy and torch (each notebook states its own).
        threads: torch CPU threads (default: all cores).

    Returns:
        A :class:`NotebookContext`.
    """
    seed_everything(seed)
    if threads:
        torch.set_num_threads(threads)
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    viz.configure_offscreen()
    matplotlib.rcParams.update(
        {
            "figure.dpi": 80,
            "savefig.dpi": 80,
            "figure.figsize": (7.0, 3.5),
            "axes.grid": True,
            "grid.alpha": 0.3,
        }
    )
    pd.set_option("display.precision", 3)
    pd.set_option("display.max_rows", 60)
    np.set_printoptions(precision=4, suppress=True)
    torch.set_printoptions(precision=4, sci_mode=False)
    figures = REPO_ROOT / "build" / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    return NotebookContext(seed, active_profile(), np.random.default_rng(seed), figures)
