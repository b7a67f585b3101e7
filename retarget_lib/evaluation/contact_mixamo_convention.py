"""Table 1's protocol on the Mixamo-convention profile: the contact-aware method where copying
rotations is nearly right.

Villegas et al. 2021 evaluate on Mixamo, where every character shares one T-pose rest and every
motion exists on every character; the synthetic Table 1 (:mod:`.contact`) uses the varied-rest
characters, where copying rotations is wrong. This table runs the same metrics
(:func:`~retarget_lib.evaluation.contact.evaluate_contact_case`) on the Mixamo-convention
characters (:mod:`~retarget_lib.data.synthetic.mixamo_convention`): a real Mixamo pair is like
these, so this is where a method must not be worse than copy (issue 24: global position error
within 1.5x copy's).

**Cases**: the pairs of the profile's TDCN split (:func:`mixamo_convention_split`, every scenario)
whose motion family is one of the evaluation profile's families
(:data:`~retarget_lib.evaluation.contact.CONTACT_PROFILES`), source and target different, at most
:data:`PAIRS_PER_FAMILY` per family (the split's order), the first ``max_frames`` frames. The
source clip is the source character's own version; its foot and hand contacts are detected on its
mesh (Sec. 3.4) and carried to the target's (App. F); the ground truth is the target's own version
(its own footsteps and hand contacts, authored on its body).
"""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from ..data.synthetic.mixamo_convention import (
    mixamo_convention_split,
    mixamo_convention_versions,
)
from ..geometry.contacts import transfer_contacts
from ..methods.contact import contact_clip
from .contact import (
    CONTACT_PROFILES,
    CONTACT_RICH,
    ContactCase,
    contact_methods,
    contact_row_checkpoints,
    evaluate_contact_methods,
    summary_table,
)
from .results import StoredResult, load_result, write_result
from .tdcn import write_table

__all__ = [
    "PAIRS_PER_FAMILY",
    "ROWS",
    "mixamo_convention_contact_cases",
    "run_mixamo_convention_contact_evaluation",
    "stored_mixamo_convention_contact_results",
]

#: the most pairs of one motion family (the ESO rows take ~6 s a 60-frame case)
PAIRS_PER_FAMILY = 4
#: the rows: the baselines, TDCN's default and both contact-aware networks with ESO
ROWS = ("copy", "copy-rest", "TDCN", "Ours (residual)", "Ours")
#: the stored per-case file (``results/``)
CASES_FILE = "contact_mixamo_convention_cases"


def mixamo_convention_contact_cases(profile: str = "fast") -> list[ContactCase]:
    """The cases of the module docstring for evaluation ``profile`` (``"fast"`` or ``"paper"``)."""
    p = CONTACT_PROFILES[profile]
    split = mixamo_convention_split()
    data = mixamo_convention_versions(
        pair
        for pairs in split.scenarios.values()
        for pair in pairs
        if pair.motion.family in p["families"]
    )
    per_family: dict[str, int] = {}
    seen, cases = set(), []
    for pairs in split.scenarios.values():
        for pair in pairs:
            family, clip = pair.motion.family, pair.motion.clip
            key = (clip, pair.source, pair.target)
            if (
                family not in p["families"]
                or pair.source == pair.target
                or key in seen
                or per_family.get(family, 0) >= PAIRS_PER_FAMILY
            ):
                continue
            seen.add(key)
            per_family[family] = per_family.get(family, 0) + 1
            source_char, target = data.characters[pair.source], data.characters[pair.target]
            motion, truth = data.clips[clip][pair.source], data.clips[clip][pair.target]
            frames = min(motion.num_frames, truth.num_frames, p["max_frames"] or motion.num_frames)
            motion = motion.slice(0, frames)
            motion.name = clip
            prepared = contact_clip(
                motion, source_char, cache_key=f"eval_mc_{pair.source}_{clip}_{frames}"
            )
            cases.append(
                ContactCase(
                    clip,
                    family,
                    source_char,
                    target,
                    prepared.motion,
                    truth.slice(0, frames),
                    prepared.foot_contacts,
                    transfer_contacts(prepared.self_contacts, source_char, target),
                    body_type="mixamo-convention",
                    contact_rich=family in CONTACT_RICH,
                )
            )
    return cases


def run_mixamo_convention_contact_evaluation(
    out_dir: str | Path,
    profile: str = "fast",
    device: str | None = None,
    command: str = "retarget evaluate --table contact --out DIR",
) -> pd.DataFrame:
    """Evaluate :data:`ROWS` on :func:`mixamo_convention_contact_cases`; write
    ``contact_mixamo_convention.csv/.md`` (the means, with each row's global position error as a
    multiple of copy's) and the per-case ``contact_mixamo_convention_cases.csv`` with provenance.

    Returns:
        the table.
    """
    t0 = time.perf_counter()
    methods, missing = contact_methods(ROWS, device)
    cases = mixamo_convention_contact_cases(profile)
    per_case = evaluate_contact_methods(methods, cases, CONTACT_PROFILES[profile]["eval_every"])
    table = summary_table(per_case, tuple(methods), {}).filter(like="ours")  # no paper values here
    copy_error = table.loc["copy", "ours global position MSE"]
    table["ours global position MSE / copy's"] = table["ours global position MSE"] / copy_error
    note = (
        "Table 1's metrics on the Mixamo-convention profile (one T-pose rest, every clip authored "
        "on every "
        f"character; ground truth = the target's own version), profile {profile}: {len(cases)} "
        "cases "
        f"({', '.join(sorted({c.family for c in cases}))}); interpenetration x1000, vertex contact "
        "MSE and "
        "global position MSE in cm^2/cm. "
        + (f"Rows without a shipped checkpoint: {', '.join(missing)}." if missing else "")
    )
    write_table(table, Path(out_dir), "contact_mixamo_convention", note)
    write_result(
        per_case,
        out_dir,
        CASES_FILE,
        command=command,
        profile=profile,
        checkpoints=contact_row_checkpoints(tuple(methods)),
        seconds=time.perf_counter() - t0,
    )
    return table


def stored_mixamo_convention_contact_results() -> StoredResult:
    """The stored per-case metrics of ``results/contact_mixamo_convention_cases.csv`` with their
    provenance and staleness (:func:`~retarget_lib.evaluation.results.load_result`)."""
    return load_result(CASES_FILE, rows=contact_row_checkpoints(ROWS))
