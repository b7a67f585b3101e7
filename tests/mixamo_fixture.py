"""A synthetic character written in the layout of a reviewer's Mixamo download (test helper).

:func:`write_mixamo_fixture` writes ``shape.npz`` and BVH files exactly as
:mod:`retarget_lib.data.sources.mixamo_local` expects them — ``mixamorig:`` names, five finger
chains per hand, ``HeadTop_End`` and toe end sites, centimetres — so the loaders are tested on what
a real download looks like without shipping Mixamo data.
"""

from pathlib import Path

import numpy as np
import torch

from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_axis_angle
from retarget_lib.core.skeleton import CANONICAL22, Skeleton
from retarget_lib.data.sources.mixamo_local import SHAPE_FILE
from retarget_lib.io.bvh import save_bvh
from retarget_lib.io.shape import save_shape_npz

FINGERS = ("Thumb", "Index", "Middle", "Ring", "Pinky")


def mixamo_skeleton(skeleton: Skeleton, prefix: str = "mixamorig:") -> tuple[Skeleton, list[int]]:
    """Add Mixamo's extra joints to a canonical-22 skeleton: finger chains, ``HeadTop_End``,
    ``*_ToeBase`` ends — and the prefix.

    Finger chains (``LeftHandThumb1..4`` ... ``LeftHandPinky1..4``) fan out from the hand along the
    forearm->hand direction, scaled to the hand's size; the ``*4`` joints and ``HeadTop_End`` /
    ``LeftToe_End`` are joints, as in Blender's export of Mixamo rigs.

    Args:
        skeleton: canonical-22 :class:`Skeleton`.
        prefix: joint-name prefix.

    Returns:
        ``(skeleton, kept)``: the extended skeleton and the index of each canonical joint in it.
    """
    if not skeleton.is_canonical22():
        raise ValueError("mixamo_skeleton needs a canonical-22 skeleton")
    names = list(CANONICAL22)
    parents = list(skeleton.parents)
    offsets = [o for o in skeleton.offsets]
    # Blender export order is depth-first, but any parent-before-child order is valid BVH.
    head = CANONICAL22.index("Head")
    neck_len = np.linalg.norm(skeleton.offsets[head])
    names.append("HeadTop_End"), parents.append(head), offsets.append(np.array([0.0, 1.8 * neck_len, 0.0]))
    for side in ("Left", "Right"):
        toe = CANONICAL22.index(f"{side}ToeBase")
        names.append(f"{side}Toe_End"), parents.append(toe)
        offsets.append(skeleton.offsets[toe] * 0.6)
        hand = CANONICAL22.index(f"{side}Hand")
        along = skeleton.offsets[hand] / np.linalg.norm(skeleton.offsets[hand])
        seg = 0.18 * np.linalg.norm(skeleton.offsets[hand])
        sideways = np.cross(along, [0.0, 0.0, 1.0])
        sideways /= max(np.linalg.norm(sideways), 1e-9)
        for k, finger in enumerate(FINGERS):
            spread = (k - 2) * 0.35 * seg
            parent = hand
            for i in range(1, 5):
                names.append(f"{side}Hand{finger}{i}")
                parents.append(parent)
                offsets.append(along * (2.0 * seg if i == 1 else seg) + (sideways * spread if i == 1 else 0.0))
                parent = len(names) - 1
    sk = Skeleton([prefix + n for n in names], parents, np.array(offsets))
    return sk, list(range(22))


def extend_motion_to_mixamo(motion: Motion, prefix: str = "mixamorig:", curl: float = 0.4) -> Motion:
    """Put a canonical-22 motion on :func:`mixamo_skeleton`; fingers curl and uncurl over time.

    Args:
        motion: canonical-22 motion.
        prefix: joint-name prefix.
        curl: maximum finger curl per joint (radians).
    """
    sk, kept = mixamo_skeleton(motion.skeleton, prefix)
    T, n = motion.num_frames, sk.num_joints
    angles = np.zeros((T, n, 3))
    phase = np.sin(np.linspace(0.0, 2.0 * np.pi, T))[:, None]
    finger_joints = [j for j, name in enumerate(sk.joint_names) if "Hand" in name and name[-1].isdigit()]
    angles[:, finger_joints, 2] = curl * (0.5 + 0.5 * phase)
    rot = quat_from_axis_angle(torch.from_numpy(angles)).numpy()
    rot[:, kept] = motion.rotations
    return Motion(sk, rot, motion.root_positions.copy(), motion.fps, name=motion.name)


def write_mixamo_fixture(root: str | Path, character, motions: list[Motion],
                         prefix: str = "mixamorig:", unit: str = "cm") -> Path:
    """Write ``<root>/<character.name>/shape.npz`` and one BVH per motion, Mixamo style.

    Args:
        root: the ``mixamo-local`` folder.
        character: a :class:`~retarget_lib.core.character.Character` (canonical 22 joints).
        motions: canonical-22 motions on ``character.skeleton`` (names become file names).
        prefix: joint-name prefix.
        unit: length unit of the files (Mixamo via Blender: centimetres).

    Returns:
        the character's folder.
    """
    folder = Path(root) / character.name
    folder.mkdir(parents=True, exist_ok=True)
    save_shape_npz(character, folder / SHAPE_FILE, unit=unit, prefix=prefix)
    for m in motions:
        save_bvh(extend_motion_to_mixamo(m, prefix), folder / f"{m.name}.bvh", unit=unit)
    return folder
