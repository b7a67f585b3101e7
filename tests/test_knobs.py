"""The knobs (:mod:`retarget_lib.viz.knobs`): a live ipywidgets slider in a kernel, the HTML
slider and a still PNG everywhere, and the same output on every run."""

import types

import numpy as np
import pytest

from retarget_lib.viz import knobs
from retarget_lib.viz.knobs import WIDGET_VIEW, knob, live_kernel

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

FALLBACK = {"text/html", "image/png", "text/plain"}
VALUES = [10, 20, 30, 40]


def solid(value) -> np.ndarray:
    """A small picture whose colour is the value: every value gives different PNG bytes."""
    image = np.zeros((12, 16, 3), np.uint8)
    image[...] = (value * 5 % 256, 255 - value, 7)
    return image


@pytest.fixture
def in_a_kernel(monkeypatch):
    """What :func:`live_kernel` sees in ipykernel: a shell with a ``kernel``."""
    shell = types.SimpleNamespace(kernel=object())
    monkeypatch.setattr(knobs, "get_ipython", lambda: shell)


def test_outside_a_kernel_the_bundle_is_the_html_slider_and_the_still():
    assert not live_kernel()  # pytest runs no IPython kernel
    k = knob(solid, "alpha", VALUES, default=30)
    bundle = k._repr_mimebundle_()
    assert set(bundle) == FALLBACK
    assert bundle["image/png"] == k.pngs[2] and bundle["image/png"][:8] == b"\x89PNG\r\n\x1a\n"
    assert bundle["text/html"].count("data:image/png;base64,") == len(VALUES) + 1
    assert 'type="range"' in bundle["text/html"] and "alpha = 30" in bundle["text/html"]
    assert bundle["text/plain"] == "<knob alpha: 4 values>"
    assert k.widget is None  # no widget (no comm) is created


def test_live_kernel_needs_a_kernel_and_ipywidgets(monkeypatch):
    monkeypatch.setattr(knobs, "get_ipython", lambda: None)  # plain Python
    assert not live_kernel()
    monkeypatch.setattr(knobs, "get_ipython", lambda: types.SimpleNamespace())  # terminal IPython
    assert not live_kernel()
    monkeypatch.setattr(knobs, "get_ipython", lambda: types.SimpleNamespace(kernel=object()))
    assert live_kernel()
    monkeypatch.setattr(knobs, "widgets", None)
    assert not live_kernel()


def test_in_a_kernel_the_bundle_adds_the_widget_view_to_the_same_fallbacks(
    monkeypatch, in_a_kernel
):
    k = knob(solid, "alpha", VALUES, default=30)
    bundle = k._repr_mimebundle_()
    assert set(bundle) == FALLBACK | {WIDGET_VIEW}
    assert bundle[WIDGET_VIEW] == {
        "version_major": 2,
        "version_minor": 0,
        "model_id": k.widget.model_id,
    }
    # shown again (a second display of the same knob): the same widget
    assert k._repr_mimebundle_()[WIDGET_VIEW]["model_id"] == k.widget.model_id
    # what a front end without a widget manager shows is what is shown outside a kernel
    monkeypatch.setattr(knobs, "get_ipython", lambda: None)
    offline = knob(solid, "alpha", VALUES, default=30)
    assert offline._repr_mimebundle_() == {m: v for m, v in bundle.items() if m != WIDGET_VIEW}
    assert offline.widget is None
    k.close()


def test_moving_the_slider_swaps_in_the_precomputed_picture(in_a_kernel):
    drawn = []

    def draw(v):
        drawn.append(v)
        return solid(v)

    k = knob(draw, "reach (cm)", VALUES, default=20)
    k._repr_mimebundle_()
    assert len(set(k.pngs)) == len(VALUES)  # a wrong index would show other bytes
    assert k.slider.options == tuple((str(v), i) for i, v in enumerate(VALUES))
    assert k.image.format == "png" and k.image.value == k.pngs[1]
    assert k.label.value == "reach (cm) = 20"
    for i, via in ((3, "value"), (0, "value"), (2, "index"), (1, "index"), (3, "value")):
        setattr(k.slider, via, i)  # a front end moving the slider sends the new index
        assert k.image.value == k.pngs[i]
        assert k.image.value == knobs.png_bytes(solid(VALUES[i]), 40)
        assert k.label.value == f"reach (cm) = {VALUES[i]}"
        assert k.index == i and k.value == VALUES[i]
    assert drawn == VALUES  # drawn once each, up front: moving the slider draws nothing
    # the still in the bundle stays the default's, whatever the live control shows
    assert k._repr_mimebundle_()["image/png"] == k.pngs[1]
    k.close()
    assert k.widget is None and k.slider is None


def test_without_ipywidgets_the_fallback_bundle_is_unchanged(monkeypatch, in_a_kernel):
    monkeypatch.setattr(knobs, "widgets", None)
    k = knob(solid, "alpha", VALUES, default=10)
    bundle = k._repr_mimebundle_()
    assert set(bundle) == FALLBACK and bundle["image/png"] == k.pngs[0]
    assert k.widget is None
    with pytest.raises(RuntimeError, match="ipywidgets"):
        k.make_widget()


def test_the_html_slider_is_the_same_on_every_run():
    first = knob(solid, "alpha", VALUES, default=20).html()
    assert knob(solid, "alpha", VALUES, default=20).html() == first
    other = knob(lambda v: solid(v + 1), "alpha", VALUES, default=20).html()
    assert other[:20] != first[:20]  # other pictures, another element id


def test_a_knob_needs_values_and_a_picture_for_each():
    with pytest.raises(ValueError):
        knob(solid, "alpha", [])
    with pytest.raises(ValueError):
        knobs.Knob("alpha", VALUES, [solid(1)], 0, 40)
