"""Pictures: renders are non-blank, change with the pose, stay small; animations and the player."""

import numpy as np
import pytest

from retarget_lib import viz
from retarget_lib.core.skeleton import CANONICAL22_PARENTS, canonical22_skeleton

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


@pytest.fixture(scope="module")
def tpose():
    o = np.zeros((22, 3))
    o[0] = [0, 0.95, 0]
    chain = {
        1: [0, 0.1, 0],
        2: [0, 0.12, 0],
        3: [0, 0.13, 0],
        4: [0, 0.15, 0],
        5: [0, 0.1, 0],
        6: [0.09, -0.05, 0],
        7: [0, -0.43, 0],
        8: [0, -0.42, 0],
        9: [0, -0.05, 0.13],
        14: [0.06, 0.1, 0],
        15: [0.12, 0, 0],
        16: [0.27, 0, 0],
        17: [0.25, 0, 0],
    }
    for j, v in chain.items():
        o[j] = v
    for left, right in ((6, 10), (7, 11), (8, 12), (9, 13), (14, 18), (15, 19), (16, 20), (17, 21)):
        o[right] = o[left] * [-1, 1, 1]
    return canonical22_skeleton(o).rest_positions()


def content_fraction(img, box=None):
    """Share of pixels that are neither white background nor floor grey."""
    sub = img if box is None else img[box]
    return (np.abs(sub.astype(int) - 255).sum(-1) > 60).mean()


def test_skeleton_render_non_blank_centred_and_pose_dependent(tpose):
    img = viz.render_skeleton(tpose, CANONICAL22_PARENTS)
    assert img.shape == (400, 640, 3) and img.dtype == np.uint8
    h, w = img.shape[:2]
    assert content_fraction(img, (slice(h // 4, 3 * h // 4), slice(w // 3, 2 * w // 3))) > 0.02
    raised = tpose.copy()
    raised[[16, 17]] += [0, 0.3, 0]  # lift the left forearm and hand
    assert np.abs(viz.render_skeleton(raised, CANONICAL22_PARENTS).astype(int) - img).sum() > 1000


def test_side_by_side_has_three_characters(tpose):
    img = viz.render_side_by_side([(tpose, CANONICAL22_PARENTS)] * 3, titles=["a", "b", "c"])
    w = img.shape[1]
    thirds = [content_fraction(img[:, k * w // 3 : (k + 1) * w // 3]) for k in range(3)]
    assert min(thirds) > 0.01


def test_png_under_budget_and_show(tmp_path, tpose):
    img = viz.render_side_by_side([(tpose, CANONICAL22_PARENTS)] * 8, ncols=4)
    path = viz.save_png(img, tmp_path / "a.png")
    assert path.stat().st_size <= 150 * 1024
    noise = np.random.default_rng(0).integers(0, 255, (600, 800, 3), dtype=np.uint8)
    assert len(viz.png_bytes(noise, max_kb=150)) <= 150 * 1024  # incompressible input is downscaled
    assert viz.show(img).format == "png"


def test_gif_has_all_frames(tmp_path, tpose):
    import imageio.v3 as iio

    T = 10
    pos = np.repeat(tpose[None], T, 0)
    pos[:, 17, 1] += np.linspace(0, 0.3, T)
    path = viz.animate_motion(
        pos, CANONICAL22_PARENTS, tmp_path / "a.gif", every=1, window_size=(240, 160)
    )
    frames = iio.imread(path, index=None)
    assert frames.shape[0] == T
    assert not np.array_equal(frames[0], frames[-1])


def test_mesh_render_with_scalars_and_pairs():
    import pyvista as pv

    box = pv.Box(bounds=(-0.2, 0.2, 0.0, 1.0, -0.1, 0.1)).triangulate()
    v, f = np.asarray(box.points), np.asarray(box.faces).reshape(-1, 4)[:, 1:]
    img = viz.render_mesh(
        v, f, scalars=v[:, 1], point_pairs=np.array([[0, 1]]), highlight_faces=np.array([0])
    )
    assert content_fraction(img) > 0.02


def test_plots():
    ax = viz.plot_root_trajectories({"a": np.zeros((5, 3)), "b": np.ones((5, 3))})
    assert len([ln for ln in ax.get_lines() if ln.get_label() in ("a", "b")]) == 2
    ax = viz.plot_timeline(
        {"left": np.array([0, 1, 1, 0]), "right": np.array([1, 0, 0, 1])}, fps=30
    )
    assert [t.get_text() for t in ax.get_yticklabels()] == ["left", "right"]


def test_player_static_and_widget_modes(tpose):
    from retarget_lib.core.motion import Motion

    sk = canonical22_skeleton(np.zeros((22, 3)) + 0.1)
    rot = np.zeros((12, 22, 4))
    rot[..., 0] = 1
    motions = {
        "a": Motion(sk, rot, np.zeros((12, 3)), 30.0),
        "b": Motion(sk, rot[:5], np.zeros((5, 3)), 30.0),
    }
    still = viz.player(motions, mode="static")
    bundle = still._repr_mimebundle_()
    assert still.widget is None and "image/png" in bundle
    live = viz.player(motions, mode="widget")
    assert live.slider.max == 11 and list(live.picker.options) == ["a", "b"]
    live.picker.value = "b"
    assert live.slider.max == 4
    bundle = live._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in bundle and "image/png" in bundle
    live.close()
    with pytest.raises(ValueError, match="mode"):
        viz.player(motions, mode="nope")


@pytest.mark.data
def test_player_character_picker_shows_the_motion_on_that_character():
    from retarget_lib.data.synthetic.dataset import load_synthetic

    ds = load_synthetic()
    clip = ds.family("wave")[0]
    other = next(n for n in ds.characters if n != clip.performer)
    p = viz.player({clip.name: clip.motion}, ds.characters, mode="widget", window_size=(160, 120))
    assert p.character_picker.options[0] == "performer" and other in p.character_picker.options
    mine = p.scene(clip.name, 10)
    p.character_picker.value = other
    theirs = p.scene(clip.name, 10)
    assert len(theirs.vertices) == ds.characters[other].num_vertices
    assert mine.vertices.shape != theirs.vertices.shape or not np.allclose(
        mine.vertices, theirs.vertices
    )
    p.close()


def test_titles_stay_inside_the_image_and_apart(tpose):
    from retarget_lib.viz.plotter import SceneRenderer
    from retarget_lib.viz.scene import Scene

    scenes = [
        Scene(positions=tpose + [dx, 0, 0], parents=CANONICAL22_PARENTS) for dx in (-0.5, 0.0, 0.5)
    ]
    r = SceneRenderer((240, 160), "front")
    try:
        r.update(scenes, 1.8)
        r.frame(np.array([-1.4, 0, -0.2]), np.array([1.4, 1.9, 0.2]), 1.8)
        r.set_titles(
            ["source", "retargeted", "ground truth"], [[dx, 1.9, 0] for dx in (-0.5, 0.0, 0.5)]
        )
        boxes = []
        for actor in r._texts:
            bb = [0.0] * 4
            actor.GetBoundingBox(r.pl.renderer, bb)
            x, y = actor.GetPosition()
            boxes.append((x - 0.5 * (bb[1] - bb[0]), x + 0.5 * (bb[1] - bb[0]), y))
        assert len(boxes) == 3
        assert all(0 <= lo and hi <= 240 for lo, hi, _ in boxes)
        for (_, hi_a, ya), (lo_b, _, yb) in zip(boxes, boxes[1:], strict=False):
            assert hi_a <= lo_b or ya != yb  # side by side, or staggered onto another line
    finally:
        r.close()


def test_mp4_keeps_its_size(tmp_path, tpose):
    import imageio.v3 as iio

    pos = np.repeat(tpose[None], 4, 0)
    path = viz.animate_motion(
        pos, CANONICAL22_PARENTS, tmp_path / "a.mp4", every=1, window_size=(240, 150)
    )
    assert iio.imread(path, index=None).shape[1:3] == (150, 240)  # 150 is not a multiple of 8 or 16


def test_animate_meshes_with_different_vertex_counts(tmp_path):
    import imageio.v3 as iio
    import pyvista as pv

    meshes = [pv.Sphere(theta_resolution=r, phi_resolution=r).triangulate() for r in (8, 12)]
    lift = np.linspace(0, 0.5, 4)[:, None, None] * [0, 1, 0]  # the meshes rise: every frame differs
    verts = [np.asarray(m.points)[None] + [0, 1, 0] + lift for m in meshes]
    faces = [np.asarray(m.faces).reshape(-1, 4)[:, 1:] for m in meshes]
    assert verts[0].shape[1] != verts[1].shape[1]
    path = viz.animate_mesh(
        verts, faces, tmp_path / "two.gif", every=1, window_size=(160, 100), titles=["a", "b"]
    )
    assert iio.imread(path, index=None).shape[0] == 4


def _subject_box(mask):
    """Fractions of the image's width and height covered by the ``True`` pixels' bounding box."""
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    return (cols[-1] - cols[0] + 1) / mask.shape[1], (rows[-1] - rows[0] + 1) / mask.shape[0]


def _red(img):
    """Pixels of a red-painted subject (shaded: red clearly above green and blue)."""
    i = img.astype(int)
    return (i[..., 0] - i[..., 1] > 60) & (i[..., 0] - i[..., 2] > 60)


def test_mesh_fills_the_canvas_with_its_title_on_top():
    import pyvista as pv

    box = pv.Box(bounds=(-0.2, 0.2, 0.3, 1.9, -0.1, 0.1)).triangulate()  # a body-sized slab
    v, f = np.asarray(box.points), np.asarray(box.faces).reshape(-1, 4)[:, 1:]
    img = viz.render_mesh(v, f, color="red", view="front", title="a title")
    wide, tall = _subject_box(_red(img))
    assert max(wide, tall) >= 0.6  # the subject fills the canvas in at least one dimension
    rows = np.flatnonzero(_red(img).any(1))
    assert rows[0] > 0.05 * img.shape[0]  # the title band above the subject stays free of it
    dark = (img.astype(int).sum(-1) < 200)[: rows[0]]  # black title text above the subject
    assert dark.any()


def test_floor_is_at_the_lowest_drawn_point(tpose):
    from retarget_lib.viz.plotter import SceneRenderer
    from retarget_lib.viz.scene import Scene

    lifted = tpose + [0.0, 0.37, 0.0]  # a skeleton hanging 37 cm above y = 0
    r = SceneRenderer((240, 160), "front")
    try:
        r.update([Scene(positions=lifted, parents=CANONICAL22_PARENTS)], 1.8)
        r.frame(lifted.min(0), lifted.max(0), 1.8)
        lowest = r.drawn_points()[:, 1].min()  # the toe spheres' bottoms
        assert abs(r.floor_y - lowest) < 1e-9  # no float arithmetic: the same number is copied
        floor = r.pl.actors["floor"].GetMapper().GetInput().GetPoints()
        assert (
            abs(floor.GetBounds()[2] - lowest) < 1e-9 and abs(floor.GetBounds()[3] - lowest) < 1e-9
        )
    finally:
        r.close()


def test_side_by_side_stands_every_character_on_the_floor(tpose):
    from retarget_lib.viz.layout import stand_on_floor
    from retarget_lib.viz.scene import Scene

    high = Scene(positions=tpose + [0, 0.5, 0], parents=CANONICAL22_PARENTS)
    low = Scene(positions=tpose - [0, 0.2, 0], parents=CANONICAL22_PARENTS)
    for s in (high, low):
        # 1e-12: a translation of metre-scale coordinates
        assert abs(stand_on_floor(s).points()[:, 1].min()) < 1e-12
    img = viz.render_side_by_side([high, low], window_size=(320, 200))
    # both characters' feet reach the same image row (within 3 px of anti-aliasing and perspective)
    h, w = img.shape[:2]
    dark = np.abs(img.astype(int) - 255).sum(-1) > 300  # joints and bones, not the pale floor
    feet = [
        np.flatnonzero(dark[:, half].any(1))[-1] for half in (slice(0, w // 2), slice(w // 2, w))
    ]
    assert abs(feet[0] - feet[1]) <= 3


def test_animation_fills_the_canvas(tmp_path, tpose):
    import imageio.v3 as iio

    pos = np.repeat(tpose[None], 6, 0) + np.linspace(0, 0.6, 6)[:, None, None] * [
        0,
        0,
        1,
    ]  # walks 60 cm forward
    path = viz.animate_motion(
        [pos, pos],
        CANONICAL22_PARENTS,
        tmp_path / "a.gif",
        every=1,
        titles=["mannequin-x", "a long title"],
    )
    frames = iio.imread(path, index=None)[..., :3]
    content = np.abs(frames.astype(int) - 255).sum(-1) > 300
    wide, tall = _subject_box(content.any(0))
    assert max(wide, tall) >= 0.6


def test_a_title_wider_than_the_window_shrinks_to_fit(tpose):
    from retarget_lib.viz.plotter import SceneRenderer
    from retarget_lib.viz.scene import Scene

    r = SceneRenderer((160, 160), "front")
    try:
        r.update([Scene(positions=tpose, parents=CANONICAL22_PARENTS)], 1.8)
        r.frame(tpose.min(0), tpose.max(0), 1.8, top_px=r.title_band(1))
        r.set_titles(["a label far too long for a window this narrow"], [[0.0, 1.9, 0.0]])
        bb = [0.0] * 4
        r._texts[0].GetBoundingBox(r.pl.renderer, bb)
        x = r._texts[0].GetPosition()[0]
        half = 0.5 * (bb[1] - bb[0])
        assert 0 <= x - half and x + half <= 160
    finally:
        r.close()


def test_colorbar_and_legend_strips_and_categorical_colors():
    img = np.full((200, 300, 3), 255, np.uint8)
    with_bar = viz.add_colorbar(img, "magma", (0.0, 10.0), "error (cm)", width_px=110)
    assert with_bar.shape == (200, 410, 3) and np.array_equal(with_bar[:, :300], img)
    assert (with_bar[:, 300:].astype(int).sum(-1) < 300).any()  # the dark end of magma is drawn
    with_legend = viz.add_legend(img, ["a", "b"], ["red", "blue"], width_px=120)
    assert with_legend.shape == (200, 420, 3)
    colors = viz.categorical_colors(22)
    assert colors.shape == (22, 3)
    gaps = np.linalg.norm(colors[:, None] - colors[None], axis=-1) + np.eye(22)
    assert gaps.min() > 0.08  # no two categories share (nearly) one colour
    with pytest.raises(ValueError):
        viz.categorical_colors(40)


def test_vertex_colors_are_drawn():
    import pyvista as pv

    box = pv.Box(bounds=(-0.2, 0.2, 0.0, 1.0, -0.1, 0.1)).triangulate()
    v, f = np.asarray(box.points), np.asarray(box.faces).reshape(-1, 4)[:, 1:]
    img = viz.render_mesh(v, f, vertex_colors=np.tile([1.0, 0.0, 0.0], (len(v), 1)), view="front")
    assert _red(img).mean() > 0.05


def test_gif_keeps_its_size_budget(tmp_path, tpose):
    import imageio.v3 as iio

    T = 16
    pos = np.repeat(tpose[None], T, 0) + np.linspace(0, 0.6, T)[:, None, None] * [0, 0, 1]
    pos[:, 17, 1] += np.linspace(0, 0.4, T)
    free = viz.animate_motion(
        pos, CANONICAL22_PARENTS, tmp_path / "free.gif", every=1, window_size=(320, 200)
    )
    budget = 0.6 * free.stat().st_size / 1024  # a budget the full-quality file does not meet
    path = viz.animate_motion(
        pos, CANONICAL22_PARENTS, tmp_path / "b.gif", every=1, window_size=(320, 200), max_kb=budget
    )
    assert path.stat().st_size <= budget * 1024
    assert iio.imread(path, index=None).shape[0] >= 4  # still an animation


def test_updating_a_smooth_mesh_in_place_matches_a_fresh_render():
    import pyvista as pv

    from retarget_lib.viz.plotter import SceneRenderer
    from retarget_lib.viz.scene import Scene

    sphere = pv.Sphere(theta_resolution=24, phi_resolution=24).triangulate()
    v, f = np.asarray(sphere.points) + [0, 1, 0], np.asarray(sphere.faces).reshape(-1, 4)[:, 1:]
    bent = v * [1.6, 0.7, 1.0]  # squashed: new normals everywhere
    box = np.r_[v, bent]
    shots = []
    for steps in ([v, bent], [bent]):
        r = SceneRenderer((160, 160), "front_side")
        try:
            for verts in steps:
                r.update([Scene(vertices=verts, faces=f)], 1.0)
            r.frame(box.min(0), box.max(0), 1.0, points=box, floor=0.0)
            shots.append(r.screenshot().astype(int))
        finally:
            r.close()
    assert np.abs(shots[0] - shots[1]).mean() < 1.0  # same picture: normals follow the new vertices


def test_every_row_of_a_wrapped_lineup_labels_at_one_size(tpose, monkeypatch):
    """A row whose labels crowd shrinks them; a row with one label would not: the figure uses the
    smallest size for every row (results/real_worst.png's lone last label was larger)."""
    from retarget_lib.viz import render
    from retarget_lib.viz.scene import Scene

    used: list[tuple[int, int]] = []

    class Recording(render.SceneRenderer):
        def set_titles(self, titles, anchors, font_cap=None):
            lines = super().set_titles(titles, anchors, font_cap)
            used.append((len(titles), self.title_font))
            return lines

    monkeypatch.setattr(render, "SceneRenderer", Recording)
    scenes = [Scene(positions=tpose, parents=CANONICAL22_PARENTS) for _ in range(4)]
    titles = [f"a rather long label number {k}\nwith a second line" for k in range(4)]
    render.render_side_by_side(scenes, titles=titles, ncols=3, window_size=(420, 200))
    first_pass, final = used[:2], used[2:]
    assert [n for n, _ in final] == [3, 1]
    assert first_pass[0][1] < first_pass[1][1]  # the crowded row shrank, the lone label did not
    assert final[0][1] == final[1][1] == first_pass[0][1]
