"""A small AMASS-format (SMPL-X) clip made from the synthetic motion library, for tests, the README
and notebook 10: a synthetic motion authored directly on the SMPL-X skeleton of a body shape
(:func:`~retarget_lib.io.amass.smplx_skeleton`) and written with
:func:`~retarget_lib.io.amass.save_amass` (Z-up, ``poses (T, 165)``, 16 betas). Deterministic.

The shipped copy is ``tests/data/amass_walk.npz`` (``python -m
retarget_lib.data.synthetic.amass_clip`` writes it again).
"""

from __future__ import annotations

import os

import numpy as np

from ...files import REPO_ROOT
from ...io.amass import save_amass, smplx_skeleton
from .motions import make_motion

__all__ = ["AMASS_CLIP_BETAS", "AMASS_CLIP_PATH", "make_amass_clip"]

#: a body a little taller and slimmer than the neutral SMPL-X mean
AMASS_CLIP_BETAS = np.array([0.8, -0.6, 0.3, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0])
#: the shipped clip
AMASS_CLIP_PATH = REPO_ROOT / "tests" / "data" / "amass_walk.npz"


def make_amass_clip(
    path: str | os.PathLike,
    family: str = "walk",
    seed: int = 0,
    duration: float = 4.0,
    betas: np.ndarray = AMASS_CLIP_BETAS,
) -> None:
    """Write a synthetic ``family`` clip performed by the SMPL-X body ``betas`` as an AMASS
    ``.npz``.

    Args:
        path: destination ``.npz``.
        family: a synthetic motion family (``walk``, ``clap``, ...).
        seed: style seed.
        duration: seconds at 30 fps.
        betas: ``(10,)`` SMPL-X shape.
    """
    motion = make_motion(family, smplx_skeleton(betas), seed, duration)
    save_amass(motion, path, betas)


if __name__ == "__main__":
    make_amass_clip(AMASS_CLIP_PATH)
    print(AMASS_CLIP_PATH)
