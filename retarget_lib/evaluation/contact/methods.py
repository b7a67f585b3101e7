"""The rows of the contact tables as methods (network, network + IK, network + ESO, registry
methods) and running them over the cases."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path

import pandas as pd

from ...core.motion import Motion
from ...data.manifest import (
    table_checkpoints,
)
from ...geometry.ik import apply_foot_contact_ik
from ...geometry.penetration import InterpenetrationEnergy
from ...losses.contact import TABLE3_ROWS as ENERGY_ROWS
from ...methods.contact import (
    load_contact_model,
    retarget_with_eso,
    retarget_with_network,
)
from ...methods.registry import get_method
from .cases import (
    EFULL_ROWS,
    ESO_ROWS,
    REGISTRY_ROWS,
    TABLE1_ROWS,
    TABLE3_ROWS,
    VARIANT_ROWS,
    ContactCase,
    evaluate_contact_case,
)

__all__ = ["contact_methods", "evaluate_contact_methods"]


# ----------------------------------------------------------------------------- methods
#: a contact method: (case, the target's Eint) -> motion on the target
ContactMethod = Callable[[ContactCase, object], Motion]


def _network_method(model) -> ContactMethod:
    return lambda case, eint: retarget_with_network(model, case.source, case.target)


def _ik_method(model) -> ContactMethod:
    return lambda case, eint: apply_foot_contact_ik(
        retarget_with_network(model, case.source, case.target), case.foot_contacts
    )


def _eso_method(model, eso_config: Mapping) -> ContactMethod:
    """A row that runs ESO: compiled (hundreds of frames per table repay the compilation)."""
    return lambda case, eint: retarget_with_eso(
        model,
        eso_config,
        case.source,
        case.target,
        case.contacts,
        eint,
        case.foot_contacts,
        name=f"{case.clip}->{case.target.name}",
        compile=True,
    )


def _skeleton_method(fn) -> ContactMethod:
    return lambda case, eint: fn(case.source, case.target.skeleton)


def contact_methods(
    rows: tuple[str, ...] = TABLE1_ROWS + TABLE3_ROWS,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
) -> tuple[dict[str, ContactMethod], list[str]]:
    """The methods of the requested table rows whose checkpoints are shipped, and the rows missing
    one (reported, never faked).

    ``device`` is where the networks and ESO run (a ``--device`` name; default the CPU); ``runs``
    maps a network row to a checkpoint trained for it (e.g. the finished rows of a ``retarget
    sweep``), used instead of the shipped one.

    Table 3's network rows (the energies of :data:`~retarget_lib.losses.contact.TABLE3_ROWS`) load
    the checkpoint the manifest lists for that row (``table: contact``); :data:`EFULL_ROWS` add IK
    or ESO to the Efull network; :data:`REGISTRY_ROWS` are registry methods with their default
    checkpoints.
    """
    shipped = table_checkpoints("contact")
    models = {}

    def model(row: str):
        if row not in models:
            models[row] = load_contact_model((runs or {}).get(row, shipped[row].id), device)
        return models[row]

    methods, missing = {}, []
    for row in dict.fromkeys(rows):
        base = EFULL_ROWS.get(row, row)
        if base in ENERGY_ROWS or base in VARIANT_ROWS:
            if base not in shipped:
                missing.append(row)
                continue
            net, cfg = model(base)
            methods[row] = (
                _eso_method(net, cfg["eso"])
                if row in ESO_ROWS
                else _ik_method(net)
                if row == "Efull + IK"
                else _network_method(net)
            )
        elif row in REGISTRY_ROWS:
            methods[row] = _skeleton_method(get_method(REGISTRY_ROWS[row]).retargeter(None, device))
        else:
            raise ValueError(f"unknown contact table row {row!r}")
    return methods, missing


# ----------------------------------------------------------------------------- tables
def evaluate_contact_methods(
    methods: Mapping[str, ContactMethod],
    cases: list[ContactCase],
    eval_every: int = 1,
    same: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Per (method, case) metrics plus the seconds each method took. ``same`` maps a row to one
    whose outputs it shares (e.g. ``"Efull + ESO" -> "Ours"``), which is then not re-run."""
    same = dict(same or {})
    eints = {}
    rows = []
    for case in cases:
        name = case.target.name
        if name not in eints:
            eints[name] = InterpenetrationEnergy(
                case.target.faces, case.target.rest_vertices, geodesic_weights=True
            )
        for row, method in methods.items():
            if row in same and same[row] in methods:
                continue
            began = time.perf_counter()
            output = method(case, eints[name])
            seconds = time.perf_counter() - began
            metrics = evaluate_contact_case(output, case, eints[name], eval_every)
            for r in [row] + [k for k, v in same.items() if v == row and k in methods]:
                rows.append(
                    {
                        "method": r,
                        "clip": case.clip,
                        "family": case.family,
                        "source": case.source_character.name,
                        "target": name,
                        "body": case.body_type,
                        "contact_rich": case.contact_rich,
                        "frames": case.source.num_frames,
                        "seconds": seconds,
                        **metrics,
                    }
                )
    return pd.DataFrame(rows)
