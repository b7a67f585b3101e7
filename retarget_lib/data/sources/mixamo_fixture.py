"""A tiny ``mixamo-local`` folder written by the library: synthetic characters exported in the
layout of a reviewer's Mixamo download, under Mixamo character and motion names.

:func:`write_mixamo_fixture` writes :data:`FIXTURE_CAST` performing :data:`FIXTURE_MOTIONS` as
:mod:`retarget_lib.data.sources.mixamo_local` expects them — ``mixamorig:`` names, five finger
chains per hand, ``HeadTop_End`` and toe end sites, centimetres, ``shape.npz`` — so that the
reviewer's path (``retarget evaluate --data mixamo-local``, ``retarget train data.source=...``)
runs, in the tests and notebook 08b, without shipping Mixamo data. It also holds what real
downloads hold: a character exported at 60 fps, skinning weights whose rows sum to 0.998, a
character missing a motion and one clip with a different frame count (so the coverage report has
something to report).

The same fixture comes in the other formats of a download (``clip_format``, ``mesh`` of
:func:`write_mixamo_fixture`): clips as ``.fbx`` (binary FBX in centimetres, as Mixamo serves
them, with the skin: :func:`~retarget_lib.io.fbx_write.save_fbx` always writes the mesh) or as
``.glb`` without a skin (Mixamo's "Without Skin" downloads, converted) or with one; the mesh as
``shape.npz`` or as a T-pose character file ``<Character>/<Character>.fbx`` / ``.glb`` holding every
Mixamo joint (fingers included). Reading the FBX variant needs the ``fbx`` extra.

Each character performs its *own* version of a motion, authored on its skeleton and mesh
(:func:`~retarget_lib.data.synthetic.motions.make_motion` with the same family and seed), as
Mixamo gives every character its own version of a clip; these versions are the ground truth.
"""

from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from ...core.character import Character
from ...core.motion import Motion
from ...core.rig import Rig
from ...core.rotations import quat_from_axis_angle
from ...core.skeleton import CANONICAL22, Skeleton, canonical22_skeleton
from ...io.bvh import save_bvh
from ...io.fbx_write import save_fbx
from ...io.gltf_write import save_glb
from ...io.shape import save_shape_npz
from ..synthetic.characters import make_character
from ..synthetic.motions import body_radii_from_mesh, make_motion
from .mixamo_local import SHAPE_FILE

__all__ = [
    "FINGERS",
    "FIXTURE_CAST",
    "FIXTURE_MOTIONS",
    "FixtureMotion",
    "CLIP_FORMATS",
    "MESH_FORMATS",
    "mixamo_skeleton",
    "extend_motion_to_mixamo",
    "mixamo_rig",
    "write_mixamo_character",
    "write_mixamo_fixture",
]

#: how :func:`write_mixamo_character` writes clips: BVH, FBX (with the skin), GLB without a skin,
#: GLB with the skin
CLIP_FORMATS = ("bvh", "fbx", "glb", "glb-skinned")
#: how it writes the character's mesh: ``shape.npz``, a T-pose ``<Character>.fbx`` or ``.glb``, or
#: not at all
MESH_FORMATS = ("shape", "fbx", "glb", "none")

FINGERS = ("Thumb", "Index", "Middle", "Ring", "Pinky")

#: Mixamo name -> synthetic character. Kaya (skinny) and Warrok (bulky) are training characters of
#: TDCN and contact targets; Claire is an unseen TDCN source; Y Bot is the contact source.
FIXTURE_CAST: dict[str, str] = {
    "Y Bot": "milo",
    "Kaya": "cleo",
    "Warrok W Kurniawan": "otto",
    "Claire": "juno",
}


class FixtureMotion(NamedTuple):
    """One motion of the fixture: Mixamo name, synthetic family and seed, frames, performers."""

    name: str
    family: str
    seed: int
    frames: int
    performers: tuple[str, ...]


#: "Praying" is not performed by Kaya (a TDCN scenario 1/2 source), so it is an unseen motion of
#: the TDCN split (:func:`retarget_lib.data.mixamo_splits.unseen_motions`); "Sitting Clap" is longer
#: than one 120-frame short chunk; "Walking" is the only motion outside the contact paper's test
#: list (a contact training clip)
FIXTURE_MOTIONS: tuple[FixtureMotion, ...] = (
    FixtureMotion("Sitting Clap", "clap", 8, 150, tuple(FIXTURE_CAST)),
    FixtureMotion("Praying", "pray", 8, 90, ("Y Bot", "Warrok W Kurniawan", "Claire")),
    FixtureMotion("Walking While Texting", "walk", 8, 60, tuple(FIXTURE_CAST)),
    FixtureMotion("Walking", "walk", 2, 70, ("Kaya", "Warrok W Kurniawan")),
)
#: the realism of real downloads: Claire at 60 fps, Kaya's weight rows summing to 0.998, Claire's
#: "Walking While Texting" two frames short (its pairs are reported as "frame counts differ"), and
#: Warrok's "Walking" exported with rest offsets 0.2 % longer than his other files
FIXTURE_FPS = {"Claire": 60.0}
FIXTURE_WEIGHT_SUM = {"Kaya": 0.998}
FIXTURE_SHORTER = {("Claire", "Walking While Texting"): 2}
FIXTURE_REST_SCALE = {("Warrok W Kurniawan", "Walking"): 1.002}


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
    (
        names.append("HeadTop_End"),
        parents.append(head),
        offsets.append(np.array([0.0, 1.8 * neck_len, 0.0])),
    )
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
                offsets.append(
                    along * (2.0 * seg if i == 1 else seg) + (sideways * spread if i == 1 else 0.0)
                )
                parent = len(names) - 1
    sk = Skeleton([prefix + n for n in names], parents, np.array(offsets))
    return sk, list(range(22))


def extend_motion_to_mixamo(
    motion: Motion, prefix: str = "mixamorig:", curl: float = 0.4
) -> Motion:
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
    finger_joints = [
        j for j, name in enumerate(sk.joint_names) if "Hand" in name and name[-1].isdigit()
    ]
    angles[:, finger_joints, 2] = curl * (0.5 + 0.5 * phase)
    rot = quat_from_axis_angle(torch.from_numpy(angles)).numpy()
    rot[:, kept] = motion.rotations
    return Motion(sk, rot, motion.root_positions.copy(), motion.fps, name=motion.name)


def mixamo_rig(
    character: Character, prefix: str = "mixamorig:", skeleton: Skeleton | None = None
) -> Rig:
    """A canonical-22 character on Mixamo's full joint set (:func:`mixamo_skeleton`: fingers, end
    joints, prefix), as in a Mixamo FBX; the extra joints carry no skinning weight.

    Args:
        character: canonical-22 character (its mesh and weights).
        prefix: joint-name prefix.
        skeleton: canonical-22 rest skeleton to extend instead of ``character.skeleton`` (a clip's).
    """
    sk, kept = mixamo_skeleton(skeleton if skeleton is not None else character.skeleton, prefix)
    weights = np.zeros((len(character.rest_vertices), sk.num_joints))
    weights[:, kept] = character.weights
    return Rig(
        character.name, sk, character.rest_vertices, character.faces, weights, {j: j for j in kept}
    )


def write_mixamo_character(
    root: str | Path,
    character: Character,
    motions: list[Motion],
    name: str | None = None,
    prefix: str = "mixamorig:",
    unit: str = "cm",
    fps: float | None = None,
    clip_format: str = "bvh",
    mesh: str = "shape",
) -> Path:
    """Write ``<root>/<name>/shape.npz`` and one BVH per motion, Mixamo style (or the other formats
    of a download: ``clip_format``, ``mesh``).

    Args:
        root: the ``mixamo-local`` folder.
        character: a :class:`~retarget_lib.core.character.Character` (canonical 22 joints).
        motions: canonical-22 motions on ``character.skeleton`` (names become file names).
        name: folder name (default ``character.name``).
        prefix: joint-name prefix.
        unit: length unit of the files (Mixamo via Blender: centimetres).
        fps: write the clips at this frame rate (resampled; default each motion's own).
        clip_format: one of :data:`CLIP_FORMATS`: ``"bvh"`` (``<Motion>.bvh`` in ``unit``),
            ``"fbx"`` (``<Motion>.fbx``, binary, centimetres, with the mesh and skin: a "With Skin"
            download), ``"glb"`` (``<Motion>.glb``, joints and animation, no skin: a "Without
            Skin" download), ``"glb-skinned"`` (``<Motion>.glb`` with the mesh and skin). GLB is
            in metres; FBX and GLB store the frame rate.
        mesh: one of :data:`MESH_FORMATS`: ``"shape"`` (``shape.npz`` in ``unit``), ``"fbx"`` /
            ``"glb"`` (``<name>.fbx`` / ``.glb``: the T-pose character with skin, all Mixamo joints,
            no animation; FBX in centimetres), ``"none"``.

    Returns:
        the character's folder.
    """
    if clip_format not in CLIP_FORMATS or mesh not in MESH_FORMATS:
        raise ValueError(
            f"clip_format must be one of {CLIP_FORMATS} and mesh one of {MESH_FORMATS}, "
            f"got {clip_format!r}, {mesh!r}"
        )
    name = name or character.name
    folder = Path(root) / name
    folder.mkdir(parents=True, exist_ok=True)
    if mesh == "shape":
        save_shape_npz(character, folder / SHAPE_FILE, unit=unit, prefix=prefix)
    elif mesh == "glb":
        save_glb(mixamo_rig(character, prefix), folder / f"{name}.glb")
    elif mesh == "fbx":
        save_fbx(mixamo_rig(character, prefix), folder / f"{name}.fbx", unit_scale_factor=1.0)
    for m in motions:
        m = m.resample(fps) if fps else m
        full = extend_motion_to_mixamo(m, prefix)
        if clip_format == "bvh":
            save_bvh(full, folder / f"{m.name}.bvh", unit=unit)
        elif clip_format == "fbx":
            save_fbx(
                mixamo_rig(character, prefix, skeleton=m.skeleton),
                folder / f"{m.name}.fbx",
                full,
                unit_scale_factor=1.0,
            )
        else:
            rig = mixamo_rig(character, prefix, skeleton=m.skeleton)
            save_glb(rig, folder / f"{m.name}.glb", full, skin=clip_format == "glb-skinned")
    return folder


def write_mixamo_fixture(root: str | Path, clip_format: str = "bvh", mesh: str = "shape") -> Path:
    """Write the fixture folder (:data:`FIXTURE_CAST` x :data:`FIXTURE_MOTIONS`) under ``root``.

    Takes about a second; write it under a temporary or cache folder, never into the repository.

    Args:
        root: the folder.
        clip_format, mesh: the files' formats (:func:`write_mixamo_character`).

    Returns:
        ``root``.
    """
    root = Path(root)
    for mixamo_name, synthetic in FIXTURE_CAST.items():
        character = make_character(synthetic)
        weight_sum = FIXTURE_WEIGHT_SUM.get(mixamo_name)
        if weight_sum is not None:  # float32 exports: every other row sums to slightly below 1
            character = character.copy()
            character.weights[::2] *= weight_sum
        radii = body_radii_from_mesh(character.skeleton, character.rest_vertices, character.weights)
        clips = []
        for m in FIXTURE_MOTIONS:
            if mixamo_name not in m.performers:
                continue
            frames = m.frames - FIXTURE_SHORTER.get((mixamo_name, m.name), 0)
            clip = make_motion(
                m.family,
                character.skeleton,
                m.seed,
                duration=(m.frames + 1) / 30.0,
                body_radii=radii,
            ).slice(0, frames)
            clip.name = m.name
            rest_scale = FIXTURE_REST_SCALE.get((mixamo_name, m.name), 1.0)
            clips.append(
                clip.with_skeleton(canonical22_skeleton(clip.skeleton.offsets * rest_scale))
            )
        write_mixamo_character(
            root,
            character,
            clips,
            name=mixamo_name,
            fps=FIXTURE_FPS.get(mixamo_name),
            clip_format=clip_format,
            mesh=mesh,
        )
    return root
