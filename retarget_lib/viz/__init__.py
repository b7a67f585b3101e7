"""Pictures: offscreen PyVista renders of skeletons and skinned meshes (PNG, GIF/MP4), side-by-side
lineups, matplotlib trajectory and timeline plots, and a notebook motion player."""

from .animate import animate, animate_mesh, animate_motion, render_frames, write_animation
from .display import png_bytes, show, show_gif
from .knobs import Knob, figure_image, knob
from .player import Player, player
from .plots import (plain_log_ticks, plot_grouped_barh, plot_root_trajectories, plot_skeleton_mpl,
                    plot_timeline)
from .render import (PALETTE, VIEWS, Scene, SceneRenderer, configure_offscreen, render_filmstrip,
                     render_mesh, render_scenes, render_side_by_side, render_skeleton, save_png)

__all__ = [
    "PALETTE", "VIEWS", "Scene", "SceneRenderer", "configure_offscreen", "render_mesh", "render_scenes", "render_filmstrip",
    "render_side_by_side", "render_skeleton", "save_png", "animate", "animate_mesh", "animate_motion",
    "render_frames", "write_animation", "Knob", "knob", "figure_image", "png_bytes", "show", "show_gif", "Player", "player",
    "plot_root_trajectories", "plot_skeleton_mpl", "plot_timeline", "plot_grouped_barh", "plain_log_ticks",
]
