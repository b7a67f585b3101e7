"""The geometry-conditioned RNN of Villegas et al. 2021 (Sec. 3.2, Fig. 3, App. B, Eqs. 12-19).

Per frame ``t``::

    h^enc_t = f_enc(m^A_t, h^enc_(t−1))                                  (12)  2-layer GRU, 512
    h^dec_t = f_dec([h^enc_t, p^B_(t−1), o^B_(t−1), s̄^B, e^B], h^dec_(t−1)) (13)  2-layer GRU, 512
    θ^B_t   = f_θ(h^dec_t)                                               (14)  linear → 6D → wxyz
    p^B_t   = FK(θ^B_t, s̄^B)                                             (15)  root-relative joints
    o^B_t   = f_o(h^dec_t)                                               (17)  linear, root velocity
    g^B_t   = p^B_t + r^B_t,   r^B_t = r^B_(t−1) + o^B_(t−1)              (18)
    e^B     = max_v f_vert([v̄^B_v, w^B_v])                               (19)  PointNet

Choices the paper leaves open (decided here):

* **Input** ``m^A_t ∈ R^267`` (:func:`motion_features`): the source's joint positions relative to
  the root (FK with the root at the origin, the root's rotation applied; 22×3), its local
  rotations as row-major 3×3 matrices (22×9) and its root velocity
  ``o^A_t = r_(t+1) − r_t`` (3; :func:`~retarget_lib.core.quantities.forward_root_velocity`).
  Positions and velocity are divided by the source height ``h_A`` (NKN/TDCN ``H``).
* **Scale.** Everything the decoder sees about the target is divided by ``h_B``: ``p^B_(t−1)``,
  ``o^B_(t−1)``, the rest offsets ``s̄^B`` (all 22 rows, the root row being the hips' rest
  position) and the vertices of the PointNet input; ``f_o`` predicts ``o^B / h_B``. One model
  therefore serves characters of any height (1.2-2.1 m in our data).
* **PointNet input** (:func:`normalize_rest_vertices`): rest vertices centred on the mesh's
  bounding-box footprint (x, z centre, lowest y: :func:`~retarget_lib.core.measures.mesh_ground`)
  and divided by the mesh's standing height (its bounding-box y extent,
  :func:`~retarget_lib.core.measures.mesh_standing_height`), concatenated with the 22 skinning
  weights. Both the normalisation and
  the max-pool ignore vertex order and duplicates, so meshes of different sizes can be batched by
  repeating vertices (:func:`batch_meshes`).
* **Rotations.** ``f_θ`` outputs the continuous 6D representation (Zhou et al. 2019), turned into
  a rotation matrix by Gram-Schmidt and then into a unit ``w ≥ 0`` quaternion; its bias starts at
  the identity (output = rest pose).
* **Root trajectory.** ``o^B_t`` is the displacement from frame ``t`` to ``t + 1``, so frame
  ``t``'s root is ``r^B_t = r^B_0 + Σ_(k<t) o^B_k`` with a caller-given start ``r^B_0``
  (:func:`pose_outputs`; e.g. the source's first root position times the leg ratio). The step API
  carries ``(p_(t−1), o_(t−1), r_(t−1))`` in :class:`DecoderState`; before frame 0 they are the
  target's rest pose, zero and the start, so frame 0 sits at the start.
* **Dropout** (0.1, App. B.1) acts between the stacked GRU layers of both RNNs.

FK and skinning are not part of the module: callers use :func:`pose_outputs` (FK + root
integration) and :func:`retarget_lib.core.skinning.linear_blend_skinning` with its global rotations.

The package: :mod:`.parts` (features, PointNet, decoder state, posing) and :mod:`.model`
(:class:`GeometryConditionedRNN`).
"""

from __future__ import annotations

from .model import GeometryConditionedRNN
from .parts import (
    MOTION_FEATURE_LAYOUT,
    MOTION_FEATURES,
    NUM_JOINTS,
    DecoderGates,
    DecoderState,
    GeoRetOutput,
    PointNetEncoder,
    PosedOutput,
    ResidualBase,
    TargetContext,
    batch_meshes,
    gru_update,
    motion_features,
    normalize_rest_vertices,
    pose_outputs,
)

__all__ = [
    "MOTION_FEATURES",
    "MOTION_FEATURE_LAYOUT",
    "GeoRetOutput",
    "ResidualBase",
    "PosedOutput",
    "TargetContext",
    "DecoderState",
    "DecoderGates",
    "gru_update",
    "PointNetEncoder",
    "GeometryConditionedRNN",
    "motion_features",
    "normalize_rest_vertices",
    "batch_meshes",
    "pose_outputs",
    "NUM_JOINTS",
]
