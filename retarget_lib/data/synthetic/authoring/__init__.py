"""Motion authoring engine: keyframed, IK-solved poses made physically consistent for one character.

The motion families (:mod:`retarget_lib.data.synthetic.motions`) describe *what* is performed; this
package provides the tools they are written with (the character, :mod:`.body`; timing and easing
curves, :mod:`.timing`; the canonical pose, :mod:`.pose`; footstep plans, :mod:`.feet`; hand goals,
:mod:`.assembly`) and turns a finished :class:`Plan` into a
:class:`~retarget_lib.core.motion.Motion` (:mod:`.assembly`).

How a clip is made (so that it is physically consistent *for the given character*):

1. **Author in the retarget pose.** Joint angles are written for the character re-rested in its
   retarget pose (:func:`~retarget_lib.core.retarget_pose.retarget_pose_skeleton`: the canonical
   T-pose, spine up, legs down, arms sideways, feet flat, each character's own shape within the
   pose's tolerance kept), so "arm lowered 80 degrees" means the same world pose for an A-pose and
   a T-pose character. The angles are moved onto the real character with the ground-truth
   transfer (:func:`~retarget_lib.core.transfer.transfer_rotations`, exact here: every joint stays
   where it was authored).
   Conventions for the angles (degrees): ``fwd`` swings a limb to the front, ``down`` lowers an
   arm from the T-pose, ``bend`` flexes the spine/head forward, ``twist``/``yaw`` turn towards
   the character's left (+X).
2. **Plant the feet.** Footsteps are planned on the ground of the rest pose
   (:func:`~retarget_lib.core.measures.rest_ground`: ``y = 0`` under a character that
   stands on the floor, so its soles, not its toe joints, touch it): a planted foot is flat, still,
   and keeps its rest height above that ground; between plants the ankle follows a minimum-jerk path
   with a lift, toe-off and heel-strike pitch, never letting the toe joint under its rest height.
   The root is lowered wherever a leg could not reach, and both legs are solved with
   :func:`~retarget_lib.geometry.ik.two_bone_ik` (knees towards the toes).
3. **Make the hand contacts real.** Targets are computed from *this* character's joints plus a
   body-size hint (:func:`default_body_radii`): palms meeting in front of the chest (clap, pray),
   hands on the side of the pelvis (hands_on_hips), a hand on top of the head (touch_head), fists
   at arm's reach (punch). The arms are solved with two-bone IK, eased in and out.

:func:`assemble` fills ``Motion.meta`` with the style, body radii and contact labels described in
:mod:`retarget_lib.data.synthetic.motions`.
"""

from __future__ import annotations

from .assembly import HandGoal, Plan, assemble, contact_runs, fk, palm_targets
from .body import FPS, SIDES, HandContact, Rig, body_radii_from_mesh, default_body_radii
from .feet import Feet, Plant, foot_rot, plan_feet, still_plants, yaw_xz
from .pose import Pose
from .timing import event_times, hermite, keyframes, minjerk, noise, ramp, window

__all__ = [
    "FPS",
    "SIDES",
    "HandContact",
    "default_body_radii",
    "body_radii_from_mesh",
    "Rig",
    "minjerk",
    "ramp",
    "window",
    "keyframes",
    "noise",
    "event_times",
    "hermite",
    "Pose",
    "Plant",
    "Feet",
    "foot_rot",
    "plan_feet",
    "still_plants",
    "yaw_xz",
    "HandGoal",
    "palm_targets",
    "contact_runs",
    "Plan",
    "fk",
    "assemble",
]
