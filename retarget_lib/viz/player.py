"""An ipywidgets motion player (frame slider + play button + motion picker + character picker) that
degrades to a still image when no Jupyter front end is attached.

How it degrades: the player's display bundle carries the widget view, an offline scrubber and a
PNG of the current frame. A live front end (JupyterLab, Notebook, VS Code) renders the widget. The
HTML book (``retarget_lib.notebook.book``) drops the widget view, whose script would load from a
CDN, and shows the scrubber: a handful of frames behind a slider made of inline HTML and JavaScript
(the same mechanism as :mod:`retarget_lib.viz.knobs`), nothing fetched from the network. Where no
script runs, the scrubber's ``<img>`` still shows the current frame, and viewers that prefer images
to HTML show the PNG. ``mode="static"`` forces the still image and scrubber (no widget is created),
``mode="widget"`` the widget; ``offline_frames=0`` leaves the scrubber out.
"""

from __future__ import annotations

from collections.abc import Mapping

import ipywidgets as widgets
import numpy as np

from ..core.transfer import retarget_ground_truth
from .display import png_bytes
from .knobs import Knob
from .plotter import SceneRenderer
from .scene import Scene


class Player:
    """Step through motions on characters.

    Args:
        motions: name -> :class:`~retarget_lib.core.motion.Motion` (canonical 22 joints for the
            character picker).
        characters: name -> :class:`~retarget_lib.core.character.Character` (skinned meshes).
            The character picker offers "performer" (the motion's own skeleton, drawn on
            ``characters[motion.meta["performer"]]`` when present, else as a skeleton) and every
            character, on which the motion is shown through ``transfer``.
        transfer: ``(motion, skeleton) -> motion`` used for another character (default: the
            ground-truth retargeting of :func:`retarget_lib.core.transfer.retarget_ground_truth`).
        mode: ``"auto"`` (widget plus still-image fallback), ``"widget"`` or ``"static"``.
        window_size: ``(width, height)`` of the picture.
        view: camera preset.
        offline_frames: frames of the current motion in the offline scrubber (evenly spaced, the
            current frame among them); 0 for none. Each is a small PNG stored in the notebook.
        offline_max_kb: size budget of each scrubber frame.
    """

    PERFORMER = "performer"

    def __init__(
        self,
        motions: Mapping,
        characters: Mapping | None = None,
        mode: str = "auto",
        window_size=(480, 320),
        view="front_side",
        transfer=None,
        offline_frames: int = 6,
        offline_max_kb: float = 30,
    ):
        if not motions:
            raise ValueError("Player needs at least one motion")
        if mode not in ("auto", "widget", "static"):
            raise ValueError(f"mode must be 'auto', 'widget' or 'static', got {mode!r}")
        self.motions = dict(motions)
        self.characters = dict(characters or {})
        self.mode, self.window_size, self.view = mode, window_size, view
        self.transfer = transfer
        self.offline_frames, self.offline_max_kb = int(offline_frames), offline_max_kb
        self.name = next(iter(self.motions))
        self.character = self.PERFORMER
        self._shown: dict[tuple[str, str], object] = {}
        self.frame = self.motions[self.name].num_frames // 2
        self._renderer: SceneRenderer | None = None
        self._box = None
        self.widget = None if mode == "static" else self._build_widget()

    # ------------------------------------------------------------------ drawing
    def shown_motion(self, name: str, character: str):
        """Motion ``name`` as drawn for ``character`` (transferred once, then cached)."""
        if character == self.PERFORMER:
            return self.motions[name]
        key = (name, character)
        if key not in self._shown:
            transfer = retarget_ground_truth if self.transfer is None else self.transfer
            self._shown[key] = transfer(self.motions[name], self.characters[character].skeleton)
        return self._shown[key]

    def scene(self, name: str, frame: int, character: str | None = None) -> Scene:
        """The :class:`Scene` of motion ``name`` at ``frame`` on ``character`` (a skinned mesh
        when a mesh is known, else the skeleton)."""
        character = self.character if character is None else character
        m = self.shown_motion(name, character)
        frame = int(np.clip(frame, 0, m.num_frames - 1))
        ch = self.characters.get(
            m.meta.get("performer", "") if character == self.PERFORMER else character
        )
        if ch is not None and ch.skeleton.offsets.shape == m.skeleton.offsets.shape:
            return Scene(
                vertices=ch.skinned(m.rotations[frame], m.root_positions[frame]), faces=ch.faces
            )
        return Scene(
            positions=m.global_positions()[frame],
            parents=m.skeleton.parents,
            joint_names=m.skeleton.joint_names,
        )

    def render(self, name: str | None = None, frame: int | None = None) -> np.ndarray:
        """``(H, W, 3)`` uint8 picture of ``name`` at ``frame`` (defaults: the current ones)."""
        name = self.name if name is None else name
        frame = self.frame if frame is None else frame
        if self._renderer is None:
            self._renderer = SceneRenderer(self.window_size, self.view)
        m = self.shown_motion(name, self.character)
        s = self.scene(name, frame)
        if self._box is None or self._box[0] != (name, self.character):
            pts = m.global_positions().reshape(-1, 3)
            size = max(s.size(), 0.5)
            lo, hi = pts.min(0) - 0.15 * size, pts.max(0) + 0.15 * size
            self._box = ((name, self.character), lo, hi, size)
        _, lo, hi, size = self._box
        self._renderer.update([s], size)
        self._renderer.frame(lo, hi, size)
        return self._renderer.screenshot()

    def scrubber(self) -> Knob | None:
        """The offline scrubber: ``offline_frames`` frames of the current motion on the current
        character behind an inline HTML slider (``None`` when ``offline_frames`` is 0)."""
        if self.offline_frames <= 0:
            return None
        n = self.shown_motion(self.name, self.character).num_frames
        frames = np.linspace(0, n - 1, max(self.offline_frames, 1)).round().astype(int).tolist()
        frames = sorted(set(frames) | {int(np.clip(self.frame, 0, n - 1))})
        images = [self.render(frame=f) for f in frames]
        return Knob(
            f"{self.name} on {self.character}, frame",
            frames,
            images,
            frames.index(int(np.clip(self.frame, 0, n - 1))),
            self.offline_max_kb,
        )

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ widget
    def _build_widget(self):
        m = self.motions[self.name]
        self.image = widgets.Image(format="png", value=png_bytes(self.render()))
        self.slider = widgets.IntSlider(
            value=self.frame,
            min=0,
            max=m.num_frames - 1,
            description="frame",
            continuous_update=True,
        )
        self.play = widgets.Play(
            value=self.frame, min=0, max=m.num_frames - 1, interval=int(1000 / m.fps)
        )
        widgets.jslink((self.play, "value"), (self.slider, "value"))
        self.picker = widgets.Dropdown(
            options=list(self.motions), value=self.name, description="motion"
        )
        self.character_picker = widgets.Dropdown(
            options=[self.PERFORMER] + list(self.characters),
            value=self.PERFORMER,
            description="character",
        )
        self.slider.observe(self._on_frame, names="value")
        self.picker.observe(self._on_pick, names="value")
        self.character_picker.observe(self._on_character, names="value")
        return widgets.VBox(
            [
                widgets.HBox([self.picker, self.character_picker]),
                widgets.HBox([self.play, self.slider]),
                self.image,
            ]
        )

    def _on_frame(self, change) -> None:
        self.frame = int(change["new"])
        self.image.value = png_bytes(self.render())

    def _on_pick(self, change) -> None:
        self.name = change["new"]
        m = self.motions[self.name]
        self.frame = min(self.frame, m.num_frames - 1)
        for ctl in (self.slider, self.play):
            ctl.max = m.num_frames - 1
        self.play.interval = int(1000 / m.fps)
        self.image.value = png_bytes(self.render())

    def _on_character(self, change) -> None:
        self.character = change["new"]
        self.image.value = png_bytes(self.render())

    def _repr_mimebundle_(self, include=None, exclude=None):
        still = png_bytes(self.render())
        text = (
            f"Player: {self.name} on {self.character}, frame {self.frame} "
            f"({len(self.motions)} motions)"
        )
        offline = self.scrubber()
        bundle = (
            {}
            if self.widget is None
            else dict(self.widget._repr_mimebundle_(include=include, exclude=exclude) or {})
        )
        if offline is not None:
            bundle["text/html"] = offline.html()
        bundle["image/png"] = still
        if self.widget is None:
            bundle["text/plain"] = text
            return bundle
        bundle["text/plain"] = text + " — still image shown where widgets cannot run"
        return bundle


def player(motions: Mapping, characters: Mapping | None = None, mode: str = "auto", **kw) -> Player:
    """Create a :class:`Player` (display it as a cell's last expression)."""
    return Player(motions, characters, mode, **kw)
