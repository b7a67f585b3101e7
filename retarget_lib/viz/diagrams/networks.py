"""Diagrams of the networks, every number read from the models the library builds: the TDCN
generator with its dilation pyramid (Kim et al. 2020, Fig. 2b), the patch discriminator beside
NKN's whole-clip one (Fig. 3), the NKN baseline (Villegas et al. 2018) and the
geometry-conditioned RNN (Villegas et al. 2021, Fig. 3).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import FancyBboxPatch
from torch import nn

from ...models import build_model
from ...models.georet import GeometryConditionedRNN
from .canvas import MIN_FONT, Canvas

__all__ = [
    "dilation_offsets",
    "georet_diagram",
    "nkn_diagram",
    "patch_discriminator_diagram",
    "tdcn_generator_diagram",
]


# ------------------------------------------------------------------------------------------ TDCN
def dilation_offsets(
    kernels_dilations: Sequence[tuple[int, int]], causal: bool = False
) -> list[np.ndarray]:
    """Input-frame offsets that one output frame depends on, layer by layer (the dilation pyramid).

    Args:
        kernels_dilations: ``(kernel, dilation)`` of every temporal convolution, input side first
            (1x1 convolutions may be included; they change nothing).
        causal: taps at ``t - (k-1-i)·d`` (A5) instead of centred ``t + (i - (k-1)/2)·d``.

    Returns:
        ``levels[0]`` = offsets at the input, ..., ``levels[-1] = [0]`` (the output frame); each a
        sorted int array. ``levels[0].max() - levels[0].min() + 1`` is the receptive field.
    """
    levels = [np.array([0])]
    for k, d in reversed(list(kernels_dilations)):
        taps = np.array(
            [-(k - 1 - i) * d for i in range(k)]
            if causal
            else [(i - (k - 1) // 2) * d for i in range(k)]
        )
        levels.insert(0, np.unique(levels[0][:, None] + taps[None, :]))
    return levels


def _temporal_convs(generator) -> list[tuple[str, int, int, int, int]]:
    """``(name, kernel, dilation, in, out)`` of every Conv1d of a TDCN body, input side first."""
    return [
        (name, m.kernel_size[0], m.dilation[0], m.in_channels, m.out_channels)
        for name, m in generator.body.named_modules()
        if isinstance(m, nn.Conv1d)
    ]


def tdcn_generator_diagram(config: Mapping[str, Any] | None = None) -> Figure:
    """The TDCN generator of Kim et al. 2020 (Sec. 3.2, Fig. 2b) and the frames one output sees.

    Left: input features (Sec. 3.1, Eq. 2: local positions ``p``, quaternions ``q``, root ``r``
    and the target skeleton ``s̄B``), edge padding, the "3d1" convolution, the residual blocks
    (dilated convolution, 1x1 convolution, skip connection), the head and the outputs ``q̂``,
    ``r̂``.
    Right: the dilation pyramid — which frames of each layer feed one output frame.

    Every number is read from the generator that :func:`retarget_lib.models.build_model` builds
    for ``config`` (widths of the fast or paper profile, kernels, dilations, causal/dense
    variants), and the receptive field is computed from its convolutions.

    Args:
        config: a model config (default ``{"row": "ours", "profile": "fast"}``), e.g.
            ``{"row": "A5", "profile": "paper"}``.

    Returns:
        the figure; ``fig.receptive_field`` holds the receptive field drawn (frames).
    """
    config = {"row": "ours", "profile": "fast"} if config is None else dict(config)
    gen = build_model(config).generator
    if not hasattr(gen, "body") or not hasattr(gen.body, "pad_amounts"):
        raise ValueError("tdcn_generator_diagram draws TDCN generators; use nkn_diagram for NKN")
    convs = _temporal_convs(gen)
    causal = gen.body.causal
    levels = dilation_offsets([(k, d) for _, k, d, _, _ in convs], causal)
    rf = int(levels[0].max() - levels[0].min() + 1)
    j = gen.num_joints
    c = gen.body.channels
    left_pad, right_pad = gen.body.pad_amounts
    profile = gen.config.get("profile", "")
    variant = gen.config.get("variant", "ours")

    cv = Canvas(
        9.0,
        4.3,
        f"TDCN generator ({variant}, {profile} profile: C = {c})"
        "  ·  Kim et al. 2020, Sec. 3.2, Fig. 2b",
    )
    x0, w = 0.15, 4.05
    h, gap = 0.28, 0.15
    y = cv.height - 0.45 - h
    parts = f"p {3 * j} + q {4 * j} + r 3 + s̄B {3 * j}"
    c_in = gen.in_channels
    inp = cv.box(
        x0,
        y,
        w,
        h,
        f"features: {c_in} x T" + (f"  ({parts})" if c_in == 10 * j + 3 else ""),
        role="data",
    )
    y -= h + gap
    pad = cv.box(
        x0,
        y,
        w,
        h,
        f"edge padding: {left_pad} copies of frame 1, {right_pad} of frame T",
        role="io",
    )
    cv.arrow(inp.bottom, pad.top)
    first = convs[0]
    y -= h + gap
    prev = cv.box(
        x0, y, w, h, f"3d1: conv k={first[1]}, d={first[2]}, {first[3]} → {first[4]}", role="conv"
    )
    cv.arrow(pad.bottom, prev.top)
    temporal = [cv_ for cv_ in convs[1:] if cv_[1] > 1]
    cx = x0 + (w - 0.4) / 2
    for i, (_, k, d, _, _) in enumerate(temporal):
        y -= h + gap
        blk = cv.box(
            x0, y, w - 0.4, h, f"block {i + 1}: conv k={k}, d={d} → conv 1x1 (C={c})", role="conv"
        )
        cv.arrow((cx, prev.y), blk.top)
        # the skip connection: from above the block, around its right side, added below it (⊕)
        xs = x0 + w - 0.2
        cv.polyline_arrow(
            [
                (cx, y + h + gap / 2),
                (xs, y + h + gap / 2),
                (xs, y - gap / 2),
                (cx + 0.06, y - gap / 2),
            ],
            color="#7a7a7a",
            lw=1.1,
        )
        cv.ax.plot([cx], [y - gap / 2], marker="o", ms=7, mfc="white", mec="#555555", zorder=4)
        cv.ax.plot([cx], [y - gap / 2], marker="+", ms=6, color="#555555", zorder=5)
        prev = blk
    y -= h + gap
    head_hidden = gen.head.extra.out_features if gen.head.extra is not None else None
    head = cv.box(
        x0,
        y,
        w,
        h,
        f"head: 1x1 {c} → {head_hidden}, LeakyReLU, linear → {gen.head.out.out_features}"
        if head_hidden
        else f"head: linear {c} → {gen.head.out.out_features}",
        role="head",
    )
    cv.arrow((cx, prev.y), (cx, head.y + h))
    y -= h + gap
    q_out = cv.box(x0, y, w / 2 - 0.05, h, f"q̂: {j} x 4 raw quaternions", role="out")
    has_root = gen.head.out.out_features > 4 * j
    r_out = cv.box(
        x0 + w / 2 + 0.05,
        y,
        w / 2 - 0.05,
        h,
        "$\\hat{r}$: root position (3)" if has_root else "root: source x leg ratio",
        role="out",
    )
    cv.arrow(head.bottom, q_out.top)
    cv.arrow(head.bottom, r_out.top)
    cv.text(
        x0,
        y - 0.22,
        f"each conv: BatchNorm, LeakyReLU, dropout {gen.config.get('dropout', 0.1)}"
        "  ·  ⊕: skip connection",
        size=MIN_FONT,
        color="#444444",
        ha="left",
    )

    # the dilation pyramid
    ax = cv.fig.add_axes([0.655, 0.17, 0.33, 0.68])
    names = ["input", f"3d1 (d={first[2]})"] + [
        f"block {i + 1} (d={d})" for i, (_, _, d, _, _) in enumerate(temporal)
    ]
    names[-1] = f"output (d={temporal[-1][2]})" if temporal else names[-1]
    temporal_all = [(k, d) for _, k, d, _, _ in convs if k > 1]
    lo, hi = int(levels[0].min()), int(levels[0].max())
    lv = dilation_offsets(temporal_all, causal)  # the input, then the output of every temporal conv
    frames = np.arange(lo, hi + 1)
    for row, offsets in enumerate(lv):
        ax.scatter(frames, np.full(len(frames), row), s=3, color="#cccccc", zorder=1)
        ax.scatter(
            offsets,
            np.full(len(offsets), row),
            s=7 if row else 5,
            color="C3" if row == len(lv) - 1 else "C0",
            zorder=3,
        )
    segments = []
    for row in range(1, len(lv)):
        k, d = temporal_all[row - 1]
        taps = (
            [-(k - 1 - i) * d for i in range(k)]
            if causal
            else [(i - (k - 1) // 2) * d for i in range(k)]
        )
        for o in lv[row]:
            segments += [[(o, row), (o + tp, row - 1)] for tp in taps]
    ax.add_collection(LineCollection(segments, colors="C0", linewidths=0.5, alpha=0.5, zorder=2))
    ax.set_yticks(range(len(lv)))
    ax.set_yticklabels(names[: len(lv)], fontsize=MIN_FONT)
    ax.set_xlim(lo - 2, hi + 2)
    step = max(10, int(np.ceil((hi - lo) / 4 / 10) * 10))
    ax.set_xticks(
        [t for t in range(lo - lo % step, hi + 1, step) if lo <= t <= hi]
        if lo < 0 < hi
        else [t for t in range(hi - (hi - lo) // step * step, hi + 1, step)]
    )
    ax.set_ylim(-0.5, len(lv) - 0.5)
    ax.tick_params(axis="x", labelsize=MIN_FONT)
    ax.set_xlabel("input frame, relative to the output frame t", fontsize=MIN_FONT)
    ax.set_title(f"receptive field: {rf} frames (t{lo:+d} … t{hi:+d})", fontsize=10)
    ax.grid(False)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    cv.fig.receptive_field = rf
    cv.fig.generator_receptive_field = int(gen.receptive_field)
    return cv.fig


# ----------------------------------------------------------------------------------- discriminators
def patch_discriminator_diagram(
    config: Mapping[str, Any] | None = None, clip_frames: int = 120
) -> Figure:
    """TDCN's patch discriminator (Kim et al. 2020, Secs. 4.1-4.2, Fig. 3) beside NKN's whole-clip
    one.

    Top: the patch discriminator scores every window of ``RF`` frames (31, or 81 for A4) of the
    height-normalised features ``(l_t, δ_t, B)`` (Eqs. 18-20) with valid convolutions, giving one
    score per window. Bottom: the NKN baseline's discriminator (Villegas et al. 2018, as TDCN
    Sec. 4.1 describes it) reads the whole clip, unnormalised, and gives one logit.

    Receptive field, channels and the number of scores are read from the models
    (:func:`retarget_lib.models.build_model`); the score count is measured by running the
    discriminator on ``clip_frames`` frames of zeros.

    Args:
        config: TDCN model config (default ``{"row": "ours", "profile": "fast"}``).
        clip_frames: feature frames of the drawn clip.

    Returns:
        the figure; ``fig.scores`` = ``(patch scores, whole-clip scores)`` for ``clip_frames``.
    """
    config = {"row": "ours", "profile": "fast"} if config is None else dict(config)
    disc = build_model(config).discriminator.eval()
    nkn_disc = build_model(
        {"row": "Baseline", "profile": config.get("profile", "fast")}
    ).discriminator.eval()
    rf = disc.receptive_field
    with torch.no_grad():
        n_patch = disc(torch.zeros(1, disc.in_channels, clip_frames)).shape[-1]
        n_whole = nkn_disc(torch.zeros(1, nkn_disc.in_channels, clip_frames)).shape[-1]
    dil = [
        m.dilation[0]
        for m in disc.body.modules()
        if isinstance(m, torch.nn.Conv1d) and m.kernel_size[0] > 1
    ]
    widths = [m.out_channels for m in nkn_disc.body if isinstance(m, torch.nn.Conv1d)]

    cv = Canvas(9.0, 4.2, "Patch discriminator (TDCN, Sec. 4.1) vs whole-clip discriminator (NKN)")
    x0, x1 = 0.3, 6.0
    scale = (x1 - x0) / clip_frames

    def strip(y, h, n, color, start=0):
        xs = x0 + (start + np.arange(n)) * scale
        for x in xs:
            cv.ax.add_patch(
                FancyBboxPatch(
                    (x, y), scale * 0.85, h, boxstyle="square,pad=0", fc=color, ec="none"
                )
            )

    # top: patch
    y_in = 2.95
    cv.text(
        x0,
        y_in + 0.42,
        f"{clip_frames} frames of ($l_t$, $\\delta_t$, $B$): {disc.in_channels} channels, "
        "height-normalised (Eqs. 18-20)",
        ha="left",
        size=MIN_FONT,
    )
    strip(y_in, 0.22, clip_frames, "#9ecae1")
    y_sc = 2.1
    strip(y_sc, 0.22, n_patch, "#fdae6b", start=(rf - 1) // 2)
    colors = ["C3", "C2", "C4"]
    for c_, s in zip(colors, (0, (clip_frames - rf) // 2, clip_frames - rf), strict=False):
        xa, xb = x0 + s * scale, x0 + (s + rf) * scale
        cv.ax.plot(
            [xa, xa, xb, xb], [y_in - 0.04, y_in - 0.1, y_in - 0.1, y_in - 0.04], color=c_, lw=1.5
        )
        centre = x0 + (s + (rf - 1) / 2 + 0.4) * scale
        cv.arrow(((xa + xb) / 2, y_in - 0.1), (centre, y_sc + 0.24), color=c_, lw=1.2)
    cv.text(
        x0,
        y_sc - 0.2,
        f"{n_patch} scores: one per {rf}-frame window (valid convolutions)",
        ha="left",
        size=MIN_FONT,
    )
    cv.box(
        6.35,
        2.2,
        2.5,
        1.05,
        "patch discriminator",
        f"RF {rf} frames\ndilations 1, {', '.join(map(str, dil[1:]))}",
        role="conv",
    )
    cv.text(6.35 + 1.25, 1.95, "judges local detail", size=MIN_FONT, style="italic")

    # bottom: whole clip
    y_in2 = 1.05
    cv.text(
        x0,
        y_in2 + 0.42,
        f"{clip_frames} frames of NKN's input: {nkn_disc.in_channels} channels, in metres",
        ha="left",
        size=MIN_FONT,
    )
    strip(y_in2, 0.22, clip_frames, "#c7e9c0")
    cv.ax.plot(
        [x0, x0, x1, x1], [y_in2 - 0.04, y_in2 - 0.1, y_in2 - 0.1, y_in2 - 0.04], color="C2", lw=1.5
    )
    one = cv.box(x0 + (x1 - x0) / 2 - 0.2, 0.2, 0.4, 0.3, str(n_whole), role="#fdae6b")
    cv.arrow(((x0 + x1) / 2, y_in2 - 0.1), one.top, color="C2")
    cv.text(
        x0 + (x1 - x0) / 2 + 0.35, 0.35, "one logit for the whole clip", ha="left", size=MIN_FONT
    )
    cv.box(
        6.35,
        0.2,
        2.5,
        1.15,
        "whole-clip discriminator",
        f"{len(widths)} strided convs\n{'-'.join(map(str, widths))}, mean over time",
        role="rnn",
    )
    cv.fig.scores = (int(n_patch), int(n_whole))
    cv.fig.receptive_field = int(rf)
    return cv.fig


# ------------------------------------------------------------------------------------------ NKN
def nkn_diagram(config: Mapping[str, Any] | None = None) -> Figure:
    """The NKN baseline (Villegas, Yang, Ceylan, Lee 2018; TDCN Table 4 "Baseline"), unrolled in
    time.

    Per frame ``t``: the encoder GRU reads ``x_t = [p_t, v_t]`` (local joint positions, root
    offset); the decoder GRU reads the encoder state, the target skeleton ``s̄B`` and its own
    previous output ``p̂_{t-1}, v̂_{t-1}``; a linear layer gives raw quaternions ``q̂_t`` and the
    root offset ``v̂_t``; the forward-kinematics layer turns ``q̂_t`` into ``p̂_t`` on ``s̄B`` (fed
    back to the next step); the root is integrated, ``r̂_t = r̂_0 + Σ v̂``.

    Widths are read from the model :func:`retarget_lib.models.build_model` builds for ``config``.

    Args:
        config: NKN model config (default ``{"row": "Baseline", "profile": "fast"}``).

    Returns:
        the figure.
    """
    config = {"row": "Baseline", "profile": "fast"} if config is None else dict(config)
    gen = build_model(config).generator
    if getattr(gen, "backbone", None) != "gru":
        raise ValueError("nkn_diagram draws the GRU baseline (backbone 'gru')")
    j, hid = gen.num_joints, gen.hidden
    cv = Canvas(
        9.0,
        4.2,
        f"NKN baseline (Villegas et al. 2018), unrolled over frames  ·  hidden {hid}"
        f" ({gen.config.get('profile')} profile)",
    )
    cols = [("t-1", 0.75), ("t", 3.65), ("t+1", 6.55)]
    bw, bh = 2.2, 0.42
    rows = {"fk": 2.95, "lin": 2.2, "dec": 1.45, "enc": 0.7}
    boxes = []
    for i, (_label, x) in enumerate(cols):
        sub = ["t-1", "t", "t+1"][i]
        b = {
            "fk": cv.box(
                x,
                rows["fk"],
                bw,
                bh,
                f"FK layer → $\\hat{{p}}_{{{sub}}}$",
                f"$f_{{FK}}(\\hat{{q}}_{{{sub}}}, \\bar{{s}}_B)$",
                role="fk",
            ),
            "lin": cv.box(
                x,
                rows["lin"],
                bw,
                bh,
                "linear",
                f"$\\hat{{q}}_{{{sub}}}$ ({j}x4), $\\hat{{v}}_{{{sub}}}$ (3)",
                role="head",
            ),
            "dec": cv.box(
                x,
                rows["dec"],
                bw,
                bh,
                "decoder GRU",
                f"+ $\\bar{{s}}_B$, $\\hat{{p}}_{{{['t-2', 't-1', 't'][i]}}}$, $\\hat{{v}}$",
                role="rnn",
            ),
            "enc": cv.box(
                x,
                rows["enc"],
                bw,
                bh,
                "encoder GRU",
                f"$x_{{{sub}}} = [p_{{{sub}}}, v_{{{sub}}}]$  ({3 * j + 3})",
                role="rnn",
            ),
        }
        cv.arrow(b["enc"].top, b["dec"].bottom)
        cv.arrow(b["dec"].top, b["lin"].bottom)
        cv.arrow(b["lin"].top, b["fk"].bottom)
        boxes.append(b)
    for a, b in zip(boxes, boxes[1:], strict=False):
        cv.arrow(a["enc"].at(1, 0.35), b["enc"].at(0, 0.35), color="#2e7d32")
        cv.arrow(a["dec"].at(1, 0.25), b["dec"].at(0, 0.25), color="#2e7d32")
        # feedback: the previous FK output and root offset enter the next decoder step
        cv.polyline_arrow(
            [
                a["fk"].at(1, 0.5),
                (a["fk"].x + bw + 0.35, a["fk"].y + bh / 2),
                (a["fk"].x + bw + 0.35, b["dec"].y + 0.75 * bh),
                b["dec"].at(0, 0.75),
            ],
            color="C3",
        )
    cv.text(
        4.5,
        0.38,
        "green: recurrent states  ·  red: $\\hat{p}$, $\\hat{v}$ of the previous frame fed back",
        size=MIN_FONT,
        color="#444444",
    )
    cv.text(
        4.5,
        0.13,
        "root: $\\hat{r}_t = \\hat{r}_0 + \\sum\\hat{v}$ (offsets integrated, so errors "
        "accumulate; TDCN Sec. 6.1)",
        size=MIN_FONT,
        color="#444444",
    )
    cv.text(0.12, rows["enc"] + bh / 2, "source", ha="left", size=MIN_FONT)
    cv.text(0.12, rows["fk"] + bh / 2, "target", ha="left", size=MIN_FONT)
    return cv.fig


# ------------------------------------------------------------------------------------ contact-aware
def georet_diagram(model=None) -> Figure:
    """The geometry-conditioned RNN of Villegas et al. 2021 (Sec. 3.2, Fig. 3, Eqs. 12-19).

    PointNet (Qi et al. 2017) encodes the target's rest vertices and skinning weights into ``e^B``
    (Eq. 19); the encoder GRU turns the source features ``m^A_t`` into ``h^enc_t`` (Eq. 12); the
    decoder GRU reads ``[h^enc_t, p^B_{t-1}, o^B_{t-1}, s̄^B, e^B]`` (Eq. 13); the heads give the
    local rotations ``θ^B_t`` (6D, Eq. 14) and the root velocity ``o^B_t`` (Eq. 17); FK places the
    joints (Eqs. 15, 18) and linear blend skinning the mesh (Eq. 16), on which the energies of
    Sec. 3.1 are evaluated.

    Args:
        model: a :class:`~retarget_lib.models.georet.GeometryConditionedRNN` whose widths are
            drawn (default: App. B.1's, 512 hidden units).

    Returns:
        the figure.
    """
    model = GeometryConditionedRNN() if model is None else model
    j, hid, layers = model.joints, model.hidden, model.layers
    pn_in, pn_h = model.pointnet.in_features, model.pointnet.mlp[0].out_features
    m_in, dec_in = model.encoder.input_size, model.decoder[0].input_size
    cv = Canvas(9.0, 4.3, "Geometry-conditioned RNN (Villegas et al. 2021, Fig. 3) for frame t")
    # PointNet column
    v = cv.box(
        0.15,
        2.95,
        2.45,
        0.5,
        "rest mesh, V vertices",
        f"$[\\bar{{v}}_v, w_v]$: {pn_in} per vertex",
        role="data",
    )
    mlp = cv.box(
        0.15,
        2.05,
        2.45,
        0.55,
        "shared MLP (PointNet)",
        f"{pn_in} → {pn_h} → {pn_h}, each vertex",
        role="conv",
    )
    pool = cv.box(
        0.15, 1.15, 2.45, 0.55, "max over vertices", f"$e^B$ ({pn_h}), Eq. 19", role="conv"
    )
    cv.arrow(v.bottom, mlp.top)
    cv.arrow(mlp.bottom, pool.top)
    # RNN column
    m = cv.box(
        3.0, 0.2, 2.6, 0.5, "source features $m^A_t$", f"{m_in} = pos + rot + vel", role="data"
    )
    enc = cv.box(
        3.0, 1.0, 2.6, 0.55, f"encoder GRU, {layers} x {hid}", "$h^{enc}_t$  (Eq. 12)", role="rnn"
    )
    dec = cv.box(
        3.0,
        1.95,
        2.6,
        0.6,
        f"decoder GRU, {layers} x {hid}",
        f"{dec_in} inputs  (Eq. 13)",
        role="rnn",
    )
    sk = cv.box(
        0.15,
        0.2,
        2.45,
        0.5,
        "target skeleton $\\bar{s}^B$",
        f"{3 * j} rest offsets / $h_B$",
        role="data",
    )
    cv.arrow(m.top, enc.bottom)
    cv.arrow(enc.top, dec.bottom)
    cv.polyline_arrow(
        [pool.right, (2.72, pool.y + pool.h / 2), (2.72, dec.y + 0.45), dec.at(0, 0.75)]
    )
    cv.polyline_arrow([sk.right, (2.86, sk.y + sk.h / 2), (2.86, dec.y + 0.15), dec.at(0, 0.25)])
    th = cv.box(
        3.0, 2.95, 1.25, 0.5, "$f_\\theta \\rightarrow \\theta^B_t$", "6D, Eq. 14", role="head"
    )
    vo = cv.box(4.35, 2.95, 1.25, 0.5, "$f_o \\rightarrow o^B_t$", "Eq. 17", role="head")
    cv.arrow(dec.at(0.25, 1), th.bottom)
    cv.arrow(dec.at(0.75, 1), vo.bottom)
    # kinematics column
    fk = cv.box(6.05, 2.95, 2.8, 0.5, "FK + root", "$p^B_t$, $g^B_t$  (Eqs. 15, 18)", role="fk")
    skin = cv.box(
        6.05, 1.95, 2.8, 0.6, "linear blend skinning", "mesh $\\hat{v}^B_t$  (Eq. 16)", role="fk"
    )
    en = cv.box(
        6.05,
        0.95,
        2.8,
        0.6,
        "energies (Sec. 3.1)",
        "$E_{j2j}$, $E_{int}$, $E_{foot}$, $E_{skel}$",
        role="energy",
    )
    cv.arrow(vo.right, fk.left)
    cv.arrow(fk.bottom, skin.top)
    cv.arrow(skin.bottom, en.top)
    cv.arrow(th.at(0.5, 1), fk.at(0.1, 1), rad=-0.25)
    cv.polyline_arrow(
        [
            fk.at(0.85, 0),
            (fk.x + 0.85 * fk.w, 2.75),
            (5.85, 2.75),
            (5.85, dec.y + 0.45),
            dec.at(1, 0.75),
        ],
        color="C3",
    )
    cv.text(7.45, 0.55, "red: $p^B_{t-1}$, $o^B_{t-1}$ fed back", size=MIN_FONT, color="C3")
    cv.text(7.45, 0.3, "(next frame's decoder input)", size=MIN_FONT, color="C3")
    return cv.fig
