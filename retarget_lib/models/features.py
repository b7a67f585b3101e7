"""Input assembly for the retargeting networks (TDCN Secs. 3.1-3.2 and 4.2; NKN baseline).

Everything a model or a loss needs to turn a motion ``(q, r)`` on a skeleton into network
channels lives here, so the generator, the discriminator, the NKN baseline and the loss code
all agree on the layout.

Generator input (TDCN Sec. 3.1, Eq. 2). Per frame ``t`` the TDCN sees

* ``p_t`` — the source's joint positions relative to the root, ``f_FK(q_t, s̄A)`` (Eq. 1): FK with
  the root at the origin but the root's rotation applied (so facing is visible);
* ``q_t`` — the source's local unit quaternions (wxyz);
* ``r_t`` — the source's root position (metres, world frame);
* ``s̄B`` — the target skeleton in the default pose: its rest offsets, all ``J`` rows (row 0 is
  the root's rest position, i.e. the hips' height above the ground, which carries the leg
  length), repeated for every frame.

They are concatenated in that order into ``(B, C_in, T)`` channels-first (the ``Conv1d``
layout), ``C_in = 3J + 4J + 3 + 3J = 223`` for ``J = 22`` (:data:`GENERATOR_LAYOUT` gives the
slices).

Normalisation. The paper does not say whether the inputs are standardised. (The authors'
released code does standardise ``p``, ``s̄`` and ``r`` with dataset statistics; it also computes
``p`` with the root rotation set to identity, whereas we follow Eq. 1 and keep it.)
:class:`FeatureNormalizer` optionally applies per-channel ``(x - mean) / std`` with statistics
fitted on a dataset; it is the identity until :meth:`FeatureNormalizer.fit` is called, and its
statistics are *buffers*, so they are saved in and restored from checkpoints with the model that
owns them. Model configs opt in with ``normalize_inputs: true`` (default ``false`` = the paper as
written); the training code then fits the generator's ``normalizer`` on training features.

Discriminator input (TDCN Sec. 4.2, Eqs. 9-12 and 18-20). Per frame pair ``(t-1, t)``:

* ``l_t = ||p_t - p_{t-1}|| / H`` for every non-root joint (Eqs. 9-12; the root's ``p`` is always
  the origin, so its entry would be identically zero and is left out: ``J - 1`` channels);
* ``δ_t = ||r_t - r_{t-1}|| / H`` (Eq. 18, one channel);
* ``B`` — the rest bone lengths (``||offset_j||`` for the ``J - 1`` non-root joints, metres,
  repeated over time).

→ ``(B, 2(J-1) + 1, T - 1)`` = ``(B, 43, T - 1)``. ``H`` is the NKN/TDCN height
(:func:`retarget_lib.core.measures.nkn_height`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import torch
from torch import nn

from ..core.kinematics import forward_kinematics
from ..core.measures import nkn_height
from ..core.quantities import discriminator_inputs
from ..core.quantities import hip_facing as facing_from_hips
from ..core.rotations import quat_conjugate, quat_rotate
from ..core.skeleton import CANONICAL22, CANONICAL22_PARENTS

Tensor = torch.Tensor

__all__ = [
    "NUM_JOINTS",
    "GENERATOR_LAYOUT",
    "generator_input_channels",
    "discriminator_input_channels",
    "nkn_input_channels",
    "batched_offsets",
    "source_local_positions",
    "POSITION_FRAMES",
    "positions_in_frame",
    "generator_features",
    "split_generator_features",
    "root_velocities",
    "nkn_source_features",
    "hip_facing",
    "to_facing_frame",
    "from_facing_frame",
    "discriminator_features",
    "FeatureNormalizer",
    "residual_input_channels",
    "residual_generator_features",
]

NUM_JOINTS = 22
_LEFT_UP_LEG, _RIGHT_UP_LEG = CANONICAL22.index("LeftUpLeg"), CANONICAL22.index("RightUpLeg")


def residual_input_channels(num_joints: int = NUM_JOINTS) -> int:
    """``C_in`` of the residual TDCN: ``p`` (3J) + ``q`` (4J) + root (3) + ``s̄B`` (3J) + ``s̄A``
    (3J)."""
    return 13 * num_joints + 3


def generator_input_channels(num_joints: int = NUM_JOINTS) -> int:
    """``C_in`` of the TDCN generator: ``p`` (3J) + ``q`` (4J) + ``r`` (3) + ``s̄B`` (3J)."""
    return 10 * num_joints + 3


def discriminator_input_channels(num_joints: int = NUM_JOINTS) -> int:
    """Channels of :func:`discriminator_features`: ``l`` (J-1) + ``δ`` (1) + ``B`` (J-1)."""
    return 2 * (num_joints - 1) + 1


def nkn_input_channels(num_joints: int = NUM_JOINTS) -> int:
    """Channels of :func:`nkn_source_features`: ``p`` (3J) + root velocity (3)."""
    return 3 * num_joints + 3


def _layout(num_joints: int) -> dict[str, slice]:
    j = num_joints
    return {
        "p": slice(0, 3 * j),
        "q": slice(3 * j, 7 * j),
        "r": slice(7 * j, 7 * j + 3),
        "skeleton": slice(7 * j + 3, 10 * j + 3),
    }


#: channel slices of :func:`generator_features` for the canonical 22 joints
GENERATOR_LAYOUT: dict[str, slice] = _layout(NUM_JOINTS)


def batched_offsets(offsets: Tensor, batch: int) -> Tensor:
    """``(J,3)`` or ``(B,J,3)`` → ``(B,J,3)``."""
    if offsets.dim() == 2:
        offsets = offsets.unsqueeze(0)
    if offsets.dim() != 3:
        raise ValueError(f"offsets must be (J,3) or (B,J,3), got {tuple(offsets.shape)}")
    return offsets.expand(batch, -1, -1)


def source_local_positions(
    rotations: Tensor, offsets: Tensor, parents: Sequence[int] = CANONICAL22_PARENTS
) -> Tensor:
    """``p_t = f_FK(q_t, s̄)`` (TDCN Eq. 1): joints relative to the root, root rotation applied.

    Args:
        rotations: ``(B, T, J, 4)`` local unit quaternions (wxyz).
        offsets: ``(B, J, 3)`` or ``(J, 3)`` rest offsets.
        parents: ``J`` parent indices.

    Returns:
        ``(B, T, J, 3)`` root-relative joint positions.
    """
    if offsets.dim() == 3:
        offsets = offsets.unsqueeze(1)  # (B, 1, J, 3): broadcast over time
    return forward_kinematics(rotations, offsets, parents, None).positions


#: the axes a network can be given the joint positions ``p`` in (``model.positions_frame``):
#: ``"world"`` world axes, the root's rotation applied (TDCN Eq. 1, the paper); ``"facing"`` each
#: frame's facing frame (the authors' NKN code, audit N4); ``"root"`` the root joint's own axes,
#: i.e. FK with the root's rotation set to identity (the authors' TDCN code, audit T5)
POSITION_FRAMES = ("world", "facing", "root")


def positions_in_frame(
    positions: Tensor, frame: str, root_rotations: Tensor | None = None
) -> Tensor:
    """Root-relative joint positions expressed in one of :data:`POSITION_FRAMES`.

    Args:
        positions: ``(..., J, 3)`` canonical-22 ``p`` in world axes
            (:func:`source_local_positions`).
        frame: ``"world"`` (returned as they are), ``"facing"`` (rotated about the vertical into
            the frame's facing frame, :func:`hip_facing` and :func:`to_facing_frame`) or ``"root"``
            (rotated by the inverse of the root's rotation).
        root_rotations: ``(..., 4)`` wxyz root rotations, needed for ``"root"``.

    Returns:
        ``(..., J, 3)``.
    """
    if frame == "world":
        return positions
    if frame == "facing":
        return to_facing_frame(positions, hip_facing(positions).unsqueeze(-2))
    if frame == "root":
        if root_rotations is None:
            raise ValueError('positions_in_frame(..., "root") needs the root rotations')
        return quat_rotate(quat_conjugate(root_rotations).unsqueeze(-2), positions)
    raise ValueError(f"frame must be one of {POSITION_FRAMES}, got {frame!r}")


def generator_features(
    rotations: Tensor,
    root_positions: Tensor,
    offsets_src: Tensor,
    offsets_tgt: Tensor,
    positions: Tensor | None = None,
    parents: Sequence[int] = CANONICAL22_PARENTS,
) -> Tensor:
    """The TDCN generator input ``[p_t, q_t, r_t, s̄B]`` per frame (Sec. 3.1, Eq. 2; Fig. 2b).

    Args:
        rotations: ``(B, T, J, 4)`` source local quaternions ``q`` (wxyz).
        root_positions: ``(B, T, 3)`` source root positions ``r`` (metres).
        offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets ``s̄A`` (only used for ``p``).
        offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets ``s̄B``.
        positions: optional precomputed ``(B, T, J, 3)`` ``p`` (e.g. the FK of a generator's
            output in the second half of the cycle, Eq. 5); computed by FK when ``None``.
        parents: ``J`` parent indices.

    Returns:
        ``(B, 10J + 3, T)`` channels-first features; slices in :data:`GENERATOR_LAYOUT`.
    """
    b, t, j, _ = rotations.shape
    if positions is None:
        positions = source_local_positions(rotations, offsets_src, parents)
    skel = (
        batched_offsets(offsets_tgt.to(rotations.dtype), b).reshape(b, 1, 3 * j).expand(b, t, 3 * j)
    )
    x = torch.cat(
        [positions.reshape(b, t, 3 * j), rotations.reshape(b, t, 4 * j), root_positions, skel], -1
    )
    return x.transpose(1, 2)


def residual_generator_features(
    rotations: Tensor,
    root_positions: Tensor,
    offsets_src: Tensor,
    offsets_tgt: Tensor,
    positions: Tensor | None = None,
    parents: Sequence[int] = CANONICAL22_PARENTS,
) -> Tensor:
    """Input of the residual TDCN variant: ``[p_t, q_t, ρ_t, s̄B, s̄A]`` per frame.

    Differs from :func:`generator_features` (the paper's Eq. 2) in two ways, both so that the
    network can compute a rest-pose alignment and never sees an absolute horizontal position:

    * the root enters as ``ρ_t = (Δx_t, y_t, Δz_t) / H(s̄A)`` (horizontal velocity, height;
      ``Δ·_1 = 0``) instead of ``r_t``: the output no longer depends on where the clip is;
    * the source skeleton ``s̄A`` is appended (the paper gives only ``s̄B``; ``s̄A`` is implicit in
      ``p``), so the two rest poses are both visible.

    Args:
        rotations: ``(B, T, J, 4)`` source local quaternions (wxyz).
        root_positions: ``(B, T, 3)`` source root positions (metres).
        offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets ``s̄A``.
        offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets ``s̄B``.
        positions: optional precomputed ``(B, T, J, 3)`` ``p``.
        parents: ``J`` parent indices.

    Returns:
        ``(B, 13J + 3, T)`` channels-first.
    """
    b, t, j, _ = rotations.shape
    off_a = batched_offsets(offsets_src.to(rotations.dtype), b)
    v = root_velocities(root_positions)
    rho = torch.stack([v[..., 0], root_positions[..., 1], v[..., 2]], -1) / nkn_height(off_a).view(
        b, 1, 1
    )
    # the paper's [p, q, r, s̄B] with ρ in r's channels, then s̄A
    x = generator_features(rotations, rho, off_a, offsets_tgt, positions, parents)
    return torch.cat([x, off_a.reshape(b, 3 * j, 1).expand(b, 3 * j, t)], 1)


def split_generator_features(features: Tensor, num_joints: int = NUM_JOINTS) -> dict[str, Tensor]:
    """Undo :func:`generator_features`.

    Args:
        features: ``(B, 10J + 3, T)``.

    Returns:
        dict with ``p (B,T,J,3)``, ``q (B,T,J,4)``, ``r (B,T,3)``, ``skeleton (B,J,3)`` (frame 0).
    """
    lay = _layout(num_joints)
    x = features.transpose(1, 2)
    b, t, _ = x.shape
    return {
        "p": x[..., lay["p"]].reshape(b, t, num_joints, 3),
        "q": x[..., lay["q"]].reshape(b, t, num_joints, 4),
        "r": x[..., lay["r"]],
        "skeleton": x[:, 0, lay["skeleton"]].reshape(b, num_joints, 3),
    }


def root_velocities(root_positions: Tensor, facing: Tensor | None = None) -> Tensor:
    """Per-frame root displacement ``v_t = r_t - r_{t-1}`` with ``v_1 = 0`` (NKN's root input).

    Args:
        root_positions: ``(B, T, 3)``.
        facing: optional ``(B, T, 2)`` facing directions (:func:`hip_facing`); when given each
            step is expressed in its frame's facing frame (:func:`to_facing_frame`).

    Returns:
        ``(B, T, 3)``; ``r_t = r_1 + sum_{k<=t} v_k`` (world axes without ``facing``).
    """
    v = torch.cat([torch.zeros_like(root_positions[:, :1]), root_positions.diff(dim=1)], 1)
    return v if facing is None else to_facing_frame(v, facing)


def hip_facing(positions: Tensor) -> Tensor:
    """Horizontal facing direction per frame of canonical-22 positions
    (:func:`~retarget_lib.core.quantities.hip_facing` of the two up-legs).

    Args:
        positions: ``(..., J, 3)`` canonical-22 joint positions (root-relative or world).

    Returns:
        ``(..., 2)`` unit ``(f_x, f_z)``.
    """
    return facing_from_hips(positions[..., _LEFT_UP_LEG, :], positions[..., _RIGHT_UP_LEG, :])


def to_facing_frame(v: Tensor, facing: Tensor) -> Tensor:
    """World vectors into the facing frame (``+z`` forward, ``+x`` to the character's left).

    Args:
        v: ``(..., 3)`` world vectors (metres).
        facing: ``(..., 2)`` unit ``(f_x, f_z)`` (:func:`hip_facing`).

    Returns:
        ``(..., 3)``; :func:`from_facing_frame` inverts it.
    """
    fx, fz = facing.unbind(-1)
    x, y, z = v.unbind(-1)
    return torch.stack((x * fz - z * fx, y, x * fx + z * fz), -1)


def from_facing_frame(v: Tensor, facing: Tensor) -> Tensor:
    """Facing-frame vectors back to world axes (inverse of :func:`to_facing_frame`)."""
    fx, fz = facing.unbind(-1)
    x, y, z = v.unbind(-1)
    return torch.stack((x * fz + z * fx, y, z * fz - x * fx), -1)


def nkn_source_features(
    positions: Tensor,
    root_positions: Tensor,
    height: Tensor | None = None,
    facing: Tensor | None = None,
    root_height: Tensor | None = None,
) -> Tensor:
    """The NKN encoder input per frame: local joint positions and root velocity (Villegas 2018).

    Args:
        positions: ``(B, T, J, 3)`` root-relative joint positions ``p`` (Eq. 1).
        root_positions: ``(B, T, 3)`` root positions.
        height: optional ``(B,)`` source heights ``H(s̄A)``; when given the root velocity is divided
            by it ("normalised root offsets", TDCN Sec. 6 Baseline-height).
        facing: optional ``(B, T, 2)`` facing directions (:func:`hip_facing`); when given the root
            velocity is expressed in each frame's facing frame (:func:`to_facing_frame`, the
            authors' NKN code's root representation) instead of world axes.
        root_height: optional ``(B, T)``; when given it replaces the vertical root step (the
            NKN option ``root_height="floor"``: the root's height over the floor in leg lengths).

    Returns:
        ``(B, 3J + 3, T)`` channels-first.
    """
    b, t, j, _ = positions.shape
    v = root_velocities(root_positions, facing)
    if height is not None:
        v = v / height.view(b, 1, 1)
    if root_height is not None:
        v = torch.stack((v[..., 0], root_height, v[..., 2]), -1)
    return torch.cat([positions.reshape(b, t, 3 * j), v], -1).transpose(1, 2)


def discriminator_features(
    positions: Tensor, root_positions: Tensor, offsets: Tensor, normalize: bool = True
) -> Tensor:
    """Discriminator input ``(l_t, δ_t, B)`` of TDCN Eqs. 19-20 for frames ``2..T``.

    Args:
        positions: ``(B, T, J, 3)`` root-relative joint positions (``p`` or FK of ``q̂``, Eq. 3).
        root_positions: ``(B, T, 3)`` root positions (``r`` or ``r̂``).
        offsets: ``(B, J, 3)`` or ``(J, 3)`` rest offsets of the skeleton that performs the motion.
        normalize: divide ``l`` and ``δ`` by ``H(s̄)`` (TDCN; Sec. 4.2 (ii)). ``False`` keeps
            metres, as in the NKN baseline's discriminator.

    Returns:
        ``(B, 2(J-1) + 1, T-1)``: ``l`` for joints ``1..J-1``, then ``δ``, then bone lengths.
    """
    b, t = positions.shape[:2]
    offsets = batched_offsets(offsets.to(positions.dtype), b)
    # the same l, δ and bone lengths as the loss module's Eqs. 11/12, 18, 19/20; H = 1 keeps metres
    d = discriminator_inputs(
        positions, root_positions, offsets, nkn_height(offsets) if normalize else 1.0
    )
    bones = d.bones[:, 1:].unsqueeze(1).expand(b, t - 1, -1)
    return torch.cat([d.l[..., 1:], d.delta.unsqueeze(-1), bones], -1).transpose(1, 2)


class FeatureNormalizer(nn.Module):
    """Optional per-channel standardisation ``(x - mean) / std`` of ``(B, C, T)`` features.

    The TDCN paper does not mention input normalisation; this is an opt-in convenience
    (``normalize_inputs: true`` in a model config). Until :meth:`fit` is called it is the
    identity (``mean = 0``, ``std = 1``). Statistics are buffers, so they travel with the owning
    model's ``state_dict``. Channels whose std is below ``min_std`` (constants such as a fixed
    target skeleton, or the root's zero position) are only centred, not blown up.

    Args:
        num_channels: ``C``.
        min_std: floor for the fitted std.
    """

    mean: Tensor
    std: Tensor
    fitted: Tensor

    def __init__(self, num_channels: int, min_std: float = 1e-2):
        super().__init__()
        self.min_std = float(min_std)
        self.register_buffer("mean", torch.zeros(num_channels))
        self.register_buffer("std", torch.ones(num_channels))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))

    @property
    def is_identity(self) -> bool:
        return not bool(self.fitted)

    @torch.no_grad()
    def fit(self, features: Tensor | Iterable[Tensor]) -> FeatureNormalizer:
        """Compute per-channel mean and std over batch and time.

        Args:
            features: one ``(B, C, T)`` tensor or an iterable of them (streamed, float64 sums).

        Returns:
            ``self``.
        """
        chunks = [features] if isinstance(features, Tensor) else features
        n, s, s2 = 0, 0.0, 0.0
        for x in chunks:
            x = x.detach().to(torch.float64).transpose(0, 1).reshape(x.shape[1], -1)
            n += x.shape[1]
            s = s + x.sum(1)
            s2 = s2 + (x * x).sum(1)
        if n == 0:
            raise ValueError("FeatureNormalizer.fit got no frames")
        mean = s / n
        std = (s2 / n - mean * mean).clamp_min(0).sqrt()
        self.mean.copy_(mean.to(self.mean.dtype))
        self.std.copy_(std.clamp_min(self.min_std).to(self.std.dtype))
        self.fitted.fill_(True)
        return self

    def reset(self) -> None:
        """Back to the identity."""
        self.mean.zero_()
        self.std.fill_(1.0)
        self.fitted.fill_(False)

    def forward(self, x: Tensor) -> Tensor:
        """Args: x ``(B, C, T)``. Returns: ``(B, C, T)`` standardised (``x`` itself if unfitted)."""
        if not bool(self.fitted):
            return x
        return (x - self.mean.view(1, -1, 1)) / self.std.view(1, -1, 1)

    def extra_repr(self) -> str:
        return f"channels={self.mean.numel()}, fitted={bool(self.fitted)}"
