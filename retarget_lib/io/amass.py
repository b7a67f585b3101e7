"""SMPL-X / AMASS motion ``.npz`` files: read as a canonical-22
:class:`~retarget_lib.core.motion.Motion`, and write.

An AMASS-style file holds (``allow_pickle=False``; SMPL-H files alike, the first 22 joints agree):

=====================================  ============  =============================================
key                                    shape         meaning
=====================================  ============  =============================================
``poses``                              ``(T, >=66)``  axis-angle (radians), SMPL-X joint order:
                                                     ``[0:3]`` the pelvis (global orientation),
                                                     ``[3:66]`` the 21 body joints; jaw, eyes and
                                                     hands after (not read). Or ``root_orient``
                                                     ``(T, 3)`` + ``pose_body`` ``(T, 63)``.
``betas``                              ``(>=10,)``   body shape; the first 10 set the skeleton
``trans``                              ``(T, 3)``    translation (metres): pelvis = ``J_0 + trans``
``mocap_frame_rate`` / ``mocap_framerate``  scalar  frames per second (SMPL-X / SMPL-H AMASS)
``gender``, ``surface_model_type``     scalar str    kept in ``meta`` (not needed)
=====================================  ============  =============================================

**Skeleton from the betas, without SMPL-X model files:** SMPL-X rest joints are linear in the first
ten betas, ``J(b) = J_rest + D b``; the PyPI package ``mannequin-x`` ships that table
(``mannequin/assets/smplx_calibration.npz``, baked from the neutral SMPL-X model, checked here by
SHA-256) with the rest heights of the soles. The 22 body joints (:data:`SMPLX_BODY_NAMES`) are
mapped onto the canonical 22 like any file's joints
(:func:`~retarget_lib.io.joint_maps.to_canonical22`: the ``smplx`` convention of
:data:`~retarget_lib.io.rig_maps.RIG_MAPS`, one-to-one, then a joint map if one is given); hands,
jaw and eyes are dropped. The skeleton is the *neutral* model's: a gendered fit's joints differ by
millimetres (``meta["gender"]`` says which model the file was fitted with). SMPL-X's zero pose is
the library's rest pose (identity local rotations), so the file's axis-angles are the local
rotations.

**Axes.** AMASS is Z-up; the library is +Y up. ``up="z"`` turns the world by -90 degrees about X
(``(x, y, z) -> (x, z, -y)``), ``up="y"`` keeps it; ``up=None`` (default) decides from the data:
the body's up axis (the pelvis frame's +Y) points mostly along world +Z in a Z-up file.

Bounds (:class:`~retarget_lib.errors.AMASSError` / :class:`~retarget_lib.errors.LimitError`):
|betas| <= 10, at most 10,000 betas, |pose angle| <= 100 rad, frame rate 1-1000 (one number),
1,000,000 frames and at most :data:`~retarget_lib.io.untrusted.MAX_MOTION_SAMPLES` / 22 of them
(136,363: 19 minutes at 120 fps), at most 330 pose columns, file size 512 MiB. Each array's size
is read from its header and checked before it is inflated
(:func:`~retarget_lib.io.untrusted.read_npz`: a small file whose ``poses`` would inflate to
gigabytes is refused, as is a ``.npy`` file named ``.npz``).
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

import numpy as np
import torch

from ..core.motion import Motion
from ..core.rotations import quat_from_axis_angle, quat_mul, quat_rotate, quat_to_axis_angle
from ..core.skeleton import CANONICAL22, Skeleton
from ..errors import AMASSError
from ..files import DataError, atomic_write, check_sha256, readable_file
from .joint_maps import to_canonical22
from .rig_maps import JointMapLike, map_joints
from .untrusted import check_count, check_motion_samples, is_real_dtype, read_npz

__all__ = [
    "AMASSError",
    "SMPLX_CALIBRATION_SHA256",
    "SMPLX_BODY_NAMES",
    "SMPLX_BODY_PARENTS",
    "SMPLX_TO_CANONICAL",
    "smplx_skeleton",
    "load_amass",
    "save_amass",
]

#: SHA-256 of ``mannequin/assets/smplx_calibration.npz`` in mannequin-x 0.3.0
SMPLX_CALIBRATION_SHA256 = "fe149bebd6e813a67305e264bd4e5e6648652f5acdc5f3aeb15e219763dfbeca"
MAX_FILE_BYTES = 512 * 2**20
MAX_FRAMES = 1_000_000
MAX_BETA, MAX_ANGLE = 10.0, 100.0
MAX_BETAS, MAX_POSE_COLUMNS = 10_000, 330
_NUM_BETAS = 10
#: the SMPL-X (and SMPL-H) body joints in the order of a file's pose columns, and their parents
SMPLX_BODY_NAMES: tuple[str, ...] = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
)
SMPLX_BODY_PARENTS: tuple[int, ...] = (
    -1,
    0,
    0,
    0,
    1,
    2,
    3,
    4,
    5,
    6,
    7,
    8,
    9,
    9,
    9,
    12,
    13,
    14,
    16,
    17,
    18,
    19,
)


def _body_order() -> tuple[int, ...]:
    """``(22,)`` the SMPL-X body joint of each canonical joint, found by the rig conventions'
    detector."""
    found, _ = map_joints(SMPLX_BODY_NAMES, SMPLX_BODY_PARENTS, what="the SMPL-X body")
    file_of = {c: i for i, c in found.items()}
    return tuple(file_of[c] for c in range(22))


#: canonical joint c is SMPL-X body joint ``SMPLX_TO_CANONICAL[c]``
SMPLX_TO_CANONICAL: tuple[int, ...] = _body_order()
#: world rotation (wxyz) taking AMASS Z-up to the library's Y-up: -90 degrees about X
_Z_TO_Y = np.array([np.cos(-np.pi / 4), np.sin(-np.pi / 4), 0.0, 0.0])


def _calibration() -> dict[str, np.ndarray]:
    """The SMPL-X joint/sole table of mannequin-x (:class:`~retarget_lib.files.DataError` if
    missing)."""
    try:
        path = Path(
            str(importlib.resources.files("mannequin") / "assets" / "smplx_calibration.npz")
        )
    except ModuleNotFoundError:
        raise DataError(
            "the mannequin-x package is not installed; `pip install mannequin-x==0.3.0`"
        ) from None
    check_sha256(path, SMPLX_CALIBRATION_SHA256)
    with np.load(path, allow_pickle=False) as data:
        return {
            k: data[k].astype(np.float64)
            for k in ("joint_rest", "joint_dirs", "sole_y_rest", "sole_y_dirs")
        }


def _body_skeleton(betas: np.ndarray) -> Skeleton:
    """The neutral SMPL-X body with shape ``betas`` on its own joints (:data:`SMPLX_BODY_NAMES`, in
    metres, +Y up, facing +Z, the soles on ``y = 0``)."""
    cal, b = _calibration(), _first_betas(betas)
    joints = (cal["joint_rest"] + cal["joint_dirs"] @ b)[: len(SMPLX_BODY_NAMES)]
    joints[:, 1] -= (cal["sole_y_rest"] + cal["sole_y_dirs"] @ b).min()
    offsets = joints.copy()
    offsets[1:] -= joints[list(SMPLX_BODY_PARENTS[1:])]
    return Skeleton(SMPLX_BODY_NAMES, SMPLX_BODY_PARENTS, offsets)


def smplx_skeleton(
    betas: np.ndarray, mapping: JointMapLike = None, what: str = "the SMPL-X body"
) -> Skeleton:
    """The canonical-22 skeleton of the neutral SMPL-X body with shape ``betas``.

    Args:
        betas: ``(>=10,)`` shape coefficients; the first 10 are used.
        mapping: a joint map on :data:`SMPLX_BODY_NAMES` (docs/joint-maps.md), or None.
        what: the file, for messages.

    Returns:
        a canonical-22 :class:`~retarget_lib.core.skeleton.Skeleton` in metres, +Y up, facing +Z,
        the root's offset = the pelvis rest position with the soles on ``y = 0``.
    """
    body = _body_skeleton(betas)
    rest = Motion(
        body, np.tile([1.0, 0.0, 0.0, 0.0], (1, body.num_joints, 1)), body.offsets[:1].copy(), 30.0
    )
    return to_canonical22(rest, mapping=mapping, what=what).skeleton


def _pelvis_rest(betas: np.ndarray) -> np.ndarray:
    """``(3,)`` ``J_0(betas)`` in the SMPL-X model frame (before the soles are put on the floor)."""
    cal = _calibration()
    return cal["joint_rest"][0] + cal["joint_dirs"][0] @ _first_betas(betas)


def _first_betas(betas: np.ndarray) -> np.ndarray:
    """``(10,)`` the first ten betas, zero-padded."""
    b = np.zeros(_NUM_BETAS)
    b[: min(_NUM_BETAS, len(betas))] = np.asarray(betas, dtype=np.float64)[:_NUM_BETAS]
    return b


_WANTED = (
    "poses",
    "root_orient",
    "pose_body",
    "betas",
    "trans",
    "mocap_frame_rate",
    "mocap_framerate",
    "gender",
    "surface_model_type",
)
_PER_FRAME = ("poses", "root_orient", "pose_body", "trans")


def _check_shape(path: Path, key: str, shape: tuple[int, ...]) -> None:
    """Refuse, from an array's header, a size the reader cannot take (before it is inflated)."""
    if key in _PER_FRAME and shape:
        check_count(shape[0], MAX_FRAMES, f"frames of {key}", str(path))
        check_motion_samples(shape[0], len(CANONICAL22), str(path))
    if key == "poses" and len(shape) == 2:
        check_count(shape[1], MAX_POSE_COLUMNS, "pose columns", str(path))
    if key == "betas":
        check_count(int(np.prod(shape)), MAX_BETAS, "betas", str(path))


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of the file the reader uses (pickled ``gender`` / ``surface_model_type`` left
    out)."""
    return read_npz(
        path,
        _WANTED,
        AMASSError,
        objects_skipped=("gender", "surface_model_type"),
        shape_check=lambda key, shape: _check_shape(path, key, shape),
    )


def _frame_rate(a: dict[str, np.ndarray], fps: float | None, path: Path) -> float:
    """The file's frame rate (one number), else ``fps``."""
    key = next((k for k in ("mocap_frame_rate", "mocap_framerate") if k in a), None)
    if key is None:
        if fps is None:
            raise AMASSError(
                f"{path}: no frame rate: the file has no 'mocap_frame_rate' or 'mocap_framerate' "
                "key; "
                "add it (frames per second), as AMASS files have it"
            )
        rate = float(fps)
    else:
        value = np.asarray(a[key])
        if value.size != 1 or not is_real_dtype(value.dtype):
            raise AMASSError(
                f"{path}: {key} must be one number (frames per second), got {value.dtype} of shape "
                f"{value.shape}"
            )
        rate = float(value.ravel()[0])
    if not (np.isfinite(rate) and 1.0 <= rate <= 1000.0):
        raise AMASSError(f"{path}: frame rate {rate} is outside 1-1000")
    return rate


def _finite(a: np.ndarray, key: str, path: Path, bound: float) -> np.ndarray:
    if not is_real_dtype(a.dtype):
        raise AMASSError(f"{path}: {key} must be real numbers, got {a.dtype}")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise AMASSError(f"{path}: {key} holds NaN or inf")
    if np.abs(a).max(initial=0.0) > bound:
        raise AMASSError(
            f"{path}: {key} has |values| up to {np.abs(a).max():.3g}, beyond the bound {bound:g}"
        )
    return a


def load_amass(
    path: str | os.PathLike,
    up: str | None = None,
    fps: float | None = None,
    mapping: JointMapLike = None,
) -> Motion:
    """Read an SMPL-X / AMASS ``.npz`` motion onto the canonical 22 joints.

    Args:
        path: the ``.npz`` (keys in the module docstring).
        up: ``"z"`` (AMASS), ``"y"``, or ``None`` to detect it from the pelvis orientation.
        fps: frame rate to use when the file has none (``mocap_frame_rate`` / ``mocap_framerate``).
        mapping: a joint map on :data:`SMPLX_BODY_NAMES` (docs/joint-maps.md), or None.

    Returns:
        a canonical-22 :class:`~retarget_lib.core.motion.Motion` (metres, +Y up; ``rotations
        (T, 22, 4)``) on :func:`smplx_skeleton` of the file's betas; ``meta`` has ``betas``,
        ``gender``, ``up``.

    Raises:
        AMASSError: no ``betas`` (naming it: the skeleton's lengths come from them), no poses, no
            translation, no frame rate, wrong shapes, non-finite or out-of-bound values, not an
            ``.npz`` (e.g. a ``.npy``), truncated or corrupt.
        JointSetError: a bad joint map (naming the file).
        InputFileError: missing, empty or larger than 512 MiB. LimitError: too many frames, pose
            columns or betas, or an array beyond the budget (checked before it is inflated).
    """
    path = readable_file(path, "SMPL-X/AMASS .npz file", MAX_FILE_BYTES)
    a = _read_arrays(path)
    if "betas" not in a:
        raise AMASSError(
            f"{path}: no 'betas': the skeleton's bone lengths come from the body shape (an AMASS "
            "motion file has betas; a file of poses alone cannot be sized)"
        )
    betas = _finite(np.atleast_1d(a["betas"]).ravel(), "betas", path, MAX_BETA)
    if len(betas) == 0:
        raise AMASSError(f"{path}: 'betas' is empty")
    if "poses" in a:
        poses = a["poses"]
        if poses.ndim != 2 or poses.shape[1] < 66:
            raise AMASSError(
                f"{path}: poses must be (T, >=66) axis-angles (pelvis + 21 body joints), got "
                f"{poses.shape}"
            )
        poses = poses[:, :66]
    elif "root_orient" in a and "pose_body" in a:
        if (
            a["root_orient"].ndim != 2
            or a["pose_body"].ndim != 2
            or a["root_orient"].shape[1] != 3
            or a["pose_body"].shape[1] != 63
            or len(a["root_orient"]) != len(a["pose_body"])
        ):
            raise AMASSError(
                f"{path}: root_orient must be (T, 3) and pose_body (T, 63), got "
                f"{a['root_orient'].shape} "
                f"and {a['pose_body'].shape}"
            )
        poses = np.concatenate([a["root_orient"], a["pose_body"]], axis=1)
    else:
        raise AMASSError(
            f"{path}: no 'poses' (or 'root_orient' + 'pose_body'): not an SMPL-X/AMASS motion file"
        )
    poses = _finite(poses, "poses", path, MAX_ANGLE)
    if "trans" not in a:
        raise AMASSError(f"{path}: no 'trans' (the body's translation per frame)")
    trans = _finite(a["trans"], "trans", path, 1e5)
    if trans.shape != (len(poses), 3):
        raise AMASSError(f"{path}: trans must be ({len(poses)}, 3) like poses, got {trans.shape}")
    if len(poses) == 0:
        raise AMASSError(f"{path}: no frames")
    rate = _frame_rate(a, fps, path)
    local = quat_from_axis_angle(torch.from_numpy(poses.reshape(-1, 22, 3))).numpy()
    root = trans + _pelvis_rest(betas)
    if up is None:
        body_up = _rotate(local[:, 0], np.array([0.0, 1.0, 0.0])).mean(axis=0)
        up = "z" if body_up[2] > body_up[1] else "y"
    if up not in ("y", "z"):
        raise AMASSError(f"{path}: up must be 'y' or 'z', got {up!r}")
    if up == "z":
        turn = np.broadcast_to(_Z_TO_Y, local[:, 0].shape)
        local[:, 0] = quat_mul(torch.from_numpy(turn.copy()), torch.from_numpy(local[:, 0])).numpy()
        root = _rotate(turn, root)
    meta = dict(
        source=str(path),
        betas=betas,
        up=up,
        gender=_text(a.get("gender")),
        surface_model_type=_text(a.get("surface_model_type")),
    )
    return to_canonical22(
        Motion(_body_skeleton(betas), local, root, rate, name=path.stem, meta=meta),
        mapping=mapping,
        what=str(path),
    )


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(..., 3)`` vectors ``v`` rotated by quaternions ``q (..., 4)`` wxyz."""
    v = np.broadcast_to(v, q.shape[:-1] + (3,)).copy()
    return quat_rotate(torch.from_numpy(np.ascontiguousarray(q)), torch.from_numpy(v)).numpy()


def _text(value) -> str:
    if value is None:
        return ""
    item = np.asarray(value).ravel()
    return (
        "" if item.size == 0 else (item[0].decode() if isinstance(item[0], bytes) else str(item[0]))
    )


def save_amass(
    motion: Motion, path: str | os.PathLike, betas: np.ndarray, gender: str = "neutral"
) -> None:
    """Write a canonical-22 motion on :func:`smplx_skeleton` ``(betas)`` as an AMASS-style SMPL-X
    ``.npz`` (Z-up, ``poses (T, 165)`` with zero jaw/eye/hand poses; atomically).

    Args:
        motion: canonical-22, on ``smplx_skeleton(betas)`` (1 mm tolerance), +Y up.
        path: destination ``.npz``.
        betas: ``(>=10,)`` body shape (written padded to 16, as AMASS does).
        gender: stored as given.

    Raises:
        AMASSError: the motion is not on that skeleton.
    """
    skeleton = smplx_skeleton(betas)
    if (
        not motion.skeleton.is_canonical22()
        or np.abs(motion.skeleton.offsets[1:] - skeleton.offsets[1:]).max() > 1e-3
    ):
        raise AMASSError(
            f"{path}: the motion must be on smplx_skeleton(betas) (retarget it there first)"
        )
    T = motion.num_frames
    local = motion.rotations.copy()
    back = np.broadcast_to(
        _Z_TO_Y * np.array([1.0, -1.0, -1.0, -1.0]), (T, 4)
    ).copy()  # Y-up -> Z-up
    local[:, 0] = quat_mul(torch.from_numpy(back), torch.from_numpy(local[:, 0])).numpy()
    root = _rotate(back, motion.root_positions)
    body = np.zeros((T, 22, 3))
    body[:, SMPLX_TO_CANONICAL] = quat_to_axis_angle(torch.from_numpy(local)).numpy()
    poses = np.zeros((T, 165))
    poses[:, :66] = body.reshape(T, 66)
    b16 = np.zeros(16)
    b16[: min(16, len(betas))] = np.asarray(betas, dtype=np.float64)[:16]
    with atomic_write(path) as f:
        np.savez_compressed(
            f,
            poses=poses.astype(np.float32),
            betas=b16,
            trans=root - _pelvis_rest(b16),
            mocap_frame_rate=np.float64(motion.fps),
            gender=np.str_(gender),
            surface_model_type=np.str_("smplx"),
        )
