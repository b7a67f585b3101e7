"""Diagrams of the pipelines: encoder-space optimisation (Villegas et al. 2021, Sec. 3.3) and, for
each method of the registry, BVH in to BVH out box by box with the library function that does the
work (:func:`resolve_stage` finds it).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any, NamedTuple

from matplotlib.figure import Figure

from ...config import load_config
from ...files import REPO_ROOT
from .canvas import FONT, MIN_FONT, Canvas

__all__ = [
    "DATAFLOW_METHODS",
    "Stage",
    "dataflow_stages",
    "eso_loop_diagram",
    "method_dataflow_diagram",
    "resolve_stage",
]


def _eso_settings(eso_config: Mapping[str, Any] | None) -> dict[str, Any]:
    if eso_config is not None:
        return dict(eso_config)
    return dict(load_config(REPO_ROOT / "configs" / "contact_paper.yaml")["eso"])


def eso_loop_diagram(eso_config: Mapping[str, Any] | None = None) -> Figure:
    """Encoder-space optimisation (Villegas et al. 2021, Sec. 3.3, Eqs. 10-11, App. B.1).

    For frame ``t`` the decoder's weights are frozen; the encoder state ``h^enc_t`` and the previous
    root velocity ``o_{t-1}`` are the variables. Decode → FK + skinning → ``E_full(t)`` → gradient
    through the frozen decoder → Adam step, ``N`` times; then frame ``t`` is decoded with the
    optimised values, kept, and the decoder state carried to ``t + 1``
    (:func:`retarget_lib.methods.eso.encoder_space_optimization`).

    Args:
        eso_config: the ``eso`` settings (``iterations``, ``lr``, ``reach``); default the
            ``eso:`` section of ``configs/contact_paper.yaml``.

    Returns:
        the figure.
    """
    s = _eso_settings(eso_config)
    n, lr, reach = int(s["iterations"]), float(s["lr"]), float(s["reach"])
    cv = Canvas(9.0, 4.2, "Encoder-space optimisation (Villegas et al. 2021, Sec. 3.3) for frame t")
    var = cv.box(
        0.2, 2.55, 2.2, 0.7, "variables", "$h^{enc}_t$ and $o_{t-1}$", role="opt", lw=1.8, edge="C1"
    )
    dec = cv.box(
        3.2, 2.55, 2.5, 0.7, "decoder + heads (frozen)", "weights fixed, Eqs. 13-17", role="rnn"
    )
    fk = cv.box(6.45, 2.55, 2.4, 0.7, "FK + skinning", "joints, mesh of frame t", role="fk")
    en = cv.box(
        6.45,
        1.1,
        2.4,
        0.85,
        "$E_{full}(t)$  (Eq. 10)",
        "j2j, hold, int,\nfoot, ee, weak",
        role="energy",
    )
    grad = cv.box(
        3.2,
        1.1,
        2.5,
        0.85,
        "gradient",
        "$\\partial E/\\partial h^{enc}_t$, $\\partial E/\\partial o_{t-1}$\nthrough the frozen "
        "decoder",
        role="head",
    )
    adam = cv.box(0.2, 1.1, 2.2, 0.85, "Adam step", f"lr {lr:g} (App. B.1)", role="opt")
    cv.arrow(var.right, dec.left)
    cv.arrow(dec.right, fk.left)
    cv.arrow(fk.bottom, en.top)
    cv.arrow(en.left, grad.right)
    cv.arrow(grad.left, adam.right)
    cv.arrow(adam.top, var.bottom, color="C1", lw=2.0)
    cv.text(1.42, 2.25, f"repeat N = {n} times", size=10, color="C1", weight="bold", ha="left")
    init = cv.box(0.2, 3.45, 2.2, 0.42, "from the encoder", "$h^{enc}_t$ (Eq. 12)", role="data")
    cv.arrow(init.bottom, var.top)
    cv.text(4.55, 3.62, "constraints fixed once per frame from the initial output:", size=MIN_FONT)
    cv.text(
        4.55, 3.38, f"contact pairs within {reach * 100:g} cm, colliding triangles", size=MIN_FONT
    )
    cv.text(
        4.5, 0.6, "after N steps: decode frame t with the optimised values, keep it,", size=MIN_FONT
    )
    cv.text(4.5, 0.36, "carry the decoder state to frame t + 1 (Eq. 11)", size=MIN_FONT)
    cv.fig.iterations = n
    return cv.fig


# ---------------------------------------------------------------------------------------- data flow
class Stage(NamedTuple):
    """One box of a method's data flow: what happens and which library object does it."""

    title: str
    function: str  # dotted path under retarget_lib
    role: str = "data"

    @property
    def short(self) -> str:
        return (
            self.function.rsplit(".", 1)[-1]
            if not self.function.split(".")[-2][:1].isupper()
            else ".".join(self.function.split(".")[-2:])
        )


_READ = [
    Stage("read the BVH", "io.bvh.load_bvh", "io"),
    Stage("fold onto 22 joints", "io.joint_maps.to_canonical22", "io"),
    Stage("resample to 30 fps", "core.motion.Motion.resample", "io"),
]
_WRITE = [
    Stage("back to source fps", "core.motion.Motion.resample", "io"),
    Stage("target's own joints", "core.canonical.unfold_from_canonical22", "io"),
    Stage("write the BVH", "io.bvh.save_bvh", "io"),
]
_METHOD_STAGES: dict[str, list[Stage]] = {
    "copy": [Stage("copy q; root x leg ratio", "methods.copy.copy_rotations", "fk")],
    "copy-unscaled": [Stage("copy q; root steps unscaled", "methods.copy.copy_unscaled", "fk")],
    "copy-rest": [
        Stage("rest-pose alignment C_j", "core.transfer.rest_alignment", "fk"),
        Stage("C⁻¹ q C, root x leg ratio", "core.transfer.retarget_ground_truth", "fk"),
    ],
    "tdcn": [
        Stage("load the generator", "methods.tdcn.load_generator", "data"),
        Stage("centre the root", "methods.tdcn.centre_root", "data"),
        Stage("features p, q, r, s̄B", "models.features.generator_features", "data"),
        Stage("TDCN (pad, convs, head)", "models.tdcn.TDCNGenerator.retarget", "conv"),
        Stage("unit q̂; root + shift", "methods.tdcn.retarget_motion_with", "out"),
    ],
    "nkn": [
        Stage("load the generator", "methods.tdcn.load_generator", "data"),
        Stage("features p, v", "models.features.nkn_source_features", "data"),
        Stage("GRU enc-dec + FK layer", "models.nkn.NKNGenerator.forward", "rnn"),
        Stage(
            "unit $\\hat{q}$; $\\hat{r}_0 + \\sum\\hat{v}$",
            "methods.tdcn.retarget_motion_with",
            "out",
        ),
    ],
    "contact": [
        Stage("target mesh + weights", "methods.inputs.load_target", "data"),
        Stage("source self-contacts", "methods.contact.contact_clip", "data"),
        Stage("contacts onto target", "geometry.contacts.transfer_contacts", "data"),
        Stage("features $m^A_t$", "models.georet.motion_features", "data"),
        Stage("RNN first guess", "models.georet.GeometryConditionedRNN", "rnn"),
        Stage("ESO, frame by frame", "methods.eso.encoder_space_optimization", "opt"),
    ],
}
#: methods :func:`method_dataflow_diagram` draws (the names of the method registry)
DATAFLOW_METHODS: tuple[str, ...] = tuple(_METHOD_STAGES)


def dataflow_stages(method: str) -> list[Stage]:
    """The boxes of ``method``'s data flow, BVH in to BVH out (``retarget retarget`` /
    :func:`retarget_lib.methods.retarget.retarget_file`).

    Raises:
        ValueError: an unknown method.
    """
    if method not in _METHOD_STAGES:
        raise ValueError(f"unknown method {method!r}; one of {list(_METHOD_STAGES)}")
    return _READ + _METHOD_STAGES[method] + _WRITE


def resolve_stage(stage: Stage):
    """The library object a stage names (``retarget_lib.<function>``), for tests and links."""
    parts = stage.function.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module("retarget_lib." + ".".join(parts[:split]))
        except ModuleNotFoundError:
            continue
        for attr in parts[split:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(stage.function)


def method_dataflow_diagram(method: str) -> Figure:
    """How ``method`` turns a BVH file into a BVH file, box by box (``retarget retarget``).

    Grey boxes are shared by every method (:func:`~retarget_lib.methods.retarget.retarget_file`:
    read, fold onto the canonical 22 joints, resample to 30 fps ... and back); the coloured boxes
    are the method's own. Each box names the library function that does the work.

    Methods: ``copy`` and ``copy-rest`` (the baselines of both papers), ``tdcn`` (Kim et al.
    2020), ``nkn`` (Villegas et al. 2018, TDCN's Table 4 baseline), ``contact`` (Villegas et al.
    2021: the geometry-conditioned RNN, then ESO).

    Args:
        method: one of :data:`DATAFLOW_METHODS`.

    Returns:
        the figure.
    """
    stages = dataflow_stages(method)
    ncols = 4
    rows = [stages[i : i + ncols] for i in range(0, len(stages), ncols)]
    width = 9.0
    longest = max(len(st.short) for st in stages)
    bw = max(1.9, 0.6 * MIN_FONT / 72 * longest + 0.16)  # monospace: 0.6 em per character
    bh, gy = 0.62, 0.42
    gx = min(0.3, (width - 0.1 - ncols * bw) / (ncols - 1))
    height = 0.55 + len(rows) * bh + (len(rows) - 1) * gy + 0.2
    cv = Canvas(width, height, f"method '{method}': BVH in → BVH out")
    x_start = (width - (ncols * bw + (ncols - 1) * gx)) / 2
    prev = None
    for r, row in enumerate(rows):
        y = height - 0.5 - bh - r * (bh + gy)
        for c, st in enumerate(row):
            x = x_start + c * (bw + gx)
            b = cv.box(
                x,
                y,
                bw,
                bh,
                st.title,
                st.short,
                role=st.role,
                mono_detail=True,
                size=MIN_FONT if len(st.title) > 22 else FONT,
            )
            if prev is not None:
                if c == 0:  # elbow from the end of the previous row to the start of this one
                    mid = y + bh + gy / 2
                    cv.polyline_arrow([prev.bottom, (prev.bottom[0], mid), (b.top[0], mid), b.top])
                else:
                    cv.arrow(prev.right, b.left)
            prev = b
    cv.fig.stages = stages
    return cv.fig
