"""BVH reading/writing: semantics, units, round trips (real CMU clips and odd channel orders),
malformed files, and the ``cmu-assimp`` data source."""

import re
import shutil

import numpy as np
import pytest
import torch

from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_axis_angle, quat_to_matrix
from retarget_lib.core.skeleton import Skeleton
from retarget_lib.data.sources import cmu
from retarget_lib.files import DataError, cache_dir, sha256_file
from retarget_lib.io import BVHError, load_bvh, save_bvh
from retarget_lib.io.bvh import UNIT_SCALES

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

# A two-joint file; line numbers are used by the malformed-input tests below.
GOOD = """HIERARCHY
ROOT Hips
{
  OFFSET 1 2 3
  CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
  JOINT Chest
  {
    OFFSET 10 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.1
5 6 7 90 0 90 0 0 0
5 6 8 0 0 0 90 90 0
"""


def write(tmp_path, text, name="x.bvh"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def matrices(q):
    return quat_to_matrix(torch.as_tensor(q)).numpy()


def assert_same_motion(a: Motion, b: Motion, tol=1e-5):
    assert a.skeleton.joint_names == b.skeleton.joint_names
    assert a.skeleton.parents == b.skeleton.parents
    np.testing.assert_allclose(a.skeleton.offsets, b.skeleton.offsets, atol=tol, rtol=0)
    # the writer adds an End Site to leaves that had none (as exporters do); known ones survive
    leaves = {j for j in range(a.skeleton.num_joints) if not a.skeleton.children(j)}
    assert (
        a.skeleton.end_sites.keys()
        <= b.skeleton.end_sites.keys()
        <= a.skeleton.end_sites.keys() | leaves
    )
    for j, e in a.skeleton.end_sites.items():
        np.testing.assert_allclose(e, b.skeleton.end_sites[j], atol=tol, rtol=0)
    np.testing.assert_allclose(a.root_positions, b.root_positions, atol=tol, rtol=0)
    np.testing.assert_allclose(matrices(a.rotations), matrices(b.rotations), atol=tol, rtol=0)
    assert a.fps == pytest.approx(b.fps)


# ------------------------------------------------------------------------------ semantics
def test_reader_semantics_by_hand(tmp_path):
    m = load_bvh(write(tmp_path, GOOD), unit="m")
    assert m.skeleton.joint_names == ("Hips", "Chest") and m.skeleton.parents == (-1, 0)
    assert m.fps == 10.0 and m.num_frames == 2
    # position channels replace the root OFFSET, which stays the rest root position
    np.testing.assert_allclose(m.root_positions, [[5, 6, 7], [5, 6, 8]])
    np.testing.assert_allclose(m.skeleton.offsets[0], [1, 2, 3])
    np.testing.assert_allclose(m.skeleton.end_sites[1], [0, 5, 0])
    pos = m.global_positions()
    # frame 0, root "Xrotation Yrotation Zrotation" = (90, 0, 90): Rx(90) Rz(90) (10,0,0) = (0,0,10)
    np.testing.assert_allclose(pos[0, 1], [5, 6, 7 + 10], atol=1e-12)
    # frame 1, Chest "Zrotation Xrotation Yrotation" = (90, 90, 0): Rz(90) Rx(90) maps +Z to +X
    end = pos[1, 1] + quat_to_matrix(torch.from_numpy(m.fk().rotations[1, 1])).numpy() @ [0, 5, 0]
    chest_z = quat_to_matrix(torch.from_numpy(m.rotations[1, 1])).numpy() @ [0, 0, 1]
    np.testing.assert_allclose(chest_z, [1, 0, 0], atol=1e-12)
    # the end site (0,5,0) in Chest's frame: Rz(90) Rx(90) (0,5,0) = Rz(90) (0,0,5) = (0,0,5)
    np.testing.assert_allclose(end, [5 + 10, 6, 8 + 5], atol=1e-12)
    assert m.meta["channels"][0] == [
        "Xposition",
        "Yposition",
        "Zposition",
        "Xrotation",
        "Yrotation",
        "Zrotation",
    ]
    assert m.meta["unit"] == "m" and m.meta["unit_scale"] == 1.0
    assert m.meta["file_joint_names"] == ["Hips", "Chest"]


def test_whitespace_tabs_crlf_and_blank_lines_are_tolerated(tmp_path):
    lines = ["\t " + line.replace(" ", " \t ") + "  " for line in GOOD.splitlines()]
    lines.insert(19, "")  # a blank line between the two frames
    lines.insert(15, " ")  # and one before MOTION
    messy = "\r\n".join(lines) + "\r\n\r\n"
    a = load_bvh(write(tmp_path, GOOD, "a.bvh"), unit="cm")
    b = load_bvh(write(tmp_path, messy, "b.bvh"), unit="cm")
    assert_same_motion(a, b, tol=0)


def test_prefixed_names_are_stripped_and_written_back(tmp_path):
    text = GOOD.replace("ROOT Hips", "ROOT mixamorig:Hips").replace(
        "JOINT Chest", "JOINT mixamorig:Chest"
    )
    m = load_bvh(write(tmp_path, text), unit="cm")
    assert m.skeleton.joint_names == ("Hips", "Chest")
    assert m.meta["file_joint_names"] == ["mixamorig:Hips", "mixamorig:Chest"]
    save_bvh(m, tmp_path / "out.bvh")
    assert "JOINT mixamorig:Chest" in (tmp_path / "out.bvh").read_text()


def replace_lines(text, changes):
    """``text`` with the 1-based lines in ``changes`` ({number: new line}) replaced."""
    lines = text.splitlines()
    for number, new in changes.items():
        lines[number - 1] = new
    return "\n".join(lines) + "\n"


CHEST_POSITIONS = "    CHANNELS 6 Zrotation Xrotation Yrotation Yposition Xposition Zposition"


def test_non_root_position_channels_fold_or_drop(tmp_path):
    const = replace_lines(
        GOOD, {9: CHEST_POSITIONS, 19: "5 6 7 90 0 90 0 0 0 4 3 2", 20: "5 6 8 0 0 0 90 90 0 4 3 2"}
    )
    m = load_bvh(write(tmp_path, const), unit="m")
    # constant channel values replace the OFFSET (10, 0, 0); Y, X, Z order in the file
    np.testing.assert_allclose(m.skeleton.offsets[1], [3, 4, 2])
    assert (
        m.meta["position_channels_folded"] == ["Chest"]
        and m.meta["position_channels_dropped"] == []
    )
    # the layout survives a write: the constant channels are written again and re-folded
    save_bvh(m, tmp_path / "out.bvh")
    m2 = load_bvh(tmp_path / "out.bvh", unit="m")
    assert m2.meta["channels"] == m.meta["channels"]
    assert_same_motion(m, m2)

    varying = replace_lines(const, {20: "5 6 8 0 0 0 90 90 0 6 3 2"})
    m = load_bvh(write(tmp_path, varying), unit="m")
    np.testing.assert_allclose(m.skeleton.offsets[1], [3, 5, 2])  # the mean over frames
    assert (
        m.meta["position_channels_dropped"] == ["Chest"]
        and m.meta["position_channels_folded"] == []
    )


def test_root_without_position_channels_and_joint_without_channels(tmp_path):
    text = replace_lines(
        GOOD,
        {
            5: "CHANNELS 3 Yrotation Xrotation Zrotation",
            9: "CHANNELS 0",
            19: "10 20 30",
            20: "0 0 45",
        },
    )
    m = load_bvh(write(tmp_path, text), unit="m")
    np.testing.assert_allclose(m.root_positions, [[1, 2, 3], [1, 2, 3]])  # the root OFFSET
    np.testing.assert_allclose(m.rotations[:, 1], [[1, 0, 0, 0]] * 2)
    # give the motion a root trajectory and a Chest rotation: the writer must add channels for them
    rng = np.random.default_rng(0)
    rot = m.rotations.copy()
    rot[:, 1] = quat_from_axis_angle(torch.from_numpy(rng.normal(size=(2, 3)))).numpy()
    moved = m.copy(rotations=rot, root_positions=rng.normal(size=(2, 3)))
    save_bvh(moved, tmp_path / "out.bvh")
    back = load_bvh(tmp_path / "out.bvh", unit="m")
    assert back.meta["channels"] == [
        ["Xposition", "Yposition", "Zposition", "Yrotation", "Xrotation", "Zrotation"],
        ["Zrotation", "Xrotation", "Yrotation"],
    ]
    assert_same_motion(moved, back)


# ---------------------------------------------------------------------------------- units
def stick_figure(height: float) -> str:
    """A 5-joint BVH whose rest pose is ``height`` file units tall (feet to head end site)."""
    h = height
    return f"""HIERARCHY
ROOT Hips
{{
OFFSET 0 {0.5 * h} 0
CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
JOINT Spine
{{
OFFSET 0 {0.1 * h} 0
CHANNELS 3 Zrotation Xrotation Yrotation
End Site
{{
OFFSET 0 {0.4 * h} 0
}}
}}
JOINT LeftLeg
{{
OFFSET {0.1 * h} {-0.05 * h} 0
CHANNELS 3 Zrotation Xrotation Yrotation
JOINT LeftFoot
{{
OFFSET 0 {-0.45 * h} 0
CHANNELS 3 Zrotation Xrotation Yrotation
}}
}}
}}
MOTION
Frames: 1
Frame Time: 0.033333
0 {0.5 * h} 0 0 0 0 0 0 0 0 0 0 0 0 0
"""


@pytest.mark.parametrize("unit", list(UNIT_SCALES))
def test_unit_inference_on_a_175cm_figure(tmp_path, unit):
    scale = UNIT_SCALES[unit]
    m = load_bvh(write(tmp_path, stick_figure(1.75 / scale)))
    assert m.meta["unit"] == unit and m.meta["unit_scale"] == scale
    rest = m.skeleton.rest_positions()
    top = rest[1, 1] + m.skeleton.end_sites[1][1]
    assert top - rest[3, 1] == pytest.approx(1.75)
    assert m.root_positions[0, 1] == pytest.approx(0.875)


def test_explicit_units(tmp_path):
    path = write(tmp_path, stick_figure(100.0))
    mm = load_bvh(path, unit="mm")
    assert mm.skeleton.offsets[1, 1] == pytest.approx(0.01) and mm.meta["unit"] == "mm"
    custom = load_bvh(path, unit=0.02)
    assert custom.skeleton.offsets[1, 1] == pytest.approx(0.2) and custom.meta["unit"] == "custom"
    assert custom.meta["unit_scale"] == 0.02
    assert load_bvh(path, unit=0.01).meta["unit"] == "cm"
    with pytest.raises(ValueError, match="unknown unit"):
        load_bvh(path, unit="furlong")
    # written in the unit it was read in (0.02 m per unit: the OFFSET text is unchanged) ...
    save_bvh(custom, tmp_path / "same.bvh")
    assert "OFFSET 0.000000 10.000000 0.000000" in (tmp_path / "same.bvh").read_text()
    # ... or in the one asked for
    save_bvh(custom, tmp_path / "m.bvh", unit="m")
    assert "OFFSET 0.000000 0.200000 0.000000" in (tmp_path / "m.bvh").read_text()
    assert_same_motion(custom, load_bvh(tmp_path / "m.bvh", unit="m"))


# ---------------------------------------------------------------------------- round trips
@pytest.fixture(scope="module")
def real_clips():
    return {name: load_bvh(cmu.cmu_clip_path(name)) for name in cmu.CMU_CLIPS}


def header_value(path, key):
    m = re.search(rf"^\s*{key}\s*:\s*(\S+)", path.read_text(), re.MULTILINE)
    return float(m.group(1))


@pytest.mark.parametrize(
    "name,joints,fps,unit",
    [
        ("01_01.bvh", 31, 120.0, "cmu"),
        ("01_03.bvh", 31, 120.0, "cmu"),
        ("Boxing_Toes.bvh", 21, 100.0, "cm"),
    ],
)
@pytest.mark.data
def test_real_clips_load_with_plausible_units(real_clips, name, joints, fps, unit):
    m = real_clips[name]
    path = cmu.cmu_clip_path(name)
    assert m.skeleton.num_joints == joints and m.fps == fps and m.meta["unit"] == unit
    assert m.num_frames == int(header_value(path, "Frames"))
    assert m.meta["source_path"] == str(path)
    # standing height: rest-pose vertical extent including the end sites
    rest = m.skeleton.rest_positions()
    ends = np.array([rest[j] + e for j, e in m.skeleton.end_sites.items()])
    y = np.concatenate([rest[:, 1], ends[:, 1]])
    assert 1.4 < y.max() - y.min() < 2.0
    # the clip's first frame is a standing pose of about that size too
    first = m.global_positions()[0, :, 1]
    assert 1.2 < first.max() - first.min() < 2.0


@pytest.mark.data
@pytest.mark.parametrize("name", ["01_01.bvh", "01_03.bvh", "Boxing_Toes.bvh"])
def test_real_clips_round_trip(real_clips, tmp_path, name):
    m = real_clips[name]
    out = tmp_path / name
    save_bvh(m, out)
    back = load_bvh(out)
    assert_same_motion(m, back)
    assert back.meta["unit"] == m.meta["unit"]
    assert back.meta["channels"] == m.meta["channels"]
    assert back.meta["file_joint_names"] == m.meta["file_joint_names"]

    # written in the file's own unit: the OFFSET lines carry the original numbers
    def offsets(text):
        return np.array(
            [
                [float(v) for v in line.split()[1:]]
                for line in text.splitlines()
                if line.strip().startswith("OFFSET")
            ]
        )

    np.testing.assert_allclose(
        offsets(out.read_text()), offsets(cmu.cmu_clip_path(name).read_text()), atol=1e-6
    )


def odd_order_motion(seed=0, frames=50):
    rng = np.random.default_rng(seed)
    names = ("Root", "A", "B", "C", "D", "E")
    parents = (-1, 0, 1, 1, 0, 4)
    offsets = rng.normal(size=(6, 3)) * 0.3
    rot = quat_from_axis_angle(torch.from_numpy(rng.normal(size=(frames, 6, 3)) * 1.5)).numpy()
    meta = {
        "file_joint_names": list(names),
        "channels": [
            ["Zposition", "Xposition", "Yposition", "Yrotation", "Xrotation", "Zrotation"],
            ["Xrotation", "Yrotation", "Zrotation"],
            ["Yrotation", "Xrotation", "Zrotation"],
            ["Zrotation", "Yrotation", "Xrotation"],
            ["Xrotation", "Zrotation", "Yrotation"],
            ["Yrotation", "Zrotation", "Xrotation"],
        ],
        "unit_scale": 0.001,
    }
    sk = Skeleton(
        names, parents, offsets, {2: np.array([0.0, 0.1, 0.0]), 5: np.array([0.2, 0, 0.1])}
    )
    return Motion(sk, rot, rng.normal(size=(frames, 3)), fps=60, meta=meta)


def test_odd_channel_orders_round_trip(tmp_path):
    m = odd_order_motion()
    save_bvh(m, tmp_path / "odd.bvh")
    text = (tmp_path / "odd.bvh").read_text()
    assert "CHANNELS 3 Yrotation Zrotation Xrotation" in text
    back = load_bvh(tmp_path / "odd.bvh", unit="mm")
    assert back.meta["channels"] == m.meta["channels"]
    assert_same_motion(m, back)


def test_default_layout_without_meta_is_cm(tmp_path):
    m = odd_order_motion().copy(meta={})
    save_bvh(m, tmp_path / "plain.bvh")
    text = (tmp_path / "plain.bvh").read_text()
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" in text
    assert text.count("CHANNELS 3 Zrotation Xrotation Yrotation") == 5
    back = load_bvh(tmp_path / "plain.bvh", unit="cm")
    assert_same_motion(m, back)
    assert "Frame Time: 0.01666667" in text and back.fps == 60.0


@pytest.mark.data
def test_writer_ignores_a_stale_layout_from_another_skeleton(tmp_path, real_clips):
    # a motion loaded from a 31-joint file keeps that file's meta; a 6-joint motion must not use it
    m = odd_order_motion().copy(meta=dict(real_clips["01_01.bvh"].meta))
    save_bvh(m, tmp_path / "stale.bvh")
    back = load_bvh(tmp_path / "stale.bvh", unit="cmu")
    assert back.skeleton.joint_names == m.skeleton.joint_names
    assert_same_motion(m, back)


# ------------------------------------------------------------------------------ malformed
MALFORMED = {
    "truncated motion block": (GOOD.replace("Frames: 2", "Frames: 3"), 20, "truncated"),
    "wrong value count": (replace_lines(GOOD, {20: "5 6 8 0 0 0 90 90"}), 20, "8 values"),
    "bad number": (replace_lines(GOOD, {19: "5 6 7 90 zero 90 0 0 0"}), 19, "'zero'"),
    "non-finite number": (replace_lines(GOOD, {19: "5 6 7 90 nan 90 0 0 0"}), 19, "non-finite"),
    "multiple roots": (
        GOOD.replace("MOTION", "ROOT Other\n{\n  OFFSET 0 0 0\n}\nMOTION"),
        16,
        "multiple ROOT",
    ),
    "zero frames": (GOOD.replace("Frames: 2", "Frames: 0"), 17, "0 frames"),
    "bad frame count": (GOOD.replace("Frames: 2", "Frames: two"), 17, "frame count"),
    "bad frame time": (GOOD.replace("Frame Time: 0.1", "Frame Time: -0.1"), 18, "positive"),
    "missing brace": (replace_lines(GOOD, {14: ""}), 16, "unbalanced braces"),
    "extra brace": (GOOD.replace("MOTION", "}\nMOTION"), 16, "unmatched '}'"),
    "unexpected end of file": ("\n".join(GOOD.splitlines()[:9]) + "\n", 9, "end of file"),
    "unknown channel": (
        GOOD.replace("Zrotation Xrotation Yrotation", "Zrotation Xrotation Wrotation"),
        9,
        "'Wrotation'",
    ),
    "channel count": (
        GOOD.replace("3 Zrotation Xrotation Yrotation", "3 Zrotation Xrotation"),
        9,
        "says 3 but lists 2",
    ),
    "repeated axis": (
        GOOD.replace("Zrotation Xrotation Yrotation", "Zrotation Xrotation Xrotation"),
        9,
        "each of X, Y, Z once",
    ),
    "bad offset": (GOOD.replace("OFFSET 10 0 0", "OFFSET 10 O 0"), 8, "bad number"),
    "short offset": (GOOD.replace("OFFSET 10 0 0", "OFFSET 10 0"), 8, "needs 3 numbers"),
    "missing MOTION": ("\n".join(GOOD.splitlines()[:15]) + "\n", 15, "missing MOTION"),
    "missing Frames": (GOOD.replace("Frames: 2", "Frame 2"), 17, "Frames:"),
    "duplicate joint": (GOOD.replace("JOINT Chest", "JOINT Hips"), 6, "duplicate joint name"),
    "junk in a joint": (GOOD.replace("OFFSET 10 0 0", "OFFSET 10 0 0\n    SCALE 1"), 9, "'SCALE'"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_files_name_the_line(tmp_path, case):
    text, line, problem = MALFORMED[case]
    path = write(tmp_path, text)
    with pytest.raises(BVHError) as info:
        load_bvh(path, unit="m")
    msg = str(info.value)
    assert re.search(rf"\bline {line}\b", msg), msg
    assert problem in msg, msg
    assert str(path) in msg


def test_line_numbers_survive_crlf(tmp_path):
    text = replace_lines(GOOD, {19: "5 6 7 90 zero 90 0 0 0"}).replace("\n", "\r\n")
    with pytest.raises(BVHError, match=r"line 19\b"):
        load_bvh(write(tmp_path, text))


@pytest.mark.data
def test_extra_frame_lines_are_ignored_and_counted(tmp_path, real_clips):
    m = load_bvh(write(tmp_path, GOOD.replace("Frames: 2", "Frames: 1")), unit="m")
    assert m.num_frames == 1 and m.meta["extra_frame_lines"] == 1
    np.testing.assert_allclose(m.root_positions, [[5, 6, 7]])
    # Boxing_Toes.bvh declares 3069 frames and carries one more line, as assimp reads it
    assert real_clips["Boxing_Toes.bvh"].meta["extra_frame_lines"] == 1
    assert real_clips["01_01.bvh"].meta["extra_frame_lines"] == 0


# ------------------------------------------------------------------------ cmu-assimp source
@pytest.mark.data
def test_cmu_checksums_and_names():
    assert cmu.CMU_CLIPS == tuple(cmu.CMU_SHA256)
    for name in cmu.CMU_CLIPS:
        assert sha256_file(cmu.cmu_clip_path(name)) == cmu.CMU_SHA256[name]
    with pytest.raises(ValueError, match="unknown CMU clip"):
        cmu.cmu_clip_path("02_01.bvh")


@pytest.mark.data
def test_cmu_fallback_unpacks_the_deb_into_the_cache(tmp_path, monkeypatch):
    if shutil.which("dpkg-deb") is None or shutil.which("apt-get") is None:
        pytest.skip("needs Debian's apt-get and dpkg-deb")
    cached = sorted(cache_dir("downloads").glob(f"{cmu.PACKAGE}_*.deb"))
    monkeypatch.setattr(cmu, "SYSTEM_DIR", tmp_path / "not-installed")
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path / "cache"))
    if cached:  # reuse a package downloaded before; otherwise this runs `apt-get download`
        shutil.copy(cached[-1], cache_dir("downloads"))
    paths = [cmu.cmu_clip_path(name) for name in cmu.CMU_CLIPS]
    for name, path in zip(cmu.CMU_CLIPS, paths, strict=False):
        assert path == tmp_path / "cache/assimp-testmodels/usr/share/assimp/models/BVH" / name
        assert sha256_file(path) == cmu.CMU_SHA256[name]
    assert len(list((tmp_path / "cache/downloads").glob("*.deb"))) == 1
    # no temporary folders are left behind, and only the BVH folder was unpacked
    assert not list((tmp_path / "cache").rglob(".apt-*")) + list(
        (tmp_path / "cache").rglob(".unpack-*")
    )
    assert [
        p.name for p in (tmp_path / "cache/assimp-testmodels/usr/share/assimp/models").iterdir()
    ] == ["BVH"]


def test_cmu_without_apt_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setattr(cmu, "SYSTEM_DIR", tmp_path / "not-installed")
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path / "cache"))
    with pytest.raises(DataError, match="sudo apt-get install assimp-testmodels"):
        cmu.cmu_clip_path("01_01.bvh", fetch=False)
    assert not list((tmp_path / "cache").rglob("*.deb"))  # fetch=False downloads nothing
    monkeypatch.setenv("PATH", str(tmp_path))  # no apt-get, no dpkg-deb
    with pytest.raises(DataError, match="sudo apt-get install assimp-testmodels"):
        cmu.cmu_clip_path("01_01.bvh")


@pytest.mark.data
def test_cmu_corrupt_file_fails_the_checksum(tmp_path, monkeypatch):
    fake = tmp_path / "BVH"
    fake.mkdir()
    (fake / "01_01.bvh").write_bytes(cmu.cmu_clip_path("01_01.bvh").read_bytes()[:-10])
    monkeypatch.setattr(cmu, "SYSTEM_DIR", fake)
    with pytest.raises(DataError, match="checksum mismatch"):
        cmu.cmu_clip_path("01_01.bvh")


def test_canonical_order_is_not_depth_first_yet_round_trips(tmp_path):
    """Canonical-22 order (legs before arms, Spine2's children last) differs from BVH's depth-first
    order; columns must follow the hierarchy."""
    from retarget_lib.core.skeleton import CANONICAL22, canonical22_skeleton

    rng = np.random.default_rng(5)
    rot = rng.normal(size=(4, 22, 4))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    m = Motion(
        canonical22_skeleton(rng.normal(size=(22, 3)) * 0.2), rot, rng.normal(size=(4, 3)), 30.0
    )
    save_bvh(m, tmp_path / "c.bvh")
    back = load_bvh(tmp_path / "c.bvh")
    assert set(back.skeleton.joint_names) == set(CANONICAL22)
    assert back.skeleton.joint_names != CANONICAL22  # stored depth-first
    idx = [back.skeleton.joint_names.index(n) for n in CANONICAL22]
    np.testing.assert_allclose(back.global_positions()[:, idx], m.global_positions(), atol=1e-5)
    assert "End Site" in (tmp_path / "c.bvh").read_text()
