"""Evaluation of contact-aware retargeting: Tables 1, 3, 5 and 6 of Villegas et al. 2021 (Sec. 4,
App. A and D), with the paper's numbers beside ours.

**Protocol** (our analogue of the paper's, which uses Mixamo's Y-bot as an unseen skinny source and
three skinny + three bulky targets):

* source: ``mannequin-x``, a real skinned body never used in training, performing held-out clips
  (seed >= ``held_out_seed``) of contact-rich families (clap, hands on hips, pray, touch head) and
  contact-free ones;
* targets: :data:`CONTACT_TARGETS`, three skinny and three bulky synthetic characters, none of
  them a training character of the contact model;
* ground truth for the global position error: the same clip (family, seed) authored on the target
  by :func:`~retarget_lib.data.synthetic.motions.make_motion`, hand contacts solved on the target's
  own mesh (as Mixamo gives each character its own version of a motion);
* source contacts are *detected* (Sec. 3.4) and carried to the target by the App. F correspondence.

**Metrics** (Sec. 4), per (clip, target), then averaged:

* ``interpenetration``: Eq. 4 (with the geodesic weights of Eq. 5) on height-normalised vertices,
  averaged over the evaluated frames
  (:func:`~retarget_lib.geometry.penetration.interpenetration_score`); ×1000 in the tables to give
  readable magnitudes;
* ``vertex contact MSE``: for every frame with a (transferred) source contact, the squared distance
  between the two target vertices of each contact pair, in cm², divided by the target height in
  cm (the normalisation of the position error), averaged over pairs and frames;
* ``foot contact accuracy``: foot contacts detected on the output (Sec. 3.4 thresholds at the
  target's scale) against those detected on the source, share of agreeing (frame, joint) labels;
* ``global position MSE``: the NKN/TDCN normalised MSE (cm² / cm) against the ground truth;
* ``penetration rate``: share of the arm and leg vertices inside the rest of the body (mean of
  the four limbs, :func:`~retarget_lib.geometry.penetration_rate.penetration_rate`), a metric of
  later work;
* ``foot height error`` (ours): in the source's foot-contact (frame, joint) labels, the mean
  distance in cm of the output's heel or toe joint from its rest height (the ground of Eq. 6),
  :func:`foot_height_error`. The paper's foot contact accuracy counts a foot 5 cm *below* the
  floor as a contact (its toe test is "height at most 3 cm"); this column sees floating and
  sinking feet alike.

Interpenetration and the penetration rate are evaluated on every ``eval_every``-th frame (profile
``fast``: every 3rd, ``paper``: every frame).

The package: :mod:`.cases` (cases and metrics), :mod:`.methods` (the rows as methods) and
:mod:`.tables` (the tables, stored results, the command).
"""

from __future__ import annotations

from .cases import (
    CONTACT_PROFILES,
    CONTACT_RICH,
    CONTACT_SOURCE,
    CONTACT_TARGETS,
    EFULL_ROWS,
    ESO_ROWS,
    METRICS,
    REGISTRY_ROWS,
    TABLE1_ROWS,
    TABLE3_ROWS,
    VARIANT_ROWS,
    ContactCase,
    contact_case_names,
    contact_cases,
    evaluate_contact_case,
    foot_contact_accuracy,
    foot_height_error,
    foot_heights_in_contact,
    vertex_contact_mse,
)
from .methods import ContactMethod, contact_methods, evaluate_contact_methods
from .tables import (
    RERUN_FLOOR,
    RERUN_RTOL,
    TABLE3_STEPS,
    ablation_steps,
    contact_row_checkpoints,
    contact_tables,
    rerun_cases,
    rerun_tolerance,
    run_contact_evaluation,
    stored_contact_results,
    summary_table,
    write_contact_tables,
)

__all__ = [
    "CONTACT_TARGETS",
    "CONTACT_PROFILES",
    "METRICS",
    "ContactCase",
    "stored_contact_results",
    "contact_row_checkpoints",
    "rerun_cases",
    "rerun_tolerance",
    "contact_case_names",
    "contact_cases",
    "contact_methods",
    "evaluate_contact_case",
    "evaluate_contact_methods",
    "write_contact_tables",
    "vertex_contact_mse",
    "foot_contact_accuracy",
    "foot_height_error",
    "foot_heights_in_contact",
    "contact_tables",
    "summary_table",
    "TABLE3_STEPS",
    "ablation_steps",
    "run_contact_evaluation",
    "CONTACT_RICH",
    "CONTACT_SOURCE",
    "EFULL_ROWS",
    "ESO_ROWS",
    "REGISTRY_ROWS",
    "TABLE1_ROWS",
    "TABLE3_ROWS",
    "VARIANT_ROWS",
    "ContactMethod",
    "RERUN_FLOOR",
    "RERUN_RTOL",
]
