"""The notebooks' teaching helpers: prose from values, offline knobs."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from retarget_lib.notebook.teaching import prose  # noqa: E402
from retarget_lib.viz import knob  # noqa: E402

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def test_prose_renders_values_dedented():
    x = 0.123
    md = prose(f"""
        The error is **{x:.2f} m**.
        """)
    assert md.data == "The error is **0.12 m**."


def test_knob_is_offline_html_with_a_png_fallback():
    def draw(a):
        fig, ax = plt.subplots(figsize=(2, 1.5))
        ax.plot([0, 1], [0, a])
        return fig

    k = knob(draw, "alpha", [1, 2, 3], default=2)
    bundle = k._repr_mimebundle_()
    assert bundle["image/png"][:8] == b"\x89PNG\r\n\x1a\n"
    html = bundle["text/html"]
    assert html.count("data:image/png;base64,") == 3 + 1  # the three pictures + the one shown first
    assert "http" not in html  # nothing loads from the network
    assert 'value="1"' in html and "alpha = 2" in html
    assert k.pngs[1] == bundle["image/png"]
    with pytest.raises(ValueError):
        knob(draw, "alpha", [])
