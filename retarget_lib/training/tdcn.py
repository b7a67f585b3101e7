"""Training the TDCN retargeting network and its Table 4 baselines/ablations (Kim et al. 2020,
Secs. 4-5), on the synthetic data, with the shared loop of :mod:`retarget_lib.training.loop`.

::

    from retarget_lib.config import load_config
    from retarget_lib.methods.tdcn import load_generator
    from retarget_lib.training.loop import fit
    from retarget_lib.training.tdcn import RetargetTraining

    cfg = load_config("configs/tdcn_paper.yaml", ["train.steps=300"], profile="fast")
    run = RetargetTraining(cfg)
    final = fit(run.task(), cfg, "runs/ours", cfg["train"]["steps"])
    generator, cfg = load_generator(final)          # eval mode, ready for inference

(or ``retarget train --config configs/tdcn_paper.yaml``).
Data (:mod:`retarget_lib.training.tdcn_data`): every training character performs every training
clip (its ground-truth transfer, or its own version); a sample is a source window, a target
character (the source itself half of the time) and a real window of the target, with the
balanced-data scaling of Sec. 5 and each window's root centred above the origin.

Step (:meth:`RetargetTraining.step`, Figs. 2a and 4, Eq. 6):

1. ``x̂B = G(xA, s̄B)`` (Eq. 4), FK of the unit ``q̂B`` on ``s̄B`` (Eq. 3); then the cycle
   ``x̂A = G(x̂B, s̄A)`` (Eq. 5) on the unit ``q̂B``, ``p̂B`` and ``r̂B``.
2. Generator loss ``Lc + λt Lt + λh Lh + λa La + λr Lr + λo Lo`` (:mod:`retarget_lib.losses`):
   Lc (Eq. 7) on raw ``q̂A``; Lt (Eq. 8) and Lr (Eq. 22) on raw ``q̂B`` and ``q̂A``; Lh (Eq. 17)
   between ``xA`` and ``x̂B`` — for NKN generators (which predict root *offsets*) on the offsets
   ``r_t − r_{t−1}``, the Baseline-height definition (Sec. 6 (iv)); La (Eq. 21) per sample:
   reconstruction when ``A = B``, else least squares (TDCN) or sigmoid cross-entropy (NKN,
   ``loss.gan``) on the discriminator's scores of ``x̂B`` (D frozen); Lo (Eq. 23) on the roots.
   Every term is computed and logged; a zero weight only drops it from the total.
3. Discriminator step: real windows of ``B`` → real, the detached ``x̂B`` of the ``A ≠ B``
   samples → fake (when ``A = B`` the output should *be* real motion; a batch without any ``A ≠ B``
   sample trains the real half only).
4. Adam (lr 1e-4, betas (0.5, 0.999), Sec. 5) for both.

NKN rows use the same step with their own config: sigmoid-CE GAN, ``λr = λo = 0`` (TDCN's
additions), ``λh = 0`` except Baseline-height, unbalanced data. NKN's own cycle loss compares
positions and root velocities; here every row uses Eq. 7 so that only the listed differences
separate the rows.

Checkpoints (``last.pt`` / ``final.pt`` of :func:`~retarget_lib.training.loop.fit`) hold the merged
config and the ``generator``/``discriminator`` state dicts (with the
:class:`~retarget_lib.models.features.FeatureNormalizer` buffers);
:func:`~retarget_lib.methods.tdcn.load_generator` rebuilds the generator from them, and
:func:`export_generator` writes its slim, float16 inference copy.

Speed (2 cores, 2 threads, one step = G and D updates; ``windows/s`` = batch / step time):

==============================  =====  =====  ===========  ==========
row                             width  batch  s/step       windows/s
==============================  =====  =====  ===========  ==========
ours (A2, A3, A5 alike), fast   256    16     0.28         58
A4 (81-frame D), fast           256    16     0.29         55
A1 (dense), fast                256    16     0.73         22
Baseline / -height (GRU), fast  128    16     0.25         63   (compiled decoder; eager 0.72)
Baseline-dense, fast            128    16     0.44         36
Baseline-dilated, fast          128    16     0.22         72
ours, paper width               1024   16     1.6          10
ours, paper                     1024   128    19.4         6.6
A1, paper                       1024   128    77           1.7
Baseline, paper                 512    128    2.9          43
==============================  =====  =====  ===========  ==========

The fast profile (2000 steps at batch 16 for every row, the second half with a decaying rate) takes
11-30 min of training per row on two cores (each checkpoint's ``trained_seconds`` in
``data_manifest.yaml``); the paper schedule (100k steps at batch 128) would be ~540 h for ours on
this CPU — a GPU job.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import torch

from ..core.measures import leg_length, nkn_height
from ..core.transfer import transfer_rotations_tensor
from ..data.checkpoints import save_state
from ..devices import autocast
from ..losses import (
    MotionTensors,
    PositionScale,
    TDCNLossWeights,
    adversarial_loss,
    adversarial_loss_discriminator,
    adversarial_loss_generator,
    bone_axes,
    bone_direction_loss,
    check_finite,
    cycle_loss,
    height_loss,
    orientation_loss,
    regularization_loss,
    root_smoothness_loss,
    sigmoid_ce_discriminator_loss,
    sigmoid_ce_generator_loss,
    total_generator_loss,
    twist_loss,
)
from ..losses.tdcn import CODE_END_EFFECTOR_IDS
from ..methods.tdcn import model_config
from ..models import build_model, normalize_quaternions, resolve_config
from ..models.features import (
    residual_generator_features,
    root_velocities,
    source_local_positions,
)
from .distributed import SINGLE, Distributed, prepare_module
from .loop import TrainTask, learning_rate, load_checkpoint, seed_everything
from .tdcn_data import TrainingBatch, TrainingClips, WindowSampler, config_training_clips

Tensor = torch.Tensor

__all__ = ["RetargetTraining", "export_generator", "loss_weights"]

#: (generator loss on scores, discriminator loss on (real, fake) scores) per ``loss.gan``
_GANS = {
    "lsgan": (adversarial_loss_generator, adversarial_loss_discriminator),
    "sigmoid_ce": (sigmoid_ce_generator_loss, sigmoid_ce_discriminator_loss),
}

#: how many windows the optional input normaliser is fitted on
_NORMALIZER_WINDOWS = 256

#: generator kinds whose exports store float16 weights. Measured on the shipped checkpoints: float16
#: moves the Table 4 numbers of every TDCN row by at most 2.6e-4 relative (and, for "ours", the
#: per-family means and CMU clips of notebook 08 by at most 5.8e-4), but the NKN Baseline-dense
#: Table 4 average by 1.1e-3, so NKN generators stay float32
HALF_PRECISION_KINDS = ("tdcn",)


# ------------------------------------------------------------------------------- configs


def loss_weights(config: dict) -> TDCNLossWeights:
    """:class:`~retarget_lib.losses.TDCNLossWeights` from the ``loss`` section (``lambda_*``
    keys)."""
    loss = config["loss"]
    return TDCNLossWeights(
        **{f.name: float(loss[f.name]) for f in fields(TDCNLossWeights) if f.name in loss}
    )


def _check_row(resolved: dict, config: dict, weights: TDCNLossWeights) -> None:
    """Refuse configs whose data/loss contradict the Table 4 row named in ``model.row``."""
    row = resolved.get("row", resolved["kind"])
    problems = []
    if resolved.get("data") == "unbalanced" and config["data"]["scale_range"] is not None:
        problems.append("data.scale_range must be null (unbalanced data)")
    if resolved.get("loss") == "no_height" and weights.lambda_h != 0:
        problems.append("loss.lambda_h must be 0 (no height loss)")
    if resolved["kind"] == "nkn" and bool(resolved.get("height_loss", False)) != (
        weights.lambda_h != 0
    ):
        problems.append(
            f"loss.lambda_h must be {'> 0' if resolved.get('height_loss') else '0'} "
            "for this NKN variant"
        )
    if resolved["kind"] != "nkn" and weights.lambda_s != 0:
        problems.append("loss.lambda_s must be 0 (the root smoothness needs NKN's root steps)")
    if config["loss"]["gan"] not in _GANS:
        problems.append(f"loss.gan must be one of {list(_GANS)}")
    if problems:
        raise ValueError(f"config {config.get('name', '?')!r} (row {row}): " + "; ".join(problems))


# ---------------------------------------------------------------------------- training
class RetargetTraining:
    """Generator, discriminator, optimisers, sampler and the training step of one Table 4 row.

    Construction seeds the global RNGs with ``config["seed"]`` so that the initial weights depend
    on the config only (:func:`~retarget_lib.training.loop.fit` then re-seeds for the data).

    Args:
        config: merged experiment config (:func:`~retarget_lib.config.load_config`) with sections
            ``model``, ``data`` (``window``, ``same_fraction``, ``scale_range``, ``scale_targets``,
            optional ``mirror``, ``random_yaw``, ``rest_jitter_deg``),
            ``loss`` (``gan``, ``twist_alpha_deg``, ``lambda_*``; optional ``reduction``,
            ``standardize``, and the authors' code's comparison of Lc and La's reconstruction,
            ``quaternion_weight`` and ``position_joints: end_effectors``; ``root_scale:
            leg_length`` for Lh's root term; ``root_term: velocity`` to compare the root's per-frame
            steps ``r_t - r_{t-1}`` in Lc and La instead of its path, as NKN's authors' losses
            compare their network's root output, with ``standardize`` z-scored on the steps) and
            ``train`` (``batch``, ``lr``, ``betas``, optional ``decay_from``, ``max_clips`` and
            ``max_characters`` in ``data`` for a capacity check).
        clips: training data (default :func:`config_training_clips` of ``data``).
        device: where the networks and each step's batch live (default CPU). Batches are drawn on
            the CPU either way, so every device sees the same data.
        amp: bfloat16 autocast for the forward passes (CUDA only,
            :func:`~retarget_lib.devices.autocast`).
        layout: this process's place in a ``torchrun`` job: each step draws the global batch
            ``train.batch`` and keeps this rank's shard (:mod:`~retarget_lib.training.distributed`).

    Attributes:
        generator, discriminator: the :class:`~retarget_lib.models.ModelPair`.
        sampler: the :class:`WindowSampler`.
        weights: the :class:`~retarget_lib.losses.TDCNLossWeights` of Eq. 6.
    """

    def __init__(
        self,
        config: dict,
        clips: TrainingClips | None = None,
        device: torch.device | None = None,
        amp: bool = False,
        layout: Distributed = SINGLE,
    ):
        self.config = config
        self.device, self.amp, self.layout = device or torch.device("cpu"), amp, layout
        self.rows = layout.shard(int(config["train"]["batch"]))
        autocast(self.device, amp)  # refuses --amp off CUDA before any work
        seed_everything(int(config["seed"]))
        self.generator, self.discriminator = build_model(model_config(config))
        self.resolved = self.generator.config
        self.weights = loss_weights(config)
        _check_row(self.resolved, config, self.weights)
        loss, data, train = config["loss"], config["data"], config["train"]
        self.gan, self.alpha_deg, self.batch = (
            loss["gan"],
            float(loss["twist_alpha_deg"]),
            int(train["batch"]),
        )
        self.twist_exclude_root = bool(loss.get("twist_exclude_root", False))
        self.twist_about_bone = loss.get("twist_measure", "angle") == "about_bone"
        self.gan_weight = float(loss.get("gan_weight", 1.0))
        self.clip_grad_norm = train.get("clip_grad_norm")
        self.reduction = loss.get("reduction", "mean")
        end_effectors_only = loss.get("position_joints") == "end_effectors"
        self.compare = dict(  # how Lc and La's reconstruction compare two motions
            quaternion_weight=float(loss.get("quaternion_weight", 1.0)),
            joints=CODE_END_EFFECTOR_IDS if end_effectors_only else None,
        )
        self.root_by_leg = loss.get("root_scale") == "leg_length"  # else Eqs. 15-16's H
        # Lc and La compare the root's per-frame steps instead of its path (NKN's own losses)
        self.root_steps = loss.get("root_term", "position") == "velocity"
        if clips is None:
            clips = config_training_clips(data)
        self.sampler = WindowSampler(
            clips,
            data["window"],
            data["same_fraction"],
            data["scale_range"],
            data["scale_targets"],
            bool(data.get("random_yaw", False)),
            float(data.get("rest_jitter_deg", 0.0)),
            float(data.get("rest_arm_drop_deg", 0.0)),
        )
        if self.resolved["normalize_inputs"]:
            self._fit_normalizer()
        self.position_scale = self._fit_position_scale() if loss.get("standardize", False) else None
        if bool(train.get("compile", False)) and hasattr(self.generator, "compile_decoder"):
            # NKN's per-frame GRU decoder; TDCN has no per-frame loop
            self.generator.compile_decoder()
        for module in (self.generator, self.discriminator):
            prepare_module(module, self.device, layout)
        adam = dict(lr=float(train["lr"]), betas=tuple(float(b) for b in train["betas"]))
        self.opt_g = torch.optim.Adam(self.generator.parameters(), **adam)
        self.opt_d = torch.optim.Adam(self.discriminator.parameters(), **adam)
        self.lr, self.steps = adam["lr"], int(train["steps"])
        self.decay_from = train.get("decay_from")

    def task(self) -> TrainTask:
        """The :class:`~retarget_lib.training.loop.TrainTask` for
        :func:`~retarget_lib.training.loop.fit`."""
        return TrainTask(
            {"generator": self.generator, "discriminator": self.discriminator},
            {"generator": self.opt_g, "discriminator": self.opt_d},
            self.step,
        )

    @torch.no_grad()
    def _fit_normalizer(self) -> None:
        """Fit the generator's input normaliser on source windows (own RNG: global state
        untouched)."""
        b = self.sampler.sample(
            _NORMALIZER_WINDOWS, torch.Generator().manual_seed(int(self.config["seed"]))
        )
        p = source_local_positions(b.rotations, b.offsets_source)
        if self.resolved["kind"] == "tdcn" and self.generator.residual:
            x = residual_generator_features(
                b.rotations, b.root_positions, b.offsets_source, b.offsets_target, p
            )
        elif self.resolved["kind"] == "tdcn":
            x = self.generator.input_features(
                b.rotations, b.root_positions, b.offsets_source, b.offsets_target, p
            )
        else:
            x = self.generator.source_features(p, b.root_positions, b.offsets_source)
        self.generator.normalizer.fit(x)

    @torch.no_grad()
    def _fit_position_scale(self) -> PositionScale:
        """The z-scores of ``loss.standardize`` (:class:`~retarget_lib.losses.tdcn.PositionScale`),
        fitted on source windows drawn with their own RNG (global state untouched)."""
        b = self.sampler.sample(
            _NORMALIZER_WINDOWS, torch.Generator().manual_seed(int(self.config["seed"]) + 1)
        )
        r = root_velocities(b.root_positions) if self.root_steps else b.root_positions
        return PositionScale.fit(source_local_positions(b.rotations, b.offsets_source), r)

    def _retarget(self, q: Tensor, r: Tensor, p: Tensor, off_src: Tensor, off_tgt: Tensor):
        """``G(x, s̄_tgt)`` (Eqs. 4-5) → (raw output, unit q̂ ``(B,W,J,4)``, ``p̂ = f_FK(q̂,
        s̄_tgt)``)."""
        out = self.generator.generate(q, r, off_src, off_tgt, positions=p)
        q_unit = normalize_quaternions(out.rotations)
        return out, q_unit, source_local_positions(q_unit, off_tgt)

    def _reference(self, q_a: Tensor, off_a: Tensor, off_b: Tensor) -> Tensor:
        """``(B, W, J, 3)`` positions of Ld's reference: the source's rotation deltas from the
        retarget pose on the target (copy-rest,
        :func:`~retarget_lib.core.transfer.transfer_rotations_tensor`)."""
        with torch.no_grad():
            return source_local_positions(transfer_rotations_tensor(q_a, off_a, off_b), off_b)

    def generator_terms(self, batch: TrainingBatch) -> tuple[dict[str, Tensor], MotionTensors]:
        """The six loss terms of Eq. 6 for one batch (D is used but not updated).

        Args:
            batch: a :class:`TrainingBatch`.

        Returns:
            ``(terms, x̂B)``: scalar tensors ``Lc, Lt, Lh, La, Lr, Lo, Ld`` and, for NKN, ``Ls``
            (unweighted), and the retargeted motion (``p (B,W,J,3)``, raw ``q (B,W,J,4)``,
            ``r (B,W,3)``).
        """
        q_a, r_a, off_a, off_b = (
            batch.rotations,
            batch.root_positions,
            batch.offsets_source,
            batch.offsets_target,
        )
        p_a = source_local_positions(q_a, off_a)
        out_b, q_b_unit, p_b = self._retarget(q_a, r_a, p_a, off_a, off_b)  # Eq. 4
        out_a, _, p_a_hat = self._retarget(
            q_b_unit, out_b.root_positions, p_b, off_b, off_a
        )  # Eq. 5
        steps = root_velocities if self.root_steps else (lambda r: r)
        x_a = MotionTensors(p_a, q_a, steps(r_a))
        x_b_hat = MotionTensors(p_b, out_b.rotations, out_b.root_positions)
        if out_b.root_velocities is None:
            root_a, root_b = r_a, out_b.root_positions
        else:  # NKN predicts root offsets: Lh on offsets (Baseline-height, Sec. 6 (iv))
            root_a, root_b = root_velocities(r_a), out_b.root_velocities
        x_a_hat = MotionTensors(p_a_hat, out_a.rotations, steps(out_a.root_positions))
        d, red = self.discriminator, self.reduction
        h_fake = d(d.features(p_b, out_b.root_positions, off_b))
        z = self.position_scale.apply if self.position_scale is not None else (lambda x: x)
        terms = {
            "Lc": cycle_loss(z(x_a), z(x_a_hat), red, **self.compare),
            "Lt": twist_loss(
                out_b.rotations,
                out_a.rotations,
                self.alpha_deg,
                exclude_root=self.twist_exclude_root,
                reduction=red,
                axes_b=bone_axes(off_b) if self.twist_about_bone else None,
                axes_a=bone_axes(off_a) if self.twist_about_bone else None,
            ),
            "Lh": height_loss(
                p_a,
                p_b,
                root_a,
                root_b,
                nkn_height(off_a),
                nkn_height(off_b),
                self.weights.lambda_g,
                red,
                (leg_length(off_a), leg_length(off_b)) if self.root_by_leg else None,
            ),
            "La": adversarial_loss(
                h_fake,
                z(x_a),
                z(x_b_hat._replace(r=steps(x_b_hat.r))),
                batch.same_character,
                gan=self.gan,
                reduction=red,
                gan_weight=self.gan_weight,
                **self.compare,
            ),
            "Lr": regularization_loss(out_b.rotations, out_a.rotations, red),
            "Lo": orientation_loss(q_a[:, :, 0], out_b.rotations[:, :, 0], red),
            "Ld": bone_direction_loss(
                self._reference(q_a, off_a, off_b), p_b, self.generator.parents, red
            ),
        }
        if out_b.root_velocities is not None and out_a.root_velocities is not None:  # NKN
            terms["Ls"] = root_smoothness_loss(out_b.root_velocities, out_a.root_velocities, red)
        return terms, x_b_hat

    def discriminator_loss(self, batch: TrainingBatch, x_b_hat: MotionTensors) -> Tensor:
        """Eq. 21 for D (LSGAN) or NKN's sigmoid CE: real windows of ``B`` vs the ``A ≠ B`` fakes.

        Args:
            batch: the batch the fakes were made from.
            x_b_hat: the generator's output (detached here).

        Returns:
            scalar loss; the real half only if the batch has no ``A ≠ B`` sample.
        """
        d, off_b = self.discriminator, batch.offsets_target
        g_loss, d_loss = _GANS[self.gan]
        p_real = source_local_positions(batch.real_rotations, off_b)
        h_real = d(d.features(p_real, batch.real_root_positions, off_b))
        fake = ~batch.same_character
        if not fake.any():
            return g_loss(h_real)  # = the "real → real" half of the discriminator loss
        h_fake = d(d.features(x_b_hat.p.detach()[fake], x_b_hat.r.detach()[fake], off_b[fake]))
        return d_loss(h_real, h_fake)

    def step(self, index: int) -> dict[str, float]:
        """One generator and one discriminator update (Eq. 6).

        The batch is drawn from the global RNGs on the CPU (in a multi-process run: the global
        batch, of which this rank keeps its shard) and moved to :attr:`device`.

        Args:
            index: step number (seeds this rank's dropout in a multi-process run; a single process
                draws everything from the global RNGs).

        Returns:
            ``{Lc, Lt, Lh, La, Lr, Lo, total, D}`` as floats (terms unweighted; this rank's shard).

        Raises:
            NonFiniteLossError: a weighted term, the total or the D loss is NaN/inf (named).
        """
        lr = learning_rate(self.lr, index, self.steps, self.decay_from)
        for opt in (self.opt_g, self.opt_d):
            for group in opt.param_groups:
                group["lr"] = lr
        batch = TrainingBatch(
            *(t[self.rows].to(self.device) for t in self.sampler.sample(self.batch))
        )
        with self.layout.rank_random(int(self.config["seed"]), index, self.device):
            self.discriminator.requires_grad_(False)  # La's gradient reaches G only
            try:
                with autocast(self.device, self.amp):
                    terms, x_b_hat = self.generator_terms(batch)
                    total, log = total_generator_loss(terms, self.weights)
                self.opt_g.zero_grad(set_to_none=True)
                total.backward()
                self.layout.average_gradients(self.generator)
                if self.clip_grad_norm is not None:  # NKN's code clips G and D at 25
                    torch.nn.utils.clip_grad_norm_(
                        self.generator.parameters(), float(self.clip_grad_norm)
                    )
                self.opt_g.step()
            finally:
                self.discriminator.requires_grad_(True)
            with autocast(self.device, self.amp):
                d_loss = check_finite("D", self.discriminator_loss(batch, x_b_hat))
            self.opt_d.zero_grad(set_to_none=True)
            d_loss.backward()
            self.layout.average_gradients(self.discriminator)
            if self.clip_grad_norm is not None:
                torch.nn.utils.clip_grad_norm_(
                    self.discriminator.parameters(), float(self.clip_grad_norm)
                )
            self.opt_d.step()
        log["D"] = float(d_loss.detach())
        return log


# ---------------------------------------------------------------------------- inference


def export_generator(checkpoint: str | Path, out: str | Path) -> Path:
    """Write a slim, inference-only copy of a training checkpoint (atomically): the generator's
    weights (normaliser included), the step and the config — no discriminator, optimiser or RNG
    state. :func:`~retarget_lib.methods.tdcn.load_generator` reads it like a full checkpoint.

    TDCN generators are stored as float16 (:data:`HALF_PRECISION_KINDS`; read back as float32),
    NKN generators as float32.

    Returns:
        ``out``.
    """
    state = load_checkpoint(checkpoint)
    slim = {
        "step": state["step"],
        "config": state["config"],
        "modules": {"generator": state["modules"]["generator"]},
    }
    kind = resolve_config(model_config(state["config"]))["kind"]
    return save_state(slim, out, half=kind in HALF_PRECISION_KINDS)
