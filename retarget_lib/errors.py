"""The library's exception types for bad input, and :func:`short_repr` for the values they show
(this module imports nothing of the library).

Every error a user can cause with a file, a path, a config or an option is a
:class:`RetargetInputError` (a ``ValueError``) whose message names the file or key and the problem
in one line; the command line prints it and exits with status 2, without a traceback.

=========================  ==================================================================
type                       raised for
=========================  ==================================================================
:class:`InputFileError`    a path that is missing, a directory, unreadable, empty or truncated
:class:`OutputPathError`   an ``--out`` that would overwrite an input, has an unsupported
                           extension, or cannot be created (its parent is a file)
:class:`LimitError`        a value beyond a documented bound (frame time, frame count, joints,
                           nesting depth, magnitudes, file size); the message names the limit
:class:`CheckpointError`   a checkpoint file that is not a valid model of the expected kind
:class:`GLTFError`         a glTF/GLB file that is malformed, out of bounds, or not a skinned
                           character (no skin, several skeleton roots, sparse accessors ...)
:class:`AMASSError`        an SMPL-X / AMASS ``.npz`` motion that lacks a key (``betas``,
                           ``poses``, ``trans``, the frame rate) or has wrong shapes or values
:class:`FBXError`          an FBX file the optional FBX reader cannot convert, or the reader
                           (the ``fbx`` extra) is not installed; an FBX that cannot be written
                           (a motion on other joints than the rig's, a bad unit)
:class:`DeviceError`       a ``--device``/``--amp`` this machine cannot run (no CUDA, no MPS),
                           or a distributed launch that does not fit the config (batch size not
                           divisible by the number of processes)
:class:`MixamoFolderError` a ``mixamo-local`` folder whose layout is ambiguous (two files of one
                           motion, two character files) or whose ``splits.yaml`` is invalid
=========================  ==================================================================

Also :class:`~retarget_lib.io.bvh.BVHError` (a malformed BVH; names the line),
:class:`~retarget_lib.io.gltf.NoSkinError` (a :class:`GLTFError`: a glTF/GLB/FBX file without a
skinned mesh where a character is needed),
:class:`~retarget_lib.core.skeleton.JointSetError` (joints that cannot be mapped onto the canonical
22; names them),
:class:`~retarget_lib.io.shape.ShapeError` (a malformed shape ``.npz``) and
:class:`~retarget_lib.config.ConfigError` (a config file or override) derive from
:class:`RetargetInputError`. :class:`~retarget_lib.files.DataError` (a shipped or cached data
file missing or corrupt) is separate: it is not the user's input, but the CLI also exits with 2.
"""

from __future__ import annotations

import reprlib
from typing import Any

__all__ = [
    "short_repr",
    "RetargetInputError",
    "InputFileError",
    "OutputPathError",
    "LimitError",
    "CheckpointError",
    "GLTFError",
    "AMASSError",
    "FBXError",
    "DeviceError",
    "MixamoFolderError",
]


_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxdict, _SHORT.maxlevel = 60, 60, 4, 4, 2


def short_repr(value: Any) -> str:
    """A bounded ``repr`` of a value from a user's file for an error message: at most a few items
    of a few levels, long strings cut (an aliased YAML value is never expanded)."""
    return _SHORT.repr(value)


class RetargetInputError(ValueError):
    """Bad user input; the message names the file or key and the problem, in one line."""


class InputFileError(RetargetInputError):
    """An input path that is missing, a directory, unreadable, empty or truncated."""


class OutputPathError(RetargetInputError):
    """An output path that would overwrite an input, has an unsupported extension or cannot be
    created."""


class LimitError(RetargetInputError):
    """A value beyond one of the library's documented bounds (the message names the bound)."""


class CheckpointError(RetargetInputError):
    """A checkpoint file that cannot be read or is not a valid model of the expected kind."""


class GLTFError(RetargetInputError):
    """A glTF 2.0 / GLB file that is malformed, out of bounds or not a skinned character."""


class AMASSError(RetargetInputError):
    """An SMPL-X / AMASS ``.npz`` motion with a missing key, a wrong shape or non-finite values."""


class FBXError(RetargetInputError):
    """An FBX file that cannot be converted or written, or the optional FBX reader is not
    installed."""


class DeviceError(RetargetInputError):
    """A device, precision or process layout that cannot run here (the message says what to use)."""


class MixamoFolderError(RetargetInputError):
    """A ``mixamo-local`` folder whose layout is ambiguous or whose ``splits.yaml`` is invalid."""


class RetargetWarning(UserWarning):
    """Something the user should know about an input that was still used (e.g. a target mesh whose
    skeleton differs from the target's by 1-5 % of its height and was rebound); the command line
    prints it as one ``retarget CMD: warning: ...`` line on stderr."""
