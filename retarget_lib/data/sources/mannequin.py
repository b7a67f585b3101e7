"""The ``mannequin-x`` source: a dense skinned wooden body (PyPI ``mannequin-x`` 0.3.0, Apache-2.0).

The package ships ``mannequin/assets/wooden.npz``: 24,256 vertices in 29 closed pieces (body
blocks and ball joints), skinned to 54 SMPL-X-style joints (22 body joints, two hand roots, 30
finger joints) with up to 8 influences per vertex. What its arrays mean, as checked here:

* ``skin_source_joint_positions (54, 3)`` are the joints' rest positions in the vertices' frame
  (metres, +Y up, facing +Z, the body's left at +X): the bind pose of the skin.
* ``local_offsets (54, 3)`` with ``rest_local_rotations (54, 3, 3)`` give the same skeleton by
  forward kinematics, shifted by a constant translation. Baking the rest rotations (each offset
  rotated by its parent's global rest rotation) yields world-axis offsets, so that identity local
  rotations reproduce the bind pose — the library's rest-pose convention. :func:`load_mannequin`
  verifies this and takes the offsets from the bind positions.
* The package's own skinning keeps each vertex's 4 strongest influences (renormalised) and binds
  the vertices listed in ``skin_rigid_joint_indices`` rigidly to one joint; the same is done here.

The first 22 joints follow the SMPL-X body order and map one-to-one onto the canonical 22
(:data:`~retarget_lib.io.amass.SMPLX_TO_CANONICAL`, by the rig conventions' detector); hand roots
and fingers are folded into the wrists.
The body is lifted so that its soles rest on ``y = 0``.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

import numpy as np

from ...core.character import Character
from ...core.measures import mesh_ground
from ...core.skeleton import CANONICAL22, CANONICAL22_PARENTS, canonical22_skeleton
from ...files import DataError, check_sha256
from ...io.amass import SMPLX_TO_CANONICAL

__all__ = ["MANNEQUIN_SHA256", "load_mannequin", "mannequin_path"]

#: SHA-256 of ``mannequin/assets/wooden.npz`` in mannequin-x 0.3.0
MANNEQUIN_SHA256 = "dfc62377f4a3ff21b50b0b4e5e2660be6dd4f7e085fac02f1327af2fe152600e"

_INSTALL = "install it with `pip install mannequin-x==0.3.0` (Apache-2.0)"
_BODY_JOINTS = 22
_INFLUENCES = 4


def mannequin_path() -> Path:
    """Path of the installed ``wooden.npz``.

    Raises:
        DataError: if the package or its asset is missing.
    """
    try:
        path = Path(str(importlib.resources.files("mannequin") / "assets" / "wooden.npz"))
    except ModuleNotFoundError:
        raise DataError(f"the mannequin-x package is not installed; {_INSTALL}") from None
    if not path.is_file():
        raise DataError(f"mannequin-x is installed but {path} is missing; {_INSTALL}")
    return path


def load_mannequin(verify: bool = True) -> Character:
    """The mannequin-x wooden body as a canonical-22
    :class:`~retarget_lib.core.character.Character`.

    Args:
        verify: check the asset's SHA-256 against :data:`MANNEQUIN_SHA256`.

    Returns:
        ``Character`` named ``"mannequin-x"``: 24,256 vertices, dense ``(V, 22)`` weights, rest
        pose = the asset's bind pose (a T-pose), soles on ``y = 0``, metres.

    Raises:
        DataError: if the asset is missing, has another checksum, or its layout is not the one
            described in this module.
    """
    path = mannequin_path()
    if verify:
        check_sha256(path, MANNEQUIN_SHA256)
    with np.load(path, allow_pickle=False) as data:
        arrays = {
            k: data[k]
            for k in (
                "parents",
                "local_offsets",
                "rest_local_rotations",
                "skin_source_joint_positions",
                "vertices",
                "faces",
                "skin_joint_indices",
                "skin_weights",
                "skin_rigid_joint_indices",
            )
        }
    parents = arrays["parents"].astype(int)
    bind = arrays["skin_source_joint_positions"].astype(np.float64)
    _check_bind_pose(parents, arrays["local_offsets"], arrays["rest_local_rotations"], bind)
    weights = _fold_weights(_package_weights(arrays), parents)
    vertices = arrays["vertices"].astype(np.float64)
    floor = mesh_ground(vertices)
    vertices[:, 1] -= floor
    bind[:, 1] -= floor
    # canonical joint c comes from SMPL-X body joint order[c]
    order = list(SMPLX_TO_CANONICAL)
    if [order.index(parents[order[c]]) if c else -1 for c in range(22)] != list(
        CANONICAL22_PARENTS
    ):
        raise DataError(f"{path}: the first 22 joints are not the SMPL-X body tree")
    rest = bind[order]
    offsets = rest.copy()
    offsets[1:] -= rest[list(CANONICAL22_PARENTS[1:])]
    _check_orientation(rest, path)
    return Character(
        "mannequin-x",
        canonical22_skeleton(offsets),
        vertices,
        arrays["faces"].astype(np.int64),
        weights[:, order],
        bulk=1.0,
        style=dict(rest_pose="T-pose", source="mannequin-x 0.3.0 wooden.npz", license="Apache-2.0"),
    )


def _check_bind_pose(
    parents: np.ndarray, local_offsets: np.ndarray, rest_rotations: np.ndarray, bind: np.ndarray
) -> None:
    """Bake the rest rotations into world-axis offsets and check that forward kinematics of them
    equals the skin's bind joints up to one translation (1 mm)."""
    glob = np.zeros_like(rest_rotations, dtype=np.float64)
    pos = np.zeros_like(bind)
    for j, p in enumerate(parents):
        if p < 0:
            glob[j], pos[j] = rest_rotations[j], local_offsets[j]
        else:
            glob[j] = glob[p] @ rest_rotations[j]
            pos[j] = pos[p] + glob[p] @ local_offsets[j]
    shift = bind - pos
    if np.abs(shift - shift[0]).max() > 1e-3:
        raise DataError(
            "mannequin-x: the skeleton (local_offsets, rest_local_rotations) does not "
            "match skin_source_joint_positions; unsupported asset version"
        )


def _package_weights(arrays: dict) -> np.ndarray:
    """``(V, 54)`` dense weights as the package skins: top-4 influences renormalised, rigid
    vertices bound to their one joint."""
    idx = arrays["skin_joint_indices"].astype(int)
    w = arrays["skin_weights"].astype(np.float64)
    keep = np.argsort(-w, axis=1)[:, :_INFLUENCES]
    idx, w = np.take_along_axis(idx, keep, 1), np.take_along_axis(w, keep, 1)
    w /= w.sum(axis=1, keepdims=True)
    rigid = arrays["skin_rigid_joint_indices"].astype(int)
    nv, nj = len(w), len(arrays["parents"])
    dense = np.zeros((nv, nj))
    np.add.at(dense, (np.repeat(np.arange(nv), _INFLUENCES), idx.ravel()), w.ravel())
    bound = rigid >= 0
    dense[bound] = 0.0
    dense[bound, rigid[bound]] = 1.0
    return dense


def _fold_weights(weights: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Add each extra joint's weights (hand roots, fingers) to its nearest body-joint ancestor.

    Args:
        weights: ``(V, J)`` over all joints.
        parents: ``J`` parents.

    Returns:
        ``(V, 22)`` weights of the SMPL-X body joints, rows summing to 1.
    """
    out = weights[:, :_BODY_JOINTS].copy()
    for j in range(_BODY_JOINTS, len(parents)):
        a = j
        while a >= _BODY_JOINTS:
            a = parents[a]
        out[:, a] += weights[:, j]
    return out / out.sum(axis=1, keepdims=True)


def _check_orientation(rest: np.ndarray, path: Path) -> None:
    """The library's frame: head above hips (+Y up), toes ahead of ankles (+Z), left at +X."""
    j = {n: i for i, n in enumerate(CANONICAL22)}
    ok = (
        rest[j["Head"], 1] > rest[j["Hips"], 1]
        and rest[j["LeftToeBase"], 2] > rest[j["LeftFoot"], 2]
        and rest[j["LeftUpLeg"], 0] > rest[j["RightUpLeg"], 0]
    )
    if not ok:
        raise DataError(f"{path}: unexpected axes (need +Y up, facing +Z, left at +X)")
