"""retarget_lib — the shared library behind the retarget-notebooks study suite.

Two motion-retargeting methods are taught and re-checked here: TDCN (Kim, Park, Kwon, Han 2020) and
contact-aware retargeting of skinned motion (Villegas et al. 2021).

Layers, bottom to top; each folder imports only from the ones before it (README, "The map";
docs/architecture.md): ``core`` → ``io`` → ``geometry`` → ``data`` → ``models``, ``losses`` →
``methods`` (the method registry) → ``training`` → ``evaluation`` → ``notebook``, ``viz``, ``cli``;
``files`` and ``config`` are leaf helpers. ``retarget_lib.skeleton`` and ``retarget_lib.kinematics``
re-export the core modules for the public contract.

Conventions (used everywhere; notebook 01 shows each one):

* Quaternions are **(w, x, y, z)**, shape ``(..., 4)``, unit norm; ``quat_mul(a, b)`` applies
  ``b`` first. Matrices act on **column vectors** (``v' = R @ v``).
* Units are **metres**. BVH lengths are converted to metres on load (unit given, or inferred from
  the skeleton's size) and back to the file's own unit on save.
* World up is **+Y**; characters face **+Z** at frame 0 after :meth:`Motion.normalize_root`; a
  character's left is **+X**.
* Tensor shapes are ``(batch, time, joints, channels)``; every docstring states the shape of every
  array argument.
* Joint order is the canonical 22 (:data:`retarget_lib.core.skeleton.CANONICAL22`); ``parents`` is a
  tuple of ints with the root's parent ``-1``.
* Character height ``H`` is the NKN/TDCN definition: the rest bone lengths of the root->head chain
  plus the left-leg chain (:meth:`Skeleton.height`). Every normalised metric says which height it
  uses; the other heights (standing heights for the contact thresholds), the rest ground and the
  feet's rest heights are defined once in :mod:`retarget_lib.core.measures`.
"""

__version__ = "0.1.0"
