"""The contact-aware tables (Villegas et al. 2021, Tables 1, 3, 5, 6) on a reviewer's
``mixamo-local`` folder, with the appendix's protocol (App. C/D, manifest ``test_lists.contact``).

**Cases**: the source character (Y Bot) performing each motion of the appendix's list, retargeted
to each skinny and bulky target that performs the same motion with the same frame count
(:func:`~retarget_lib.evaluation.mixamo.same_length`). Every character involved needs its real
mesh (Eint, contacts and the vertex metrics use it): its ``shape.npz``, else its FBX/GLB character
file, else a clip that carries the skin
(:meth:`~retarget_lib.data.sources.mixamo_local.MixamoFolder.character`). Whatever is absent is
listed in the coverage (``contact_coverage.csv``), not raised.

**Per case**: the source clip, resampled to 30 fps, is put on the source mesh's skeleton (the
mesh file's rest offsets, which can differ slightly from the clip's); its foot and hand contacts
are detected on the source mesh (Sec. 3.4) and carried to the target mesh (App. F); the ground
truth is the target's own clip, resampled to 30 fps. The metrics are those of
:func:`~retarget_lib.evaluation.contact.evaluate_contact_case`. The evaluation profile
(:data:`~retarget_lib.evaluation.contact.CONTACT_PROFILES`) sets the frames (``fast``: the first 60
of each clip, Eint every 3rd frame; ``paper``: whole clips, every frame).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from ..data.manifest import mixamo_local_dir
from ..data.mixamo_splits import contact_lists
from ..data.sources.mixamo_local import MixamoFolder, load_mixamo_folder
from ..files import atomic_write
from ..geometry.contacts import transfer_contacts
from ..methods.contact import contact_clip
from .contact import (
    CONTACT_PROFILES,
    METRICS,
    TABLE1_ROWS,
    TABLE3_ROWS,
    ContactCase,
    contact_methods,
    contact_row_checkpoints,
    evaluate_contact_methods,
    write_contact_tables,
)
from .mixamo import METHOD_FPS, same_length
from .results import write_result

__all__ = ["mixamo_contact_cases", "run_mixamo_contact_evaluation"]


def mixamo_contact_cases(
    folder: MixamoFolder, profile: str = "fast"
) -> tuple[list[ContactCase], pd.DataFrame]:
    """The folder's contact cases and their coverage.

    Returns:
        ``(cases, coverage)``; ``coverage`` has one row per (target, motion) of the appendix with
        ``body, target, motion, status`` (``"evaluated"`` or why not).
    """
    lists, p = contact_lists(), CONTACT_PROFILES[profile]
    groups = {name: body for body in ("skinny", "bulky") for name in lists[f"{body}_targets"]}
    src_name = lists["source_character"]
    src_char = folder.character(src_name)
    targets = {name: folder.character(name) for name in groups}
    cases, rows = [], []
    for m in lists["motions"]:
        motion = m["name"]
        src_clip = folder.clips.get((src_name, motion))
        # frames -> the source's ContactClip (frame counts agree up to resampling rounding)
        prepared = {}
        for name, body in groups.items():
            truth = folder.clips.get((name, motion))
            why = (
                f"no {src_name} mesh"
                if src_char is None
                else f"no {src_name}/{motion} clip"
                if src_clip is None
                else f"no {name} mesh"
                if targets[name] is None
                else f"no {name}/{motion} clip"
                if truth is None
                else "frame counts differ"
                if not same_length(src_clip, truth)
                else "evaluated"
            )
            rows.append({"body": body, "target": name, "motion": motion, "status": why})
            if why != "evaluated":
                continue
            src30, truth30 = (
                src_clip.resample(METHOD_FPS).with_skeleton(src_char.skeleton),
                truth.resample(METHOD_FPS),
            )
            n = min(src30.num_frames, truth30.num_frames, p["max_frames"] or src30.num_frames)
            if n not in prepared:
                src30 = src30.slice(0, n)
                src30.name = motion
                prepared[n] = contact_clip(
                    src30, src_char, f"mixamo_{folder.fingerprint(src_name, motion)}_{n}"
                )
            clip, target = prepared[n], targets[name]
            cases.append(
                ContactCase(
                    motion,
                    motion,
                    src_char,
                    target,
                    clip.motion,
                    truth30.slice(0, n),
                    clip.foot_contacts,
                    transfer_contacts(clip.self_contacts, src_char, target),
                    body_type=body,
                    contact_rich=len(clip.self_contacts) > 0,
                )
            )
    return cases, pd.DataFrame(rows)


def run_mixamo_contact_evaluation(
    out_dir: str | Path,
    root: str | Path | None = None,
    profile: str = "fast",
    rows: Sequence[str] | None = None,
) -> tuple[dict[str, pd.DataFrame], pd.DataFrame, list[str]]:
    """Tables 1, 3, 5, 6 on a ``mixamo-local`` folder; writes ``contact_table{1,3,5,6}.csv/.md``,
    ``contact_cases.csv`` and ``contact_coverage.csv`` into ``out_dir``.

    Args:
        out_dir: output folder.
        root: the folder (default ``$RETARGET_MIXAMO`` or the manifest's path).
        profile: ``"fast"`` or ``"paper"`` (frames per clip, Eint sampling).
        rows: the table rows to evaluate (default every Table 1/3 row with a shipped checkpoint).

    Returns:
        ``(tables, coverage, missing_rows)``.
    """
    t0 = time.perf_counter()
    folder = load_mixamo_folder(root if root is not None else mixamo_local_dir())
    cases, coverage = mixamo_contact_cases(folder, profile)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_write(out / "contact_coverage.csv", "w") as f:
        coverage.to_csv(f, index=False)
    methods, missing = contact_methods(tuple(rows) if rows else TABLE1_ROWS + TABLE3_ROWS)
    per_case = evaluate_contact_methods(
        methods,
        cases,
        CONTACT_PROFILES[profile]["eval_every"],
        same={"Efull + ESO": "Ours", "Efull-residual + ESO": "Ours (residual)"},
    )
    if per_case.empty:  # no case: empty tables (the paper's numbers only) and the coverage
        per_case = pd.DataFrame(columns=["method", "body", *METRICS], dtype=float)
    evaluated = coverage[coverage["status"] == "evaluated"]
    note = (
        f"Contact-aware retargeting on the mixamo-local folder {folder.root}, profile {profile}: "
        "source "
        f"{contact_lists()['source_character']}, {len(cases)} (motion, target) cases of the "
        "appendix's "
        f"{len(coverage)} ({len(evaluated['motion'].unique())} motions; the rest: "
        "contact_coverage.csv). "
        "Ground truth = each target's own clip. Interpenetration x1000, vertex contact MSE and "
        "global position "
        "MSE in cm^2/cm; 'paper' columns: Villegas et al. 2021. "
        + (f"Rows without a shipped checkpoint: {', '.join(missing)}." if missing else "")
    )
    tables = write_contact_tables(per_case, out, note)
    write_result(
        per_case,
        out,
        "contact_cases",
        profile=profile,
        seconds=time.perf_counter() - t0,
        command=f"retarget evaluate --table contact --data mixamo-local --profile {profile} --out "
        "DIR",
        checkpoints=contact_row_checkpoints(tuple(per_case["method"].unique())),
    )
    return tables, coverage, missing
