"""The ``cmu-assimp`` source: three real motion-capture clips from Debian's ``assimp-testmodels``.

* ``01_01.bvh``, ``01_03.bvh``: CMU Graphics Lab Motion Capture Database, subject 1 (cgspeed BVH
  conversion: 31 joints, 120 fps, lengths in the ASF unit of 1/0.45 inch). "The data used in this
  project was obtained from mocap.cs.cmu.edu. The database was created with funding from NSF
  EIA-0196217." Free for research and commercial use.
* ``Boxing_Toes.bvh``: 21-joint Biovision/MotionBuilder layout, 100 fps, centimetres.

Where the files come from, in order:

1. ``/usr/share/assimp/models/BVH/`` (:data:`SYSTEM_DIR`) when the package is installed
   (``sudo apt-get install assimp-testmodels``);
2. otherwise ``apt-get download assimp-testmodels`` (no root needed) into
   ``cache_dir("downloads")``, and the BVH folder of the ``.deb`` is unpacked with ``dpkg-deb``
   into ``cache_dir("assimp-testmodels")`` (the same path layout as an installed package).

Every file is checked against :data:`CMU_SHA256` before it is used.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tarfile
import tempfile
from pathlib import Path

from ...core.motion import Motion
from ...files import DataError, cache_dir, check_sha256
from ...io.bvh import load_bvh
from ...io.joint_maps import to_canonical22

__all__ = ["CMU_CLIPS", "CMU_SHA256", "SYSTEM_DIR", "cmu_clip_path", "load_cmu_clip"]

#: The clip file names, in a fixed order.
CMU_CLIPS: tuple[str, ...] = ("01_01.bvh", "01_03.bvh", "Boxing_Toes.bvh")

#: SHA-256 of each clip as shipped by ``assimp-testmodels`` 5.2.5~ds0-1 (Debian bookworm).
CMU_SHA256: dict[str, str] = {
    "01_01.bvh": "1d9ee909452ee62784306545cf1fcd634243db1173e0c90cecbed793e50361a8",
    "01_03.bvh": "72d3f37de5af9adfc228dda72422cadb8cfc58d1cd8336076241ba115715c87c",
    "Boxing_Toes.bvh": "ad81c1e3bb2349cb8ea5ac5d753b8a199fce9182bf9015bcc45c2f0414bc99af",
}

#: Where an installed ``assimp-testmodels`` keeps the clips.
SYSTEM_DIR = Path("/usr/share/assimp/models/BVH")
PACKAGE = "assimp-testmodels"
_MEMBER_DIR = "usr/share/assimp/models/BVH"  # inside the .deb
_INSTALL_HINT = (
    f"install the Debian package with `sudo apt-get install {PACKAGE}` "
    "(after `sudo apt-get update`), then try again"
)


def cmu_clip_path(name: str, fetch: bool = True) -> Path:
    """Path of one clip, fetched (and checksum-verified) on first use.

    Args:
        name: one of :data:`CMU_CLIPS`.
        fetch: download and unpack the package if the clip is in neither place; with ``False`` a
            missing clip raises :class:`DataError` instead.

    Returns:
        Path to the verified ``.bvh`` file.

    Raises:
        ValueError: unknown clip name.
        DataError: the package is not installed and cannot (or may not) be downloaded/unpacked,
            or a file's checksum does not match.
    """
    if name not in CMU_CLIPS:
        raise ValueError(f"unknown CMU clip {name!r}; choose one of {CMU_CLIPS}")
    path = SYSTEM_DIR / name
    if not path.is_file():
        path = cache_dir("assimp-testmodels", _MEMBER_DIR) / name
        if not path.is_file():
            if not fetch:
                raise DataError(
                    f"{name} is in neither {SYSTEM_DIR} nor {path.parent}: "
                    f"run `retarget data build`, or {_INSTALL_HINT}"
                )
            _fetch_package()
    check_sha256(path, CMU_SHA256[name])
    return path


def _run(cmd: list[str], cwd: Path) -> None:
    if shutil.which(cmd[0]) is None:
        raise DataError(
            f"the CMU clips are not installed and `{cmd[0]}` is not available to fetch "
            f"them: {_INSTALL_HINT}"
        )
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise DataError(f"`{' '.join(cmd)}` failed ({proc.stderr.strip()[-500:]}); {_INSTALL_HINT}")


def _fetch_package() -> None:
    """Download ``assimp-testmodels`` (if no ``.deb`` is cached) and unpack its BVH folder.

    Both steps work in temporary folders that are renamed into place, so parallel test workers
    never see half-written files.
    """
    downloads = cache_dir("downloads")
    debs = sorted(downloads.glob(f"{PACKAGE}_*.deb"))
    if not debs:
        tmp = Path(tempfile.mkdtemp(prefix=".apt-", dir=downloads))
        try:
            _run(["apt-get", "download", PACKAGE], cwd=tmp)
            got = sorted(tmp.glob(f"{PACKAGE}_*.deb"))
            if not got:
                raise DataError(f"`apt-get download {PACKAGE}` produced no .deb; {_INSTALL_HINT}")
            os.replace(got[-1], downloads / got[-1].name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        debs = sorted(downloads.glob(f"{PACKAGE}_*.deb"))
    deb = debs[-1]

    root = cache_dir("assimp-testmodels")
    tmp = Path(tempfile.mkdtemp(prefix=".unpack-", dir=root))
    try:
        if shutil.which("dpkg-deb") is None:
            raise DataError(f"cannot unpack {deb}: `dpkg-deb` is not available; {_INSTALL_HINT}")
        # `dpkg-deb --fsys-tarfile` streams the package's file tree; only the BVH folder is kept
        # (8 MB instead of the package's 75 MB).
        proc = subprocess.Popen(
            ["dpkg-deb", "--fsys-tarfile", str(deb)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        with tarfile.open(fileobj=proc.stdout, mode="r|") as tar:
            for member in tar:
                if member.isfile() and member.name.lstrip("./").startswith(_MEMBER_DIR + "/"):
                    tar.extract(member, tmp, filter="data")
        err = proc.stderr.read().decode(errors="replace")
        if proc.wait() != 0:
            raise DataError(
                f"`dpkg-deb --fsys-tarfile {deb}` failed ({err.strip()[-500:]}); "
                f"delete it and try again, or {_INSTALL_HINT}"
            )
        src = tmp / _MEMBER_DIR
        missing = [n for n in CMU_CLIPS if not (src / n).is_file()]
        if missing:
            raise DataError(
                f"{deb} does not contain {missing} under /{_MEMBER_DIR}; {_INSTALL_HINT}"
            )
        dest = root / _MEMBER_DIR
        dest.mkdir(parents=True, exist_ok=True)
        for f in src.iterdir():
            os.replace(f, dest / f.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def load_cmu_clip(
    name: str, fps: float | None = 30, canonical: bool = True, normalize: bool = True
) -> Motion:
    """Load one clip, ready for the notebooks.

    Args:
        name: one of :data:`CMU_CLIPS`.
        fps: resample to this frame rate (``None`` keeps the file's 120 or 100 fps).
        canonical: fold onto the canonical 22 joints
            (:func:`~retarget_lib.io.joint_maps.to_canonical22`).
        normalize: :meth:`~retarget_lib.core.motion.Motion.normalize_root` (frame 0 at ``x = z =
            0``, facing +Z, feet on ``y = 0``).

    Returns:
        The Motion (metres; ``rotations (T, J, 4)``, ``root_positions (T, 3)``), named after the
        file stem, with ``meta["source"] = "cmu-assimp"``.
    """
    path = cmu_clip_path(name)
    motion = load_bvh(path)
    if canonical:
        motion = to_canonical22(motion, what=str(path))
    if fps is not None:
        motion = motion.resample(fps)
    if normalize:
        motion = motion.normalize_root()
    motion.meta["source"] = "cmu-assimp"
    return motion
