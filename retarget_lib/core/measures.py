"""A character's heights, the ground under its rest pose and its feet's rest heights: one
definition each, read by every metric, loss, threshold and method.

The **rest pose** is the skeleton with identity local rotations: its ``(J, 3)`` world joint
positions are :meth:`Skeleton.rest_positions() <retarget_lib.core.skeleton.Skeleton.rest_positions>`
(the offsets summed down the tree), and a character's rest mesh is ``Character.rest_vertices``
in the same frame. Lengths and the rest ground are measured on that pose; what depends on the
character *standing* (leg length, foot heights, standing height) on its retarget pose
(:mod:`retarget_lib.core.retarget_pose`), so that a rig's rest convention does not change it.
Conventions: metres, +Y up.

The papers use three different heights, and they are kept apart here:

* **NKN/TDCN height** ``H``: the root->head and left-leg bone lengths,
  :meth:`Skeleton.height() <retarget_lib.core.skeleton.Skeleton.height>` for one skeleton (float64)
  and :func:`nkn_height` for a batch of offsets (tensors). Read by TDCN's ``Lh`` and discriminator
  inputs (Kim et al. 2020, Eqs. 9-20), Table 4's normalised MSE, the contact energies' ``h`` and
  the RNN's scale (Villegas et al. 2021, Eqs. 6, 9, App. B), the ground rule's thresholds
  (:func:`retarget_lib.core.ground.standing_feet`) and every "% of height" measure.
* **Standing height, estimated** from the skeleton: :func:`estimated_standing_height`, the
  ``Head`` joint's height times :data:`HEAD_TOP_FACTOR`. Scales Sec. 3.4's foot-contact
  thresholds (Villegas et al. 2021, "180 cm scale").
* **Standing height of the mesh**: :func:`mesh_standing_height`, the rest mesh's vertical
  extent. Scales Sec. 3.4's hand self-contact thresholds ("138 cm") and the PointNet input.

And one length: the **leg length** ``h_legs``, the hips above the lowest foot joint in the
retarget pose (:func:`skeleton_leg_length`, :func:`leg_length` for tensors), the root scale of
the ground truth, of Eq. 8 (Villegas et al. 2021) and of the residual TDCN.

The **rest ground** is :func:`rest_ground` (:func:`mesh_ground` of a mesh), and the **foot rest
heights** ``ḡ`` are :func:`foot_rest_heights` (the feet above the ground in the retarget pose,
:mod:`retarget_lib.core.retarget_pose`, the sole under them measured at rest): Efoot's ground
(Villegas et al. 2021, Eq. 6, Sec. 3.1.1), toe-contact detection, sole heights
(:mod:`retarget_lib.core.ground`) and
the synthetic clips' planted feet.

``H`` is not a standing height: it leaves out the skull above the ``Head`` joint and the foot
below the toe joint, and counts the toe bone, which is horizontal; the reference synthetic
skeleton has ``H`` = 1.56 m and stands 1.75 m.
"""

from __future__ import annotations

from typing import Any, overload

import numpy as np
import torch

from .retarget_pose import (
    pose_offsets,
    retarget_pose,
    retarget_pose_rotations,
    retarget_pose_skeleton,
    skeleton_pose_rotations,
)
from .skeleton import (
    CANONICAL22_PARENTS,
    FOOT_CONTACT_JOINTS,
    HEIGHT_BONES,
    J,
    JointSetError,
    Skeleton,
)

Tensor = torch.Tensor

__all__ = [
    "HEAD_TOP_FACTOR",
    "nkn_height",
    "leg_length",
    "skeleton_leg_length",
    "estimated_standing_height",
    "mesh_standing_height",
    "mesh_ground",
    "rest_ground",
    "foot_rest_heights",
]

#: standing height / height of the ``Head`` joint above the rest ground. The ``Head`` joint sits
#: at the base of the skull; the crown is about 12 % higher (Mixamo's Y-bot, SMPL bodies, and the
#: synthetic characters: 1.11-1.18, median 1.12).
HEAD_TOP_FACTOR = 1.12

# The height bones are (child, parent) pairs with a direct parent link, so on canonical-22 offsets
# H is a sum of offset norms.
assert all(CANONICAL22_PARENTS[c] == p for c, p in HEIGHT_BONES)
_HEIGHT_CHILDREN = [c for c, _ in HEIGHT_BONES]
_LEFT_LEG = [J[n] for n in ("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase")]
_RIGHT_LEG = [J[n] for n in ("RightUpLeg", "RightLeg", "RightFoot", "RightToeBase")]


# ----------------------------------------------------------------------------- skeleton lengths
def nkn_height(offsets: Tensor) -> Tensor:
    """The NKN/TDCN character height ``H(s̄)`` of a batch of canonical-22 rest offsets
    (Kim et al. 2020, Eqs. 11-12, 15-16, 18, after Villegas et al. 2018).

    The sum of the lengths of the :data:`~retarget_lib.core.skeleton.HEIGHT_BONES`: the
    root->head chain (5 bones) and the left leg (3 bones). The tensor form of
    :meth:`Skeleton.height() <retarget_lib.core.skeleton.Skeleton.height>` (differentiable,
    any batch shape); the two agree to rounding (the skeleton's form sums the distances between
    rest joint positions, this one the offsets' norms, about 1e-16 m apart in float64).

    Args:
        offsets: ``(..., 22, 3)`` rest offsets in canonical-22 order (metres).

    Returns:
        ``(...)`` heights in metres, in ``offsets``' dtype.
    """
    return offsets[..., _HEIGHT_CHILDREN, :].norm(dim=-1).sum(-1)


def leg_length(offsets: Tensor, pose: Tensor | None = None) -> Tensor:
    """``h_legs`` of a batch of canonical-22 rest offsets: the height of the hips above the lowest
    foot joint **in the retarget pose** (Villegas et al. 2021, Eq. 8's leg-length ratio).

    Measured in the retarget pose
    (:func:`~retarget_lib.core.retarget_pose.retarget_pose_rotations`: legs straight down, feet
    flat), so that a rig's convention does not change it: a rig resting with bent knees, splayed
    legs or lying down has the leg length it stands with. For a rig that stands straight at rest it
    is the rest height of the hips above its lowest foot joint.

    Args:
        offsets: ``(..., 22, 3)`` rest offsets in canonical-22 order (metres).
        pose: ``(..., 22, 4)`` wxyz their retarget pose if already known (default computed).

    Returns:
        ``(...)`` leg lengths in metres.
    """
    pose = retarget_pose_rotations(offsets) if pose is None else pose
    offsets = pose_offsets(offsets, pose.to(offsets.dtype))
    y = offsets[..., 1]
    left = y[..., _LEFT_LEG].cumsum(-1)  # heights below the hips, down the chain
    right = y[..., _RIGHT_LEG].cumsum(-1)
    return -torch.cat([left, right], -1).min(-1).values


def skeleton_leg_length(skeleton: Skeleton) -> float:
    """:func:`leg_length` of one canonical-22 skeleton (metres, float64): the scale of root
    motion (the ground truth's root, Villegas et al. 2021, Eq. 8's leg ratio,
    :func:`~retarget_lib.core.quantities.leg_ratio`)."""
    if not skeleton.is_canonical22():
        raise JointSetError("the leg length needs the canonical 22 joints")
    offsets = skeleton.offsets.astype(np.float64)
    pose = torch.from_numpy(skeleton_pose_rotations(offsets))
    return float(leg_length(torch.from_numpy(offsets), pose))


def _retarget_positions(skeleton: Skeleton) -> tuple[np.ndarray, bool]:
    """``(J, 3)`` the skeleton's joint positions in its retarget pose, and whether it is upright at
    rest (the pose leaves its body as it is)."""
    pose = retarget_pose(skeleton)
    upright = bool(np.allclose(pose[0], (1.0, 0.0, 0.0, 0.0)))
    return retarget_pose_skeleton(skeleton, pose).rest_positions(), upright


#: the two feet's columns in :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS` order
_FOOT_SIDES = ((0, 2), (1, 3))


def _feet_above_ground(skeleton: Skeleton, rest_vertices: np.ndarray | None) -> np.ndarray:
    """``(4,)`` each foot joint above the ground when the character stands in its retarget pose:
    each foot stands flat on its own sole, measured at rest (the rest foot joints above the rest
    ground; a rig that is not upright at rest has no sole to measure there: 0)."""
    posed, upright = _retarget_positions(skeleton)
    feet = np.array([J[n] for n in FOOT_CONTACT_JOINTS])
    rest, ground = skeleton.rest_positions(), rest_ground(skeleton, rest_vertices)
    out = np.empty(4)
    for cols in _FOOT_SIDES:
        idx = feet[list(cols)]
        sole = float(rest[idx, 1].min() - ground) if upright else 0.0
        out[list(cols)] = posed[idx, 1] - posed[idx, 1].min() + sole
    return out


# ----------------------------------------------------------------------------- standing heights
def estimated_standing_height(skeleton: Skeleton) -> float:
    """Standing height (floor to crown, metres) estimated from the skeleton alone: the ``Head``
    joint's height above the ground in the retarget pose times :data:`HEAD_TOP_FACTOR`.

    The "character height" that Villegas et al. 2021, Sec. 3.4 scales its foot-contact thresholds
    with (stated for a 180 cm character); about 12 % more than ``H``
    (:meth:`~retarget_lib.core.skeleton.Skeleton.height`).

    Args:
        skeleton: a canonical-22 skeleton.

    Returns:
        metres.
    """
    posed, _ = _retarget_positions(skeleton)
    feet = [J[n] for n in FOOT_CONTACT_JOINTS]
    ground = float((posed[feet, 1] - _feet_above_ground(skeleton, None)).min())
    return HEAD_TOP_FACTOR * float(posed[J["Head"], 1] - ground)


@overload
def mesh_standing_height(vertices: Tensor) -> Tensor: ...
@overload
def mesh_standing_height(vertices: np.ndarray) -> Any: ...
def mesh_standing_height(vertices: np.ndarray | Tensor) -> Any:
    """Standing height measured on a rest mesh: its vertical extent (top of the head minus the
    soles, metres).

    The character height of Villegas et al. 2021, Sec. 3.4's hand self-contact thresholds (stated
    for the 138 cm character) in :func:`retarget_lib.methods.contact.contact_clip`, and the scale
    of the PointNet input (:func:`retarget_lib.models.georet.normalize_rest_vertices`, ours).

    Args:
        vertices: ``(..., V, 3)`` rest vertices (metres, +Y up), NumPy or torch.

    Returns:
        ``(...)``: a float for one NumPy mesh ``(V, 3)``, else an array or a tensor
            (differentiable).
    """
    if isinstance(vertices, Tensor):
        y = vertices[..., 1]
        return y.amax(-1) - y.amin(-1)
    ys = np.asarray(vertices)[..., 1]
    height = ys.max(axis=-1) - ys.min(axis=-1)
    return float(height) if height.ndim == 0 else height


# ----------------------------------------------------------------------------- the ground
@overload
def mesh_ground(vertices: Tensor) -> Tensor: ...
@overload
def mesh_ground(vertices: np.ndarray) -> Any: ...
def mesh_ground(vertices: np.ndarray | Tensor) -> Any:
    """The ground under a rest mesh: its lowest ``y`` (the soles, metres).

    Args:
        vertices: ``(..., V, 3)`` rest vertices (metres, +Y up), NumPy or torch.

    Returns:
        ``(...)``: a float for one NumPy mesh ``(V, 3)``, else an array or a tensor.
    """
    if isinstance(vertices, Tensor):
        return vertices[..., 1].amin(-1)
    low = np.asarray(vertices)[..., 1].min(axis=-1)
    return float(low) if low.ndim == 0 else low


def rest_ground(skeleton: Skeleton, rest_vertices: np.ndarray | None = None) -> float:
    """The height of the ground under a character's rest pose (metres).

    With a rest mesh: its lowest point (:func:`mesh_ground`, the soles). Without one:
    ``min(0, lowest rest foot joint)``. A skeleton whose root offset stands it on the floor (the
    synthetic characters, mannequin-x, loaded rigs, shape files) has every foot joint at or above
    ``y = 0`` and its ground at 0; a BVH skeleton whose root sits at the origin has its feet below
    ``y = 0``, and its lowest foot joint (heel or toe) is taken as its sole.

    Args:
        skeleton: a skeleton with the canonical foot joint names
            (:data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`); its root offset places it.
        rest_vertices: ``(V, 3)`` the character's rest mesh in the same frame, if it has one.

    Returns:
        metres.
    """
    if rest_vertices is not None and len(rest_vertices):
        return mesh_ground(np.asarray(rest_vertices))
    rest = skeleton.rest_positions()
    return float(min(0.0, min(rest[skeleton.index(n), 1] for n in FOOT_CONTACT_JOINTS)))


def foot_rest_heights(skeleton: Skeleton, rest_vertices: np.ndarray | None = None) -> np.ndarray:
    """``(4,)`` heights of the heels and toes above the ground when the character stands in its
    retarget pose (metres), in :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS` order (left
    heel, right heel, left toe, right toe).

    Efoot's ``ḡ_j^y`` (Villegas et al. 2021, Eq. 6; Sec. 3.1.1: "we get the heel height from
    reference pose ... so that ground height of zero corresponds to contact"): a foot joint at
    this height above the floor is a foot standing on it. The reference pose is the retarget pose
    (:mod:`retarget_lib.core.retarget_pose`: legs straight, feet flat), each foot standing on its
    own sole: a rig that rests with bent knees, splayed legs or lying down reads the heights it
    stands with. The sole under each foot's lowest joint is measured at rest (:func:`rest_ground`:
    the mesh's lowest point where there is a mesh, else the lowest foot joint reads 0); for a rig
    upright at rest this is the rest foot joints' height above the rest ground.

    Args:
        skeleton: a canonical-22 skeleton.
        rest_vertices: ``(V, 3)`` the character's rest mesh, if it has one (the ground is then
            its lowest point).

    Returns:
        ``(4,)`` float64, >= 0 but for a joint below a mesh's lowest point (a real mesh has none).
    """
    if not skeleton.is_canonical22():
        raise JointSetError("the foot rest heights need the canonical 22 joints")
    return _feet_above_ground(skeleton, rest_vertices)
