"""Speed benchmarks (``retarget bench``): every timing is reported beside a reference measured in
the same run, as a ratio — never as an absolute pass/fail in a unit test.

FK: 64 clips x 240 frames x 22 joints; forward, and forward + backward; reference = a per-frame,
per-joint NumPy loop (how FK is often written first).
"""

from __future__ import annotations

import os
import platform
from collections.abc import Callable

import numpy as np
import torch

from ..config import load_config
from ..core.kinematics import forward_kinematics
from ..core.rotations import quat_mul, quat_rotate
from ..core.skeleton import CANONICAL22_PARENTS
from ..files import REPO_ROOT
from ..models import PROFILE_WIDTHS
from ..models.tdcn import TDCNGenerator
from ..training.contact import ContactTraining
from ..training.tdcn import RetargetTraining
from .bench_contact import bench_eint, bench_eso
from .timing import BenchRow, format_table, time_it


def numpy_fk_loop(
    rotations: np.ndarray, offsets: np.ndarray, parents, root: np.ndarray
) -> np.ndarray:
    """Reference FK: a Python loop over frames and joints with NumPy 3-vectors.

    Args:
        rotations: ``(F, J, 4)`` local wxyz.
        offsets: ``(J, 3)``.
        parents: ``J`` parents.
        root: ``(F, 3)``.

    Returns:
        ``(F, J, 3)`` global positions.
    """
    out = np.empty(rotations.shape[:2] + (3,))
    for f in range(rotations.shape[0]):
        gq = [None] * len(parents)
        for j, p in enumerate(parents):
            w, x, y, z = rotations[f, j]
            if p < 0:
                gq[j] = (w, x, y, z)
                out[f, j] = root[f]
                continue
            pw, px, py, pz = gq[p]
            gq[j] = (
                pw * w - px * x - py * y - pz * z,
                pw * x + px * w + py * z - pz * y,
                pw * y - px * z + py * w + pz * x,
                pw * z + px * y - py * x + pz * w,
            )
            u = np.array((px, py, pz))
            t = 2.0 * np.cross(u, offsets[j])
            out[f, j] = out[f, p] + offsets[j] + pw * t + np.cross(u, t)
    return out


def torch_fk_per_joint(
    rotations: torch.Tensor, offsets: torch.Tensor, parents, root: torch.Tensor
) -> torch.Tensor:
    """Reference FK as public retargeting code usually writes it: batched over frames, one joint
    at a time with quaternion products. ``rotations (..., J, 4)``, ``offsets (J, 3)``,
    ``root (..., 3)`` → ``(..., J, 3)``."""
    gq, gp = [rotations[..., 0, :]], [root]
    for j in range(1, len(parents)):
        p = parents[j]
        gp.append(gp[p] + quat_rotate(gq[p], offsets[j]))
        gq.append(quat_mul(gq[p], rotations[..., j, :]))
    return torch.stack(gp, -2)


def bench_fk(clips: int = 64, frames: int = 240, quick: bool = False) -> list[BenchRow]:
    """FK forward and forward+backward vs the NumPy loop, on random unit quaternions."""
    gen = torch.Generator().manual_seed(0)
    rot = torch.randn(clips, frames, 22, 4, generator=gen)
    rot = rot / rot.norm(dim=-1, keepdim=True)
    off = torch.randn(22, 3, generator=gen) * 0.1
    root = torch.randn(clips, frames, 3, generator=gen)
    repeat = 5 if quick else 15
    fwd = time_it(lambda: forward_kinematics(rot, off, CANONICAL22_PARENTS, root), repeat=repeat)
    rot_g = rot.clone().requires_grad_()

    def fwd_bwd():
        rot_g.grad = None
        forward_kinematics(
            rot_g, off, CANONICAL22_PARENTS, root
        ).positions.square().sum().backward()

    fb = time_it(fwd_bwd, repeat=repeat)
    per_joint = time_it(
        lambda: torch_fk_per_joint(rot, off, CANONICAL22_PARENTS, root), repeat=repeat
    )

    def per_joint_fwd_bwd():
        rot_g.grad = None
        torch_fk_per_joint(rot_g, off, CANONICAL22_PARENTS, root).square().sum().backward()

    per_joint_fb = time_it(per_joint_fwd_bwd, repeat=repeat)
    # the NumPy loop is slow: time a slice of clips and scale to the full batch (linear in frames)
    n_ref = 2 if quick else 8
    r_np, o_np, t_np = (
        rot[:n_ref].reshape(-1, 22, 4).double().numpy(),
        off.double().numpy(),
        root[:n_ref].reshape(-1, 3).double().numpy(),
    )
    ref = time_it(lambda: numpy_fk_loop(r_np, o_np, CANONICAL22_PARENTS, t_np), repeat=1, warmup=0)
    ref *= clips / n_ref
    label = f"{clips}x{frames}x22"
    ref_name = f"NumPy per-frame loop ({n_ref} clips timed, scaled)"
    return [
        BenchRow(f"FK forward {label}", fwd, ref_name, ref, "<= 10 ms"),
        BenchRow(f"FK forward {label}", fwd, "per-joint PyTorch loop", per_joint, "<= 10 ms"),
        BenchRow(f"FK forward+backward {label}", fb, ref_name, ref),
        BenchRow(f"FK forward+backward {label}", fb, "per-joint PyTorch loop", per_joint_fb),
    ]


def plain_dilated_body(in_channels: int, channels: int, dilations=(3, 9, 27)) -> torch.nn.Module:
    """Reference: the TDCN body written plainly (Conv1d + BatchNorm1d + LeakyReLU + Dropout per
    layer, residual centre crops, nothing fused) — "a plain PyTorch dilated-convolution body"."""
    nn = torch.nn

    def unit(cin, cout, k, d=1):
        return nn.Sequential(
            nn.Conv1d(cin, cout, k, dilation=d),
            nn.BatchNorm1d(cout),
            nn.LeakyReLU(0.2),
            nn.Dropout(0.1),
        )

    class Body(nn.Module):
        def __init__(self):
            super().__init__()
            self.first = unit(in_channels, channels, 3)
            self.blocks = nn.ModuleList(
                nn.Sequential(unit(channels, channels, 3, d), unit(channels, channels, 1))
                for d in dilations
            )
            self.pads = dilations

        def forward(self, x):
            h = self.first(x)
            for block, d in zip(self.blocks, self.pads, strict=False):
                h = h[..., d:-d] + block(h)
            return h

    return Body()


def bench_tdcn(quick: bool = False, frames: int = 1000) -> list[BenchRow]:
    """TDCN inference on one clip (features, network, output heads, FK), fast and paper width,
    beside the plain dilated-convolution body of the same width (same run)."""
    gen = torch.Generator().manual_seed(0)
    q = torch.randn(1, frames, 22, 4, generator=gen)
    q = q / q.norm(dim=-1, keepdim=True)
    r = torch.randn(1, frames, 3, generator=gen)
    off_a, off_b = torch.randn(22, 3, generator=gen) * 0.1, torch.randn(22, 3, generator=gen) * 0.1
    rows = []
    targets = {"fast": "<= 50 ms", "paper": "<= 350 ms"}
    for profile in ("fast", "paper"):
        width = PROFILE_WIDTHS[profile]["tdcn"]
        model = TDCNGenerator(channels=width).fuse_for_inference()
        body = plain_dilated_body(model.in_channels, width).eval()
        x = torch.randn(1, model.in_channels, frames + 80, generator=gen)

        def full(model=model):  # bound: B023 (called in this iteration)
            qh, rh = model.retarget(q, r, off_a, off_b)
            return forward_kinematics(qh, off_b, CANONICAL22_PARENTS, rh)

        with torch.inference_mode():
            t = time_it(full, repeat=3 if quick else 9)
            ref = time_it(lambda body=body, x=x: body(x), repeat=3 if quick else 9)
        rows.append(
            BenchRow(
                f"TDCN inference {frames} frames, {profile} width {width} (incl. features, heads, "
                "FK)",
                t,
                f"plain dilated-conv body, width {width}",
                ref,
                targets[profile],
            )
        )
    return rows


def bench_training(quick: bool = False, batch: int = 16) -> list[BenchRow]:
    """One full TDCN training step (Eq. 6: A→B→A cycle, all losses, G and D updates) of the paper's
    "ours" at fast and paper width and of the residual default at fast width, beside the
    generator's bare forward+backward on the same batch (same run); and the NKN Baseline's step
    with its per-frame GRU decoder compiled (the fast profile's ``train.compile``, compilation in
    the warm-up) beside the same step eager. Row names carry the throughput in windows/s."""
    rows = []
    for config, profile in (
        ("tdcn_paper", "fast"),
        ("tdcn_paper", "paper"),
        ("tdcn_ours_residual", "fast"),
    ):
        cfg = load_config(
            REPO_ROOT / "configs" / f"{config}.yaml", [f"train.batch={batch}"], profile=profile
        )
        run = RetargetTraining(cfg)
        step = time_it(lambda run=run: run.step(0), repeat=2 if quick else 5, warmup=1)
        sample = run.sampler.sample(batch)
        gen = run.generator.train()

        def bare(gen=gen, sample=sample):  # bound: B023 (called in this iteration)
            out = gen.generate(
                sample.rotations,
                sample.root_positions,
                sample.offsets_source,
                sample.offsets_target,
            )
            out.rotations.square().mean().backward()

        ref = time_it(bare, repeat=2 if quick else 5, warmup=1)
        rows.append(
            BenchRow(
                f"TDCN training step ({config}), {profile} width {cfg['model']['channels']}, "
                f"batch {batch}: {batch / step:.1f} windows/s",
                step,
                "generator forward+backward only",
                ref,
            )
        )
    steps = {}
    for compile in (
        True,
        False,
    ):  # NKN's GRU decoder runs per frame: compiled (the fast profile's) vs eager
        cfg = load_config(
            REPO_ROOT / "configs" / "tdcn_baseline.yaml",
            [f"train.batch={batch}", f"train.compile={str(compile).lower()}"],
            profile="fast",
        )
        run = RetargetTraining(cfg)
        steps[compile] = time_it(lambda run=run: run.step(0), repeat=2 if quick else 5, warmup=1)
    rows.append(
        BenchRow(
            "NKN Baseline training step (tdcn_baseline), fast, compiled GRU decoder, batch "
            f"{batch}: "
            f"{batch / steps[True]:.1f} windows/s",
            steps[True],
            f"the same step eager: {batch / steps[False]:.1f} windows/s",
            steps[False],
        )
    )
    return rows


def bench_contact_training(quick: bool = False) -> list[BenchRow]:
    """One contact-aware training step (Efull, Eqs. 1-9, of 60-frame windows at the fast profile)
    of the residual default: compiled (the fast profile's ``train.compile``, one-off compilation in
    the warm-up) beside the same step eager, and eager beside the Eskel row's energy (no mesh
    terms: what Ej2j, Eint and the skinned frame cost). Row names carry the throughput in
    windows/s."""

    def step_time(config: str, compile: bool) -> tuple[float, int]:
        cfg = load_config(
            REPO_ROOT / "configs" / f"{config}.yaml",
            [f"train.compile={str(compile).lower()}"],
            profile="fast",
        )
        run = ContactTraining(cfg)
        return time_it(
            lambda: run.step(run.steps // 2), repeat=2 if quick else 5, warmup=1
        ), run.batch

    compiled, batch = step_time("contact_residual", True)
    eager, _ = step_time("contact_residual", False)
    skeleton_only, _ = step_time("contact_eskel", False)
    return [
        BenchRow(
            "contact training step (contact_residual, Efull), fast, compiled decoder, batch "
            f"{batch}: "
            f"{batch / compiled:.1f} windows/s",
            compiled,
            f"the same step eager: {batch / eager:.1f} windows/s",
            eager,
        ),
        BenchRow(
            f"contact training step (contact_residual, Efull), fast, eager, batch {batch}: "
            f"{batch / eager:.1f} windows/s",
            eager,
            "the same step with Eskel only (contact_eskel)",
            skeleton_only,
        ),
    ]


#: every benchmark of ``retarget bench``, by name (``--only``)
BENCHES: dict[str, Callable[..., list[BenchRow]]] = {
    "fk": bench_fk,
    "tdcn": bench_tdcn,
    "training": bench_training,
    "contact-training": bench_contact_training,
    "eint": bench_eint,
    "eso": bench_eso,
}


def run(quick: bool = False, only: list[str] | None = None) -> str:
    """Run the benchmarks and return the Markdown table (also the header line with the machine)."""
    rows: list[BenchRow] = []
    for name, fn in BENCHES.items():
        if only and name not in only:
            continue
        rows += fn(quick=quick)
    header = (
        f"machine: {platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads{' (quick)' if quick else ''}"
    )
    return header + "\n\n" + format_table(rows)
