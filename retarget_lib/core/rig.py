"""The skinned rig: a character on its *own* joint set (fingers, twist bones, a ``root`` above the
hips), with the map of its joints onto the canonical 22.

A :class:`Rig` is what a glTF/GLB or FBX character file holds. The methods work on the canonical
22 (:meth:`Rig.character`: weights of unmapped joints folded into their nearest mapped ancestor);
a canonical result is put back on the rig's joints with :meth:`Rig.motion_from_canonical`
(unmapped joints keep their rest pose relative to their parent), so a file written from a
:class:`Rig` keeps the target's own joints, mesh and skin.

Conventions as everywhere in the library: metres, +Y up, facing +Z, rest pose = identity local
rotations (the rest pose lives in the skeleton's world-axis offsets).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from .canonical import fold_to_canonical22, unfold_from_canonical22
from .character import Character
from .motion import Motion
from .skeleton import CANONICAL22, CANONICAL22_PARENTS, Skeleton, canonical22_skeleton
from .skinning import linear_blend_skinning
from .virtual_joints import MAY_BE_ABSENT, with_virtual_joints

__all__ = ["Rig"]


@dataclass
class Rig:
    """A skinned character on any joint tree, mapped onto the canonical 22.

    Attributes:
        name: identifier (the file's stem, a character name).
        skeleton: the rig's full :class:`~retarget_lib.core.skeleton.Skeleton` (``J`` joints,
            world-axis rest offsets in metres; the root's offset is its rest position).
        rest_vertices: ``(V, 3)`` float64 world rest-pose vertices (metres).
        faces: ``(F, 3)`` int64 triangles.
        weights: ``(V, J)`` float64 skinning weights over the rig's joints, rows summing to 1.
        joint_map: ``{rig joint index: canonical index}``: every canonical joint once, but those of
            :data:`~retarget_lib.core.virtual_joints.MAY_BE_ABSENT` the rig may lack (a joint map's
            ``null``), which the canonical views insert as virtual joints.
        meta: where it came from (file, rig naming that matched, ...).
    """

    name: str
    skeleton: Skeleton
    rest_vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    joint_map: dict[int, int]
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.rest_vertices = np.asarray(self.rest_vertices, dtype=np.float64)
        self.faces = np.asarray(self.faces, dtype=np.int64)
        self.weights = np.asarray(self.weights, dtype=np.float64)
        nv, nj = len(self.rest_vertices), self.skeleton.num_joints
        if self.rest_vertices.shape != (nv, 3) or self.weights.shape != (nv, nj):
            raise ValueError(
                f"rig {self.name!r}: rest_vertices {self.rest_vertices.shape} and weights "
                f"{self.weights.shape} must be (V, 3) and (V, {nj})"
            )
        mapped = sorted(self.joint_map.values())
        absent = {CANONICAL22[c] for c in set(range(22)) - set(mapped)}
        if len(set(mapped)) != len(mapped) or not absent <= set(MAY_BE_ABSENT):
            raise ValueError(
                f"rig {self.name!r}: joint_map must give each canonical joint once; only "
                f"{', '.join(MAY_BE_ABSENT)} may be absent (missing: {sorted(absent)})"
            )

    @classmethod
    def from_character(cls, character: Character) -> Rig:
        """A canonical-22 character as a rig (identity joint map)."""
        return cls(
            character.name,
            character.skeleton.copy(),
            character.rest_vertices.copy(),
            character.faces.copy(),
            character.weights.copy(),
            {c: c for c in range(22)},
            dict(character.style),
        )

    def canonical_of(self) -> np.ndarray:
        """``(J,)`` the canonical joint each rig joint's weights fold into: its own when mapped,
        else its nearest mapped ancestor's, else the hips (joints above the hips)."""
        out = np.full(self.skeleton.num_joints, CANONICAL22.index("Hips"))
        for j, p in enumerate(self.skeleton.parents):
            if j in self.joint_map:
                out[j] = self.joint_map[j]
            elif p >= 0:
                out[j] = out[p]
        return out

    def _with_virtual_joints(self, motion: Motion) -> tuple[Motion, dict[int, int]]:
        """``motion`` on the rig's joints with the absent canonical ones inserted, and the full
        map."""
        return with_virtual_joints(motion, self.joint_map)

    def character(self) -> Character:
        """The canonical-22 :class:`~retarget_lib.core.character.Character` the methods use:
        mapped joints' rest positions (absent ones placed as virtual joints), weights of unmapped
        joints folded (:meth:`canonical_of`)."""
        rest_motion = Motion(
            self.skeleton,
            np.tile([1.0, 0.0, 0.0, 0.0], (1, self.skeleton.num_joints, 1)),
            self.skeleton.offsets[:1].copy(),
            30.0,
        )
        augmented, full = self._with_virtual_joints(rest_motion)
        rest = augmented.skeleton.rest_positions()
        file_of = {c: j for j, c in full.items()}
        rest22 = rest[[file_of[c] for c in range(22)]]
        offsets = rest22.copy()
        offsets[1:] -= rest22[list(CANONICAL22_PARENTS[1:])]
        weights = np.zeros((len(self.weights), 22))
        np.add.at(weights.T, self.canonical_of(), self.weights.T)
        return Character(
            self.name,
            canonical22_skeleton(offsets),
            self.rest_vertices.copy(),
            self.faces.copy(),
            weights,
            style=dict(self.meta),
        )

    def motion_to_canonical(self, motion: Motion) -> Motion:
        """Fold a motion on the rig's joints onto the canonical 22 (see ``fold_to_canonical22``;
        absent joints inserted as virtual ones first)."""
        return fold_to_canonical22(motion, self.joint_map)

    def motion_from_canonical(self, motion: Motion) -> Motion:
        """A canonical-22 motion on the rig's joints: mapped joints take the canonical rotations,
        the others keep their rest pose relative to their parent (see
        ``unfold_from_canonical22``)."""
        return unfold_from_canonical22(motion, self.skeleton, self.joint_map)

    def posed_vertices(self, motion: Motion) -> np.ndarray:
        """``(T, V, 3)`` the mesh skinned by a motion on the rig's joints (linear blend
        skinning)."""
        fk = motion.fk()
        return linear_blend_skinning(
            self.rest_vertices,
            self.weights,
            self.skeleton.rest_positions(),
            torch.from_numpy(fk.rotations),
            torch.from_numpy(fk.positions),
        ).numpy()
