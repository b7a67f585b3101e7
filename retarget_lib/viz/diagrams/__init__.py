"""Schematic figures of the networks and pipelines, drawn by code from the library's own models
(networks: :mod:`.networks`; ESO and the methods' data flow: :mod:`.pipelines`; the drawing kit
and the readability check: :mod:`.canvas`).

Every function returns a matplotlib :class:`~matplotlib.figure.Figure` of about 9 x 4 inches
(boxes, arrows, text of at least 9 pt) that is not registered with pyplot, so returning it as the
last expression of a notebook cell shows it exactly once. Numbers in the pictures (widths, kernel
sizes, dilations, receptive fields, score counts) are read from the models built by
:func:`retarget_lib.models.build_model` or the configs, never typed:

* :func:`tdcn_generator_diagram` — the TDCN generator (Kim et al. 2020, Sec. 3.2, Fig. 2b) with
  a "dilation pyramid" of the frames one output frame sees;
* :func:`patch_discriminator_diagram` — the patch discriminator (Kim et al. Secs. 4.1-4.2, Fig. 3)
  next to NKN's whole-clip discriminator;
* :func:`nkn_diagram` — the NKN baseline (Villegas et al. 2018): GRU encoder-decoder with a
  forward-kinematics layer;
* :func:`georet_diagram` — the geometry-conditioned RNN (Villegas et al. 2021, Sec. 3.2, Fig. 3,
  Eqs. 12-19) with its PointNet;
* :func:`eso_loop_diagram` — encoder-space optimisation (Villegas et al. 2021, Sec. 3.3,
  Eqs. 10-11, App. B.1);
* :func:`method_dataflow_diagram` — BVH in to BVH out for each method of the registry, box by
  box with the library function that does the work.

:func:`layout_problems` lists what makes a diagram hard to read (text under 9 pt, text outside
its box or the canvas, overlapping text); the tests require it to be empty for every diagram.
"""

from .canvas import layout_problems
from .networks import (
    dilation_offsets,
    georet_diagram,
    nkn_diagram,
    patch_discriminator_diagram,
    tdcn_generator_diagram,
)
from .pipelines import (
    DATAFLOW_METHODS,
    dataflow_stages,
    eso_loop_diagram,
    method_dataflow_diagram,
    resolve_stage,
)

__all__ = [
    "tdcn_generator_diagram",
    "patch_discriminator_diagram",
    "nkn_diagram",
    "georet_diagram",
    "eso_loop_diagram",
    "method_dataflow_diagram",
    "DATAFLOW_METHODS",
    "dataflow_stages",
    "dilation_offsets",
    "layout_problems",
    "resolve_stage",
]
