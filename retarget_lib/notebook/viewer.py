"""The book's 3-D viewer page: retargeted characters as animated GLBs, side by side, that a reader
turns and zooms in the browser, with no network.

:func:`viewer_models` retargets one real clip (CMU subject 1's forward jumps) onto one character
with several methods through :func:`~retarget_lib.methods.retarget.retarget_file` (the same command
a user runs) and keeps the GLBs; :func:`write_viewer` writes ``viewer.html`` beside the book's
pages. The page plays them with Google's ``<model-viewer>`` component
(:mod:`retarget_lib.data.sources.model_viewer`, copied to ``_static/model-viewer/``). A page opened
from disk may load classic scripts but not fetch files, so each GLB also goes into a small script
(``_static/models/NAME.glb.js``) that hands its bytes to the page as a blob; the ``.glb`` files
themselves sit beside it for download. Nothing on the page comes from another host
(:func:`~retarget_lib.notebook.book.remote_references` is empty).
"""

from __future__ import annotations

import base64
import html
import shutil
import tempfile
from pathlib import Path

from ..data.sources.cmu import cmu_clip_path
from ..data.sources.model_viewer import model_viewer_path
from ..files import atomic_write
from ..io.bvh import load_bvh, save_bvh
from ..methods.retarget import retarget_file

__all__ = ["VIEWER_PAGE", "VIEWER_METHODS", "viewer_models", "write_viewer"]

VIEWER_PAGE = "viewer.html"
#: the methods shown side by side, with what each is
VIEWER_METHODS = {
    "copy": "copied rotations, root scaled by leg length (the baseline)",
    "copy-rest": "rest-pose compensated copy (the synthetic data's ground truth rule)",
    "tdcn": "the default TDCN checkpoint (residual form, notebook 04)",
}
#: the clip and character of the page: 2 s of forward jumps onto a character of the synthetic set
CLIP, FRAMES, CHARACTER = "01_01.bvh", 240, "gus"


def viewer_models(folder: Path) -> dict[str, Path]:
    """Retarget :data:`CLIP` onto :data:`CHARACTER` with every :data:`VIEWER_METHODS` entry.

    Returns:
        ``{method: GLB path in folder}``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / f"jumps_{FRAMES}.bvh"
        save_bvh(
            load_bvh(cmu_clip_path(CLIP)).slice(0, FRAMES).normalize_root(), source
        )  # starts at the origin
        return {
            m: retarget_file(source, CHARACTER, m, folder / f"{CHARACTER}_{m}.glb")
            for m in VIEWER_METHODS
        }


def _page(models: dict[str, Path]) -> str:
    cards = "\n".join(
        f'<figure><model-viewer id="{html.escape(m)}" data-glb="{html.escape(p.stem)}" '
        "camera-controls autoplay "
        'shadow-intensity="1" exposure="1" camera-orbit="90deg 80deg 5.5m" '
        'camera-target="0m 0.9m 0.6m" '
        f'alt="{html.escape(m)} result"></model-viewer>'
        f"<figcaption><b>{html.escape(m)}</b>: {html.escape(VIEWER_METHODS[m])} "
        f'(<a href="_static/models/{html.escape(p.name)}">{html.escape(p.name)}</a>)'
        "</figcaption></figure>"
        for m, p in models.items()
    )
    scripts = "\n".join(
        f'<script src="_static/models/{html.escape(p.name)}.js"></script>' for p in models.values()
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1.0">
<title>Retargeted characters in 3-D</title>
<style>
body {{ font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 80rem;
       margin: 2rem auto; padding: 0 1rem; color: #222; line-height: 1.45; }}
.row {{ display: flex; gap: 1rem; flex-wrap: wrap; }}
figure {{ flex: 1 1 22rem; margin: 0; }}
model-viewer {{ width: 100%; height: 26rem; background: #eef1f4; }}
figcaption {{ font-size: .9em; color: #444; }}
</style>
<script src="_static/model-viewer/model-viewer-umd.min.js"></script>
{scripts}
</head>
<body>
<h1>Retargeted characters in 3-D</h1>
<p>CMU subject 1's forward jumps (<code>{CLIP}</code>, its first {FRAMES} frames) retargeted onto
the synthetic character <code>{CHARACTER}</code> by
<code>retarget retarget --method M --out {CHARACTER}_M.glb</code>, one method per view. Drag to turn
a character, scroll to zoom; the files load from this folder, no network.
<a href="index.html">Back to the learning path.</a></p>
<div class="row">
{cards}
</div>
<script>
for (const viewer of document.querySelectorAll("model-viewer[data-glb]")) {{
  const b64 = (window.RETARGET_GLB || {{}})[viewer.dataset.glb];
  if (!b64) continue;
  const bytes = Uint8Array.from(atob(b64), c => c.charCodeAt(0));
  viewer.addEventListener("load", () => {{  // a tint: the GLBs carry no material colour
    for (const m of viewer.model.materials)
      m.pbrMetallicRoughness.setBaseColorFactor([0.55, 0.68, 0.85, 1]);
  }});
  viewer.src = URL.createObjectURL(new Blob([bytes], {{type: "model/gltf-binary"}}));
}}
</script>
</body></html>
"""


def write_viewer(out: Path, models: dict[str, Path] | None = None) -> Path:
    """Write ``out/viewer.html`` with its scripts and models under ``out/_static``.

    Args:
        out: the book folder.
        models: ``{method: GLB}`` to show (default: :func:`viewer_models`, made into the book).

    Returns:
        the page's path.
    """
    static = out / "_static"
    for sub in ("model-viewer", "models"):
        (static / sub).mkdir(parents=True, exist_ok=True)
    shutil.copy2(model_viewer_path(), static / "model-viewer" / "model-viewer-umd.min.js")
    models = viewer_models(static / "models") if models is None else models
    for path in models.values():
        if path.parent != static / "models":
            shutil.copy2(path, static / "models" / path.name)
        data = base64.b64encode((static / "models" / path.name).read_bytes()).decode("ascii")
        with atomic_write(static / "models" / f"{path.name}.js", "w") as f:
            f.write(
                f'(window.RETARGET_GLB = window.RETARGET_GLB || {{}})["{path.stem}"] = "{data}";\n'
            )
    page = out / VIEWER_PAGE
    with atomic_write(page, "w") as f:
        f.write(_page({m: static / "models" / p.name for m, p in models.items()}))
    return page
