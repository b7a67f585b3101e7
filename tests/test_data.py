"""Data sources: manifest, cache helper, the built synthetic dataset, splits, CLI."""

import numpy as np
import pytest

from retarget_lib.cli import main
from retarget_lib.data import manifest, status
from retarget_lib.data.splits import tdcn_split
from retarget_lib.data.synthetic.characters import CHARACTER_NAMES
from retarget_lib.data.synthetic.dataset import (
    dataset_path,
    fingerprint_of,
    load_synthetic,
    read_dataset,
    save_dataset,
)
from retarget_lib.data.synthetic.motions import MOTION_FAMILIES
from retarget_lib.files import DataError, atomic_write, check_sha256, quantised_sha256, sha256_file


@pytest.fixture(scope="module")
def ds():
    return load_synthetic()


@pytest.mark.data
def test_every_source_has_id_license_origin_and_check():
    m = manifest.load_manifest()
    assert set(m["sources"]) == {
        "synthetic",
        "cmu-assimp",
        "mannequin-x",
        "model-viewer",
        "real-characters",
        "real-motions",
        "mixamo-local",
    }
    for sid, src in m["sources"].items():
        assert src["license"] and src["origin"], sid
    statuses = {s.id: s for s in status.verify()}
    assert statuses["synthetic"].verified and statuses["cmu-assimp"].verified
    assert statuses["mannequin-x"].verified and statuses["model-viewer"].verified
    assert statuses["real-characters"].verified and statuses["real-motions"].verified


def test_missing_source_says_how_to_get_it(monkeypatch, tmp_path):
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path))
    with pytest.raises(DataError, match="retarget data build"):
        read_or_fail()
    statuses = {s.id: s for s in status.check_sources()}
    assert (
        not statuses["synthetic"].present and "retarget data build" in statuses["synthetic"].detail
    )
    with pytest.raises(DataError, match="synthetic"):
        status.verify()


def read_or_fail():
    load_synthetic.cache_clear()
    try:
        return load_synthetic()
    finally:
        load_synthetic.cache_clear()


def test_checksum_and_atomic_write(tmp_path):
    p = tmp_path / "a.bin"
    with atomic_write(p) as f:
        f.write(b"hello")
    check_sha256(p, sha256_file(p))
    with pytest.raises(DataError, match="checksum mismatch"):
        check_sha256(p, "0" * 64)
    with pytest.raises(RuntimeError):
        with atomic_write(p) as f:
            f.write(b"partial")
            raise RuntimeError("crash mid-write")
    assert p.read_bytes() == b"hello" and list(tmp_path.iterdir()) == [p]


@pytest.mark.data
def test_dataset_content(ds):
    assert set(ds.characters) == set(CHARACTER_NAMES) and len(CHARACTER_NAMES) >= 16
    heights = [c.height for c in ds.characters.values()]
    assert min(heights) >= 1.2 and max(heights) <= 2.1 and max(heights) - min(heights) > 0.6
    families = {c.family for c in ds.clips}
    assert families == set(MOTION_FAMILIES) and len(families) >= 12
    durations = [c.motion.duration for c in ds.clips]
    assert min(durations) >= 2.0 and max(durations) <= 40.0
    assert all(c.motion.skeleton.is_canonical22() and c.motion.fps == 30 for c in ds.clips)
    # performers rotate over the characters
    assert len({c.performer for c in ds.clips}) == len(CHARACTER_NAMES)


@pytest.mark.data
def test_dataset_feet_planted_and_hands_touch(ds):
    from retarget_lib.core.skeleton import J

    for clip in ds.family("walk")[:3] + ds.family("clap")[:2]:
        pos = clip.motion.global_positions()
        for side, foot in enumerate(("LeftToeBase", "RightToeBase")):
            c = clip.foot_contacts[:, side]
            both = c[1:] & c[:-1]
            slide = np.linalg.norm(np.diff(pos[:, J[foot]], axis=0), axis=-1)[both]
            assert slide.size == 0 or slide.max() < 2e-3, clip.name
    clap = ds.family("clap")[0]
    h = clap.hand_contacts[0]
    gap = np.linalg.norm(
        clap.motion.global_positions()[h.start : h.stop, J["LeftHand"]]
        - clap.motion.global_positions()[h.start : h.stop, J["RightHand"]],
        axis=-1,
    )
    assert gap.max() < 0.12  # wrist joints: palms touching, hand thickness apart


@pytest.mark.data
def test_save_read_round_trip_and_fingerprint(ds, tmp_path):
    small = type(ds)({k: ds.characters[k] for k in list(ds.characters)[:2]}, ds.clips[:3])
    save_dataset(small, tmp_path / "d.npz")
    back = read_dataset(tmp_path / "d.npz")
    np.testing.assert_allclose(
        back.clips[1].motion.rotations, small.clips[1].motion.rotations, atol=1e-6
    )
    assert fingerprint_of(tmp_path / "d.npz") != fingerprint_of(dataset_path())


def test_manifest_records_the_split_the_code_makes():
    s = tdcn_split()
    rec = manifest.source("synthetic")["splits"]["tdcn"]
    assert list(s.train_characters) == rec["train_characters"]
    assert list(s.test_characters) == rec["test_characters"]
    assert list(s.test_families) == rec["test_families"]
    for k, pairs in s.scenarios.items():
        assert [
            f"{p.source} -> {p.target} : {p.motion.family}_{p.motion.seed:03d}" for p in pairs
        ] == rec["scenarios"][k]
    assert not set(s.train_characters) & set(s.test_characters)


@pytest.mark.data
def test_cli_data_list_and_verify(capsys):
    assert main(["data", "list"]) == 0
    out = capsys.readouterr().out
    assert "cmu-assimp" in out and "mannequin-x" in out and "MISSING" not in out
    assert main(["data", "verify"]) == 0
    assert "all required sources verified" in capsys.readouterr().out


def test_checkpoint_lookup_checks_presence_and_checksum(tmp_path, monkeypatch):
    import yaml

    ckpt = tmp_path / "m.pt"
    ckpt.write_bytes(b"weights")
    data = dict(manifest.load_manifest())
    data["checkpoints"] = {
        "toy": {
            "path": str(ckpt),
            "sha256": sha256_file(ckpt),
            "config": "configs/x.yaml",
            "command": "retarget train --config configs/x.yaml",
        }
    }
    path = tmp_path / "manifest.yaml"
    path.write_text(yaml.safe_dump(data))
    manifest.load_manifest.cache_clear()
    monkeypatch.setattr(manifest, "MANIFEST_PATH", path)
    try:
        assert manifest.checkpoint("toy").path == ckpt
        with pytest.raises(DataError, match="known: \\['toy'\\]"):
            manifest.checkpoint("nope")
        ckpt.write_bytes(b"tampered")
        with pytest.raises(DataError, match="retarget train --config configs/x.yaml"):
            manifest.checkpoint("toy")
        assert [s.verified for s in status.check_checkpoints()] == [False]
    finally:
        manifest.load_manifest.cache_clear()


def test_quantised_sha256_ignores_float_noise_but_not_real_changes():
    a = np.linspace(0.0, 1.0, 101).reshape(-1, 1) + 0.123
    digest = quantised_sha256([("x", a)], 1e4)
    assert quantised_sha256([("x", a + 1e-12)], 1e4) == digest  # last-bit noise of another CPU
    assert quantised_sha256([("x", a + 1e-3)], 1e4) != digest  # ten quantisation steps
    assert quantised_sha256([("y", a)], 1e4) != digest  # names count
    assert quantised_sha256([("x", a.astype(np.float32))], 1e4) == digest


def test_the_viewer_script_is_fetched_once_and_checked(monkeypatch, tmp_path):
    """model-viewer: absent from an empty cache (the message says how to get it); a cached file with
    other bytes fails its checksum."""
    from retarget_lib.data.sources.model_viewer import model_viewer_path

    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path))
    with pytest.raises(DataError, match="retarget data build"):
        model_viewer_path()
    (tmp_path / "model-viewer").mkdir(exist_ok=True)
    (tmp_path / "model-viewer" / "model-viewer-umd.min.js").write_text("alert('not the package')")
    with pytest.raises(DataError, match="fails its checksum"):
        model_viewer_path()
