"""Execute notebooks headless into ``build/``: executed ``.ipynb`` plus HTML (used by ``make``).

A notebook is re-run only when it, the library, the configs or the data manifest changed since its
last successful run, so ``make`` is cheap the second time.

Usage::

    python -m retarget_lib.notebook.runner --out build/notebooks notebooks/00_overview.ipynb ...
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..files import REPO_ROOT, atomic_write


def _newest_input(notebook: Path) -> float:
    inputs = [notebook, REPO_ROOT / "data_manifest.yaml"]
    for folder in ("retarget_lib", "configs"):
        inputs += list((REPO_ROOT / folder).rglob("*.py")) + list((REPO_ROOT / folder).rglob("*.yaml"))
    return max(p.stat().st_mtime for p in inputs if p.exists())


def run_notebook(notebook: Path, out_dir: Path, timeout: int = 900, force: bool = False) -> bool:
    """Execute one notebook; write ``out_dir/<name>.ipynb`` and ``out_dir/<name>.html``.

    Args:
        notebook: path of the source notebook.
        out_dir: destination folder.
        timeout: per-cell timeout in seconds.
        force: run even if the outputs are up to date.

    Returns:
        ``True`` if it was executed, ``False`` if the outputs were already up to date.
    """
    # here, not at the top: these three take ~3 s to import, which the up-to-date check and
    # --help should not pay
    import nbformat
    from nbclient import NotebookClient
    from nbconvert import HTMLExporter

    out_nb = out_dir / notebook.name
    out_html = out_nb.with_suffix(".html")
    if not force and out_html.exists() and out_html.stat().st_mtime >= _newest_input(notebook):
        return False
    nb = nbformat.read(notebook, as_version=4)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3",
                            resources={"metadata": {"path": str(notebook.parent)}})
    client.execute()
    with atomic_write(out_nb, "w") as f:
        nbformat.write(nb, f)
    html, _ = HTMLExporter().from_notebook_node(nb)
    with atomic_write(out_html, "w") as f:
        f.write(html)
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "build" / "notebooks")
    parser.add_argument("--force", action="store_true")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for nb in args.notebooks:
        t0 = time.perf_counter()
        ran = run_notebook(nb, args.out, force=args.force)
        status = f"executed in {time.perf_counter() - t0:.0f} s" if ran else "up to date"
        print(f"{nb.name}: {status} -> {args.out / nb.with_suffix('.html').name}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
