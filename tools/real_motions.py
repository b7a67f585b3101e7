"""How ``data/real_motions/*.bvh`` were made from their public sources (run by hand, once).

``motion_capture_rom.bvh``: the range-of-motion capture ``MotionCaptureROM.ase`` of assimp's test
models ("Free for any purpose", ``MotionCaptureROM.source.txt``; Debian ``assimp-testmodels``
5.2.5~ds0-1, ``/usr/share/assimp/models/ASE/``): a 3ds Max Biped with German bone names, its bones
drawn as boxes, no skin, keys every 5 frames at 30 fps (6 per second) over 45 s. Converted to glTF
by the Open Asset Import Library (``assimp export X.ase X.glb -fglb2``, assimp-utils 5.2.5), read
by the library's skinless reader with the file's own joints and names, and written as BVH in the
file's unit (3ds Max's default, the inch: the performer is 61 units, 1.55 m, tall; an
assumption, not a measurement) at the keys' rate, nothing resampled. Usage::

    python tools/real_motions.py /usr/share/assimp/models/ASE/MotionCaptureROM.ase
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from retarget_lib.io.bvh import save_bvh
from retarget_lib.io.gltf import load_gltf_animation

OUT_DIR = Path(__file__).resolve().parents[1] / "data" / "real_motions"


def convert_ase(src: Path, out: Path) -> Path:
    """``src`` (ASE) -> ``out`` (BVH, inches) through assimp's glTF export."""
    with tempfile.TemporaryDirectory() as tmp:
        glb = Path(tmp) / "clip.glb"
        subprocess.run(
            ["assimp", "export", str(src), str(glb), "-fglb2"], check=True, capture_output=True
        )
        motion, _ = load_gltf_animation(glb, mapping=out.with_suffix(".joints.yaml"))
    motion.name = out.stem
    save_bvh(
        motion, out, unit="m"
    )  # the numbers as the file has them (read as metres from glTF); the loader says inches
    return out


if __name__ == "__main__":
    print(convert_ase(Path(sys.argv[1]), OUT_DIR / "motion_capture_rom.bvh"))
