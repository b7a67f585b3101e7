"""The ``model-viewer`` source: Google's ``<model-viewer>`` web component (npm
``@google/model-viewer``, Apache-2.0; it bundles three.js, MIT, and lit, BSD-3-Clause), which the
offline HTML book uses to play result GLBs in 3-D.

One file of the package is used: ``package/dist/model-viewer-umd.min.js``, the build that a plain
``<script src=...>`` loads (a module script would be blocked on a page opened from disk). It is
fetched once from the npm registry (the URL in ``data_manifest.yaml``), the tarball and the file
each checked against their sha256, and kept in the cache; the book copies it next to its pages.
"""

from __future__ import annotations

import io
import tarfile
import urllib.error
import urllib.request
from pathlib import Path

from ...files import DataError, atomic_write, cache_dir, check_sha256, sha256_file
from ..manifest import source

__all__ = ["SOURCE_ID", "model_viewer_path"]

SOURCE_ID = "model-viewer"
#: the tarball is about 10 MB; a download larger than this is not the package
MAX_TARBALL_BYTES = 64 * 2**20


def _download(url: str, limit: int) -> bytes:
    try:
        with urllib.request.urlopen(url, timeout=60) as response:  # noqa: S310 (the manifest's https URL)
            data = response.read(limit + 1)
    except (urllib.error.URLError, OSError) as e:
        raise DataError(f"{SOURCE_ID}: cannot download {url}: {e}") from None
    if len(data) > limit:
        raise DataError(f"{SOURCE_ID}: {url} is larger than {limit} bytes: not the package")
    return data


def model_viewer_path(fetch: bool = False) -> Path:
    """The cached ``model-viewer-umd.min.js`` (checked against the manifest's sha256).

    Args:
        fetch: download the package from the npm registry when the file is not cached.

    Raises:
        DataError: the file is missing (and ``fetch`` is False), cannot be downloaded, or fails a
            checksum; the message says how to get it.
    """
    entry = source(SOURCE_ID)
    path = cache_dir("model-viewer") / Path(entry["member"]).name
    if not path.exists():
        if not fetch:
            raise DataError(
                f"{SOURCE_ID}: {path} is missing; run `retarget data build` (downloads "
                f"{entry['url']})"
            )
        tarball = _download(entry["url"], MAX_TARBALL_BYTES)
        tar_path = cache_dir("model-viewer") / Path(entry["url"]).name
        with atomic_write(tar_path) as f:
            f.write(tarball)
        check_sha256(tar_path, entry["sha256"])
        with tarfile.open(fileobj=io.BytesIO(tarball), mode="r:gz") as tar:
            member = tar.extractfile(entry["member"])
            if member is None:
                raise DataError(f"{SOURCE_ID}: {entry['member']} is not a file of {entry['url']}")
            with atomic_write(path) as f:
                f.write(member.read())
        tar_path.unlink()
    if sha256_file(path) != entry["member_sha256"]:
        raise DataError(
            f"{SOURCE_ID}: {path} fails its checksum; delete it and run `retarget data build`"
        )
    return path
