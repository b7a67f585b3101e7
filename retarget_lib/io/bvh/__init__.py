"""BVH (Biovision Hierarchy) reading and writing, for any joint set.

A BVH file has a ``HIERARCHY`` section (a tree of ``JOINT`` blocks, each with an ``OFFSET``, a
``CHANNELS`` line and optional ``End Site`` leaves) and a ``MOTION`` section (``Frames:``,
``Frame Time:`` and one line of channel values per frame).

Semantics used here (the common ones, e.g. Blender's and Holden's readers):

* rotation channels are Euler angles in degrees, composed in the order listed:
  ``Zrotation Xrotation Yrotation`` means ``R = Rz(a) @ Rx(b) @ Ry(c)``
  (:func:`~retarget_lib.core.rotations.quat_from_euler`); any permutation of the three axes is
  accepted;
* position channels *replace* the joint's ``OFFSET``: the root's become ``Motion.root_positions``
  (the root ``OFFSET`` is kept as the skeleton's rest root position); a non-root joint's constant
  position channels become its offset; varying ones cannot be represented by a
  :class:`~retarget_lib.core.skeleton.Skeleton` and are replaced by their mean (recorded in
  ``meta["position_channels_dropped"]``);
* lengths are converted to metres on load and back to the file's unit on save (see
  :func:`infer_unit_scale`).

The ``MOTION`` block is parsed with NumPy in one conversion, not value by value: the CMU clips
(3-5k frames x 96 channels) load in well under a second. Loading is linear in the file's size.

Bounds (:class:`BVHError` naming the line and the bound, or
:class:`~retarget_lib.errors.InputFileError` for the file size), each far beyond any real clip:

=========================  ==============  ==================================================
bound                      value           why
=========================  ==============  ==================================================
file size                  64 MiB          CMU's longest clips are ~10 MiB; checked before
                                           reading, and a file whose first word is not
                                           ``HIERARCHY`` is refused after its first line
joints                     1000            Mixamo with fingers has 65, SMPL-X 55, CMU 31
nesting depth              100             the longest human chain (root to a fingertip) ~25
frames (declared)          1,000,000       9 h at 30 fps
frame time                 0.001-1 s       1 to 1000 frames per second
rotation values            |a| <= 1e5 deg  larger angles have lost all precision (1e308 would
                                           turn into noise, not a rotation)
offsets and positions      |x| <= 1e6      file units: 10 km in centimetres
=========================  ==============  ==================================================

:func:`save_bvh` refuses what :func:`load_bvh` would refuse (non-finite values, a frame rate
outside those bounds, lengths beyond them), so every file it writes loads back.

The package: :mod:`.parse` (the text under limits), :mod:`.read` (files into motions) and
:mod:`.write` (:func:`save_bvh`).
"""

from __future__ import annotations

from .parse import (
    HUMAN_HEIGHT,
    MAX_ANGLE_DEG,
    MAX_DEPTH,
    MAX_FILE_BYTES,
    MAX_FRAME_TIME,
    MAX_FRAMES,
    MAX_JOINTS,
    MAX_LENGTH,
    MIN_FRAME_TIME,
    UNIT_SCALES,
    BVHError,
)
from .read import infer_unit_scale, load_bvh, load_canonical_bvh
from .write import save_bvh

__all__ = [
    "BVHError",
    "UNIT_SCALES",
    "infer_unit_scale",
    "load_bvh",
    "save_bvh",
    "MAX_FILE_BYTES",
    "MAX_JOINTS",
    "MAX_DEPTH",
    "MAX_FRAMES",
    "MIN_FRAME_TIME",
    "MAX_FRAME_TIME",
    "MAX_ANGLE_DEG",
    "MAX_LENGTH",
    "HUMAN_HEIGHT",
    "load_canonical_bvh",
]
