"""Pictures: offscreen PyVista renders of skeletons and skinned meshes (PNG, GIF/MP4), side-by-side
lineups, matplotlib trajectory and timeline plots, a notebook motion player, and schematic diagrams
of the networks and pipelines drawn from the models themselves (:mod:`.diagrams`)."""

from .animate import animate, animate_mesh, animate_motion, render_frames, write_animation
from .camera import VIEWS, fit_camera
from .colorkeys import add_colorbar, add_legend, categorical_colors
from .diagrams import (
    eso_loop_diagram,
    georet_diagram,
    layout_problems,
    method_dataflow_diagram,
    nkn_diagram,
    patch_discriminator_diagram,
    tdcn_generator_diagram,
)
from .display import png_bytes, show, show_gif
from .knobs import Knob, figure_image, knob
from .layout import stand_on_floor
from .player import Player, player
from .plots import (
    plain_log_ticks,
    plot_grouped_barh,
    plot_root_trajectories,
    plot_skeleton_mpl,
    plot_timeline,
)
from .plotter import SceneRenderer, configure_offscreen
from .render import (
    render_filmstrip,
    render_mesh,
    render_scenes,
    render_side_by_side,
    render_skeleton,
    save_png,
)
from .scene import PALETTE, Scene

__all__ = [
    "PALETTE",
    "VIEWS",
    "Scene",
    "SceneRenderer",
    "configure_offscreen",
    "render_mesh",
    "render_scenes",
    "render_filmstrip",
    "render_side_by_side",
    "render_skeleton",
    "save_png",
    "animate",
    "animate_mesh",
    "animate_motion",
    "render_frames",
    "write_animation",
    "Knob",
    "knob",
    "figure_image",
    "png_bytes",
    "show",
    "show_gif",
    "Player",
    "player",
    "plot_root_trajectories",
    "plot_skeleton_mpl",
    "plot_timeline",
    "tdcn_generator_diagram",
    "patch_discriminator_diagram",
    "nkn_diagram",
    "georet_diagram",
    "eso_loop_diagram",
    "method_dataflow_diagram",
    "layout_problems",
    "add_colorbar",
    "add_legend",
    "categorical_colors",
    "fit_camera",
    "stand_on_floor",
    "plot_grouped_barh",
    "plain_log_ticks",
]
