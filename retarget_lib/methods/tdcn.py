"""Method ``tdcn`` — TDCN inference (Kim et al. 2020): rebuild a trained generator from a checkpoint
and retarget whole clips with it. The NKN baselines (method ``nkn``, :mod:`.nkn`) run through the
same code with their own generators.

The input is centred like the training windows (:func:`centre_root`, see
:mod:`retarget_lib.training.tdcn`, "Root normalisation"), in one pass (the paper) or per output
frame on its own re-centred receptive field (``windowed=True``, our variant for long travelling
clips).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from typing import Any

import torch

from ..core.motion import Motion
from ..core.quantities import leg_ratio
from ..core.rotations import quat_slerp
from ..core.skeleton import Skeleton
from ..data.checkpoints import load_state
from ..devices import module_device, resolve_device
from ..models import TDCNGenerator, build_model
from ..models.tdcn import edge_pad

Tensor = torch.Tensor

__all__ = [
    "centre_root",
    "model_config",
    "load_generator",
    "mirror_averaged",
    "retarget_motion_with",
    "generator_retargeter",
    "load",
]


def centre_root(root_positions: Tensor) -> tuple[Tensor, Tensor]:
    """Move a clip horizontally so that its centre frame's root is above the origin.

    Args:
        root_positions: ``(..., T, 3)``.

    Returns:
        ``(centred (..., T, 3), shift (..., 3))`` with ``centred = root_positions - shift``;
        ``shift`` has ``y = 0``.
    """
    shift = root_positions[..., root_positions.shape[-2] // 2, :].clone()
    shift[..., 1] = 0.0
    return root_positions - shift.unsqueeze(-2), shift


def model_config(config: dict) -> dict[str, Any]:
    """The model config of an experiment config, with the run's profile made explicit.

    Args:
        config: merged experiment config (``model`` section, ``profile``).

    Returns:
        the dict given to :func:`~retarget_lib.models.build_model` (so widths never depend on
        ``$RETARGET_PROFILE`` at load time).
    """
    return {**config["model"], "profile": config.get("profile", "fast")}


def load_generator(
    checkpoint: str | os.PathLike,
    device: str | torch.device | None = None,
) -> tuple[torch.nn.Module, dict]:
    """Rebuild a trained generator from a checkpoint of ``retarget train`` (``last.pt``,
    ``final.pt`` or an ``--export``ed one).

    Args:
        checkpoint: a manifest checkpoint id (the shipped file, sha256 verified) or a path
            (:func:`~retarget_lib.data.checkpoints.resolve_checkpoint`).

        device: a ``--device`` name or ``torch.device`` (default the CPU).

    Returns:
        ``(generator, config)``: the generator in eval mode on ``device`` with its weights and
        normaliser statistics; the merged experiment config it was trained with.
    """
    state = load_state(checkpoint)
    config = state["config"]
    generator, _ = build_model(model_config(config))
    generator.load_state_dict(state["modules"]["generator"])
    return generator.eval().to(resolve_device(device or "cpu")), config


def _frame_windows(x: Tensor, left: int, right: int) -> Tensor:
    """``(T, ...)`` → ``(T, left + 1 + right, ...)``: frame ``t``'s receptive field, edge-padded."""
    windows = edge_pad(x, left, right, time_dim=0).unfold(0, left + 1 + right, 1)  # (T, ..., W)
    return windows.movedim(-1, 1)


def _residual_pass(generator: Any, motion: Motion, target: Skeleton) -> tuple[Tensor, Tensor]:
    """``(T, 22, 4)`` rotations and ``(T, 3)`` root of a residual generator on a whole clip."""
    device = module_device(generator)
    q, r, off_a = (x.to(device) for x in motion.torch())
    off_b = torch.as_tensor(target.offsets, dtype=torch.float32, device=device)
    q_b, r_b = generator.retarget(q[None], r[None], off_a, off_b)
    return q_b[0], r_b[0]


def mirror_averaged(generator: Any, motion: Motion, target: Skeleton) -> tuple[Tensor, Tensor]:
    """A residual generator's result made mirror-symmetric: the mean of ``R(m, s)`` and the mirror
    image of ``R(mirror(m), mirror(s))``.

    Retargeting commutes with a left/right mirror: the mirror image of a clip onto the mirror
    image of a character is the mirror image of the result. The network learns this only
    approximately (mirror augmentation in training), and on real characters the default one
    lifted the right foot more than the left (standing on the clap clip: right sole 1.0 % of the
    height above the floor, left 0.0). The mean of the two passes (rotations by slerp at 1/2, root
    positions averaged) obeys the symmetry exactly; on a clip onto its own skeleton both passes
    are the input, so identity stays exact.

    Args:
        generator: a residual :class:`~retarget_lib.models.TDCNGenerator` (eval mode).
        motion: source clip on the canonical 22 joints.
        target: canonical-22 target skeleton.

    Returns:
        ``(T, 22, 4)`` unit wxyz rotations and ``(T, 3)`` root positions (metres).
    """
    q_a, r_a = _residual_pass(generator, motion, target)
    q_m, r_m = _residual_pass(generator, motion.mirror(), target.mirror())
    q_back, r_back = target.mirror_pose(q_m, r_m)
    return quat_slerp(q_a, q_back, 0.5), (r_a + r_back) / 2


def retarget_motion_with(
    generator: Any,
    motion: Motion,
    target: Skeleton,
    windowed: bool = False,
    chunk: int = 256,
    mirror_average: bool = True,
) -> Motion:
    """Retarget a whole clip with a trained TDCN/NKN generator (any length).

    A residual generator (``ours-residual``) has translation-invariant inputs and the source's
    leg-scaled root as its root: it runs on the clip as it is (``windowed`` is not needed), on top
    of the copy-rest base (the rotation deltas from the retarget pose), once on the clip and once
    on its mirror image, averaged (:func:`mirror_averaged`; ``mirror_average=False``: one pass).

    ``windowed=False`` (the paper, Sec. 3.1): the clip is centred like the training windows
    (:func:`centre_root`) and run through the network in one pass; the removed horizontal shift
    is added back scaled by the leg ratio ``h_legs_B / h_legs_A``
    (:func:`~retarget_lib.core.quantities.leg_ratio`), the scale of the ground truth's root path
    (and of ``copy``'s). The network's own root inside the window is what it learned (``H``-scaled
    under Eqs. 15-16); scaling the shift by ``H(s̄B) / H(s̄A)`` too put a travelling clip metres
    from its ground truth, since the two ratios differ by up to 10% between characters. A long
    travelling clip feeds root positions far outside the ±(half a window's travel) seen in
    training.

    ``windowed=True`` (TDCN only, our variant): every output frame ``t`` is computed from its own
    receptive field (81 frames around ``t``, the past 81 for the causal A5), centred exactly like
    a training window, and its shift added back — every frame sees training-like root positions,
    at ``T`` network evaluations of one window each. Identical to ``windowed=False`` when the
    root does not travel.

    Args:
        generator: a ``TDCNGenerator`` or ``NKNGenerator`` with its ``.config``, e.g. from
            :func:`load_generator` (eval mode).
        motion: source clip on the canonical 22 joints (``T`` frames, metres).
        target: canonical-22 target skeleton.
        windowed: per-frame re-centred windows (needs a
            :class:`~retarget_lib.models.TDCNGenerator`).
        chunk: windows per network call when ``windowed``.
        mirror_average: a residual generator's result averaged with its mirror image's
            (:func:`mirror_averaged`, the default); False: one pass, the network alone.

    Returns:
        the target's :class:`~retarget_lib.core.motion.Motion` (``T`` frames, unit quaternions),
        computed on the generator's device.
    """
    device = module_device(generator)
    q, r, off_a = (x.to(device) for x in motion.torch())
    off_b = torch.as_tensor(target.offsets, dtype=torch.float32, device=device)
    ratio = leg_ratio(motion.skeleton, target)  # the ground truth's path scale, as `copy`'s
    with torch.inference_mode():
        if getattr(
            generator, "residual", False
        ):  # translation-invariant inputs, analytic root: no centring
            q_b, r_b = (
                mirror_averaged(generator, motion, target)
                if mirror_average
                else _residual_pass(generator, motion, target)
            )
            shift = r.new_zeros(3)
        elif not windowed:
            r, shift = centre_root(r)
            q_b, r_b = (x[0] for x in generator.retarget(q[None], r[None], off_a, off_b))
        elif isinstance(generator, TDCNGenerator):
            left, right = generator.body.pad_amounts
            r_win, shift = centre_root(_frame_windows(r, left, right))  # (T, W, 3), (T, 3)
            q_win = _frame_windows(q, left, right)  # (T, W, J, 4)
            outs = [
                generator.retarget(q_win[i : i + chunk], r_win[i : i + chunk], off_a, off_b)
                for i in range(0, len(q_win), chunk)
            ]
            q_b = torch.cat([o[0][:, left] for o in outs])
            r_b = torch.cat([o[1][:, left] for o in outs])
        else:
            raise ValueError(
                f"windowed retargeting needs a TDCNGenerator, got {type(generator).__name__}"
            )
    return motion.copy(
        skeleton=target.copy(),
        rotations=q_b.double().cpu().numpy(),
        root_positions=(r_b + shift * ratio).double().cpu().numpy(),
        meta=dict(motion.meta, retargeted=generator.config["kind"]),
    )


def generator_retargeter(
    checkpoint: str | os.PathLike,
    kind: str,
    device: str | torch.device | None = None,
) -> Callable[[Motion, Skeleton], Motion]:
    """``retarget(motion, target_skeleton)`` with the generator of ``checkpoint``, which must hold
    a ``kind`` model (``"tdcn"``: a TDCN row; ``"nkn"``: a Baseline row of Table 4), on ``device``
    (default the CPU).

    Raises:
        ValueError: the checkpoint holds the other kind of model (named in the message).
    """
    generator, config = load_generator(checkpoint, device)
    row = config["model"]["row"]
    if row.startswith("Baseline") != (kind == "nkn"):
        raise ValueError(f"checkpoint holds the {row!r} model, not a {kind} one")
    return partial(retarget_motion_with, generator)


def load(
    checkpoint: str | os.PathLike,
    device: str | torch.device | None = None,
) -> Callable[[Motion, Skeleton], Motion]:
    """The registry's loader: :func:`retarget_motion_with` a TDCN generator on ``device``."""
    return generator_retargeter(checkpoint, "tdcn", device)
