"""How much training each shipped checkpoint of a table had, read from the checkpoints themselves.

The notebooks state a model's training budget next to its scores; reading it from the checkpoint
(not from a sentence typed when it was trained) keeps that statement true when a row is retrained.
"""

from __future__ import annotations

import pandas as pd

from ..data.checkpoints import load_state
from ..data.manifest import table_checkpoints

__all__ = ["training_budget"]


def training_budget(table: str) -> pd.DataFrame:
    """Training steps, batch size and training windows of every shipped checkpoint of a table.

    Args:
        table: ``"tdcn"`` (Kim et al. 2020, Table 4) or ``"contact"`` (Villegas et al. 2021, Table
            3), as in the manifest's ``table:`` field.

    Returns:
        One row per table row (manifest order): ``checkpoint`` (manifest id), ``steps`` (the step
        stored in the checkpoint), ``batch`` (its config's ``train.batch``), ``windows``
        (``steps * batch``, the number of training examples seen).
    """
    rows = {}
    for row, entry in table_checkpoints(table).items():
        state = load_state(entry.id)
        batch = int(state["config"]["train"]["batch"])
        steps = int(state["step"])
        rows[row] = {
            "checkpoint": entry.id,
            "steps": steps,
            "batch": batch,
            "windows": steps * batch,
        }
    return pd.DataFrame.from_dict(rows, orient="index")
