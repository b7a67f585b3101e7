"""Skeletons: joint names, parents, rest offsets; the canonical 22 joints.

A :class:`Skeleton` is a tree of joints. ``offsets[j]`` is joint ``j``'s rest position relative to
its parent, expressed in the parent's frame (metres); ``offsets[root]`` is the root's rest position.

The canonical 22 joints are Mixamo's (``mixamorig:`` prefix stripped), as used by NKN (Villegas et
al. 2018) and TDCN (Kim et al. 2020, Sec. 5 "Data preprocessing").
:func:`~retarget_lib.io.joint_maps.to_canonical22` maps a motion on another joint set onto them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from ..errors import RetargetInputError

#: the mirror image across the YZ plane: a position's factors (``x -> -x``) and a wxyz quaternion's
#: (``(w, x, y, z) -> (w, x, -y, -z)``: a rotation about x keeps its sense, about y or z reverses)
MIRROR_POSITION = (-1.0, 1.0, 1.0)
MIRROR_QUATERNION = (1.0, 1.0, -1.0, -1.0)

CANONICAL22: tuple[str, ...] = (
    "Hips",
    "Spine",
    "Spine1",
    "Spine2",
    "Neck",
    "Head",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "LeftToeBase",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "RightToeBase",
    "LeftShoulder",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
    "RightShoulder",
    "RightArm",
    "RightForeArm",
    "RightHand",
)
CANONICAL22_PARENTS: tuple[int, ...] = (
    -1,
    0,
    1,
    2,
    3,
    4,
    0,
    6,
    7,
    8,
    0,
    10,
    11,
    12,
    3,
    14,
    15,
    16,
    3,
    18,
    19,
    20,
)
#: joint index of each canonical name
J = {name: i for i, name in enumerate(CANONICAL22)}
#: canonical index of each joint's mirror image (left <-> right)
MIRROR22: tuple[int, ...] = tuple(
    J[n.replace("Left", "#").replace("Right", "Left").replace("#", "Right")] for n in CANONICAL22
)
#: the bones summed by :meth:`Skeleton.height` (NKN/TDCN ``H``): root->head chain + left leg chain
HEIGHT_BONES: tuple[tuple[int, int], ...] = (
    (J["Spine"], J["Hips"]),
    (J["Spine1"], J["Spine"]),
    (J["Spine2"], J["Spine1"]),
    (J["Neck"], J["Spine2"]),
    (J["Head"], J["Neck"]),
    (J["LeftLeg"], J["LeftUpLeg"]),
    (J["LeftFoot"], J["LeftLeg"]),
    (J["LeftToeBase"], J["LeftFoot"]),
)

#: column order of a ``(T, 4)`` per-joint contact array (foot contacts: detection, Efoot, foot IK)
FOOT_CONTACT_JOINTS: tuple[str, ...] = ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")


class JointSetError(RetargetInputError):
    """A motion's joints cannot be mapped onto the canonical 22 (the message names the missing
    ones)."""


@dataclass
class Skeleton:
    """A joint tree with rest offsets.

    Attributes:
        joint_names: ``J`` names.
        parents: ``J`` parent indices; the root's parent is ``-1``; parents precede children.
        offsets: ``(J, 3)`` float64 rest offsets in metres (parent frame); row of the root = rest
            root position.
        end_sites: ``{joint index: (3,) offset}`` of BVH ``End Site`` leaves (kept for writing).
    """

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.joint_names = tuple(str(n) for n in self.joint_names)
        self.parents = tuple(int(p) for p in self.parents)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        n = len(self.joint_names)
        if len(self.parents) != n or self.offsets.shape[0] != n:
            raise ValueError(
                f"Skeleton: {n} names, {len(self.parents)} parents, {self.offsets.shape[0]} offsets"
            )
        if len(set(self.joint_names)) != n:
            dup = sorted({x for x in self.joint_names if self.joint_names.count(x) > 1})
            raise ValueError(f"Skeleton: duplicate joint names {dup}")
        for j, p in enumerate(self.parents):
            if (j == 0) != (p == -1) or p >= j:
                raise ValueError(
                    f"Skeleton: joint {j} ({self.joint_names[j]}) has parent {p}; "
                    "the root must be joint 0 and parents must precede children"
                )

    # ------------------------------------------------------------------ basics
    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    def index(self, name: str) -> int:
        """Index of joint ``name`` (raises ``KeyError`` naming the joint)."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r} in skeleton") from None

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def copy(self) -> Skeleton:
        return Skeleton(
            self.joint_names,
            self.parents,
            self.offsets.copy(),
            {k: v.copy() for k, v in self.end_sites.items()},
        )

    def scaled(self, factor: float) -> Skeleton:
        """The same skeleton with every length multiplied by ``factor``."""
        return Skeleton(
            self.joint_names,
            self.parents,
            self.offsets * factor,
            {k: v * factor for k, v in self.end_sites.items()},
        )

    def mirror_swap(self) -> list[int]:
        """``(J,)`` each joint's left/right partner (names with ``Left``/``Right`` swapped; itself
        when it has none): the joint order of the mirror image."""
        index = {n: i for i, n in enumerate(self.joint_names)}

        def partner(n: str) -> str:
            for a, b in (("Left", "Right"), ("Right", "Left")):
                if a in n:
                    return n.replace(a, b)
            return n

        return [index.get(partner(n), i) for i, n in enumerate(self.joint_names)]

    def mirror(self) -> Skeleton:
        """The left/right mirror image across the YZ plane (``x -> -x``): each joint takes its
        partner's offset (:meth:`mirror_swap`) with ``x`` negated; needs a symmetric joint set."""
        return Skeleton(
            self.joint_names,
            self.parents,
            self.offsets[self.mirror_swap()] * np.array(MIRROR_POSITION),
        )

    def mirror_pose(self, rotations: Any, root_positions: Any) -> tuple[Any, Any]:
        """The left/right mirror image of poses on this skeleton (or on its :meth:`mirror`: the
        joint swap is the same).

        Args:
            rotations: ``(..., J, 4)`` wxyz local rotations, numpy or torch.
            root_positions: ``(..., 3)`` root positions, the same array type.

        Returns:
            ``(rotations, root_positions)`` mirrored: joints swapped (:meth:`mirror_swap`), the
            factors :data:`MIRROR_QUATERNION` and :data:`MIRROR_POSITION` applied.
        """
        q_sign: Any = np.array(MIRROR_QUATERNION)
        r_sign: Any = np.array(MIRROR_POSITION)
        if isinstance(rotations, torch.Tensor):
            q_sign, r_sign = rotations.new_tensor(q_sign), root_positions.new_tensor(r_sign)
        return rotations[..., self.mirror_swap(), :] * q_sign, root_positions * r_sign

    def bone_lengths(self) -> np.ndarray:
        """``(J,)`` length of each joint's offset (the root's entry is its rest-position norm)."""
        return np.linalg.norm(self.offsets, axis=-1)

    def rest_positions(self) -> np.ndarray:
        """``(J, 3)`` global joint positions in the rest pose (all local rotations identity): the
        library's one rest pose, on which every rest height and the rest ground are measured
        (:mod:`retarget_lib.core.measures`)."""
        pos = np.zeros_like(self.offsets)
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] if p < 0 else pos[p] + self.offsets[j]
        return pos

    def is_canonical22(self) -> bool:
        return self.joint_names == CANONICAL22 and self.parents == CANONICAL22_PARENTS

    def height(self) -> float:
        """Character height ``H`` as defined by NKN/TDCN (Kim et al. 2020, Eqs. 11-12, 15-16).

        Sum of the rest bone lengths on the root->head chain (Hips-Spine-Spine1-Spine2-Neck-Head,
        5 bones) plus the left leg chain (LeftUpLeg-LeftLeg-LeftFoot-LeftToeBase, 3 bones), each
        the distance between the two rest joint positions. Needs the canonical joint names (any
        order). The library's one ``H``: :func:`~retarget_lib.core.measures.nkn_height` is its
        form for a batch of offset tensors, and :mod:`retarget_lib.core.measures` lists the other
        heights (standing heights for the contact thresholds).

        Returns:
            ``H`` in metres.
        """
        idx = {n: i for i, n in enumerate(self.joint_names)}
        missing = [n for n in CANONICAL22[:10] if n not in idx]
        if missing:
            raise JointSetError(f"height() needs canonical joints; missing {missing}")
        pos = self.rest_positions()
        return float(
            sum(
                np.linalg.norm(pos[idx[CANONICAL22[a]]] - pos[idx[CANONICAL22[b]]])
                for a, b in HEIGHT_BONES
            )
        )


def canonical22_skeleton(offsets: np.ndarray) -> Skeleton:
    """A :class:`Skeleton` on the canonical 22 joints with the given ``(22, 3)`` offsets."""
    return Skeleton(CANONICAL22, CANONICAL22_PARENTS, offsets)
