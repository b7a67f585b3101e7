"""``retarget data build``: fetch or build every source into the cache, then verify it."""

from __future__ import annotations

import time

from ..files import DataError
from .manifest import source
from .sources.cmu import CMU_CLIPS, cmu_clip_path
from .sources.mannequin import mannequin_path
from .sources.model_viewer import model_viewer_path
from .status import verify
from .synthetic.dataset import build_synthetic, dataset_path, fingerprint_of


def build_all(force: bool = False) -> None:
    """Fetch the CMU clips and the book's 3-D viewer script, check mannequin-x, build the synthetic
    dataset; verify all.

    Args:
        force: rebuild the synthetic dataset even if it is cached.

    Raises:
        DataError: if a source cannot be fetched or fails its checksum (the message says how to
            get it).
    """
    t0 = time.perf_counter()
    paths = [cmu_clip_path(name, fetch=True) for name in CMU_CLIPS]
    print(f"cmu-assimp: {len(paths)} clips in {paths[0].parent}", flush=True)
    print(f"mannequin-x: {mannequin_path()}", flush=True)
    print(f"model-viewer: {model_viewer_path(fetch=True)}", flush=True)
    existed = dataset_path().exists()
    path = build_synthetic(force=force)
    fp = fingerprint_of(path)
    state = "cached" if existed and not force else f"built in {time.perf_counter() - t0:.0f} s"
    print(f"synthetic: {path} ({state}); fingerprint {fp}", flush=True)
    expected = source("synthetic").get("fingerprint")
    if expected and fp != expected:
        raise DataError(
            f"synthetic dataset fingerprint {fp} differs from the manifest's {expected}. A stale "
            "cache: run `retarget data build --force`. A deliberate change to the generator: "
            "record "
            "the new fingerprint in data_manifest.yaml."
        )
    for s in verify():
        if s.id == "mixamo-local":
            print(f"mixamo-local: {s.detail}")
    print("data: all required sources verified", flush=True)
