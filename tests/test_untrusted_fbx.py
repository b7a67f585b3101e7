"""Malformed and hostile FBX files: one clear error naming the file, never a crash of the Open
Asset Import Library taking the process down, and no temporary folder left (``retarget_lib.io.fbx``:
a structural scan first, then assimp in a contained child process)."""

import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_gltf import random_motion
from test_untrusted_harness import memory_cap, retarget_argv, run_contained

from retarget_lib.core.rig import Rig
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.errors import FBXError, LimitError
from retarget_lib.io import fbx, fbx_write
from retarget_lib.io.fbx import fbx_missing, load_fbx_motion, load_fbx_rig

pytestmark = [
    pytest.mark.tooling,
    pytest.mark.skipif(
        fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}"
    ),
]


def kato_fbx(path: Path, monkeypatch=None, skeleton=None, mesh=None) -> Path:
    """kato as a binary FBX; ``skeleton(scene, ids)`` / ``mesh(scene)`` edit the scene before
    writing."""
    character = make_character("kato")
    if skeleton is not None:
        add_skeleton = fbx_write._add_skeleton
        monkeypatch.setattr(
            fbx_write, "_add_skeleton", lambda scene, rig: skeleton(scene, add_skeleton(scene, rig))
        )
    if mesh is not None:
        add_mesh = fbx_write._add_mesh
        monkeypatch.setattr(
            fbx_write, "_add_mesh", lambda scene, rig, ids: (add_mesh(scene, rig, ids), mesh(scene))
        )
    fbx_write.save_fbx(Rig.from_character(character), path, random_motion(character.skeleton, 6))
    if monkeypatch is not None:
        monkeypatch.undo()
    return path


def hips_under_spine(scene, ids):
    scene.link(ids[0], ids[1])  # Hips is also a child of Spine: Hips -> Spine -> Hips
    return ids


def cluster_index_1e9(scene):
    cluster = next(
        n for n in scene.objects.children if n.name == "Deformer" and n.props[2][1] == b"Cluster"
    )
    for record in cluster.children:
        if record.name in ("Indexes", "Weights"):
            record.props = [
                fbx_write._typed(
                    np.array([10**9], np.int32) if record.name == "Indexes" else np.ones(1)
                )
            ]


def nested_fbx(path: Path, depth: int) -> Path:
    """A binary FBX of ``depth`` records, each the only child of the one before (written
    iteratively: the library's writer recurses)."""
    name, head = b"Nest", 13 + 4
    start = len(fbx_write._MAGIC) + 4
    end_all = start + depth * (head + 13)
    records = [struct.pack("<3IB", end_all - k * 13, 0, 0, len(name)) + name for k in range(depth)]
    body = (
        fbx_write._MAGIC
        + struct.pack("<I", fbx_write.FBX_VERSION)
        + b"".join(records)
        + b"\0" * 13 * depth
    )
    tail = fbx_write._NULL_RECORD + fbx_write._FOOTER_ID
    pad = b"\0" * (-(len(body) + len(tail)) % 16)
    path.write_bytes(
        body
        + tail
        + pad
        + b"\0" * 4
        + struct.pack("<I", fbx_write.FBX_VERSION)
        + b"\0" * 120
        + fbx_write._FOOTER_END
    )
    return path


def temp_folders() -> set[str]:
    return {p.name for p in Path(tempfile.gettempdir()).glob("retarget-fbx-*")}


@pytest.mark.parametrize(
    "case,problem",
    [
        ("nested", "malformed FBX: records nested more than 64 deep (the limit)"),
        (
            "cycle",
            "malformed FBX: the object connections form a cycle ('Hips' -> 'Spine' -> 'Hips')",
        ),
        (
            "index",
            "malformed FBX: cluster 'Hips' binds vertex 1,000,000,000 of a mesh with 3,002 "
            "vertices",
        ),
    ],
)
def test_what_crashed_assimp_is_one_clear_error(tmp_path, monkeypatch, case, problem):
    (tmp_path / "in").mkdir()
    path = tmp_path / "in" / f"{case}.fbx"
    if case == "nested":
        nested_fbx(path, 200_000)
    else:
        edit = dict(skeleton=hips_under_spine) if case == "cycle" else dict(mesh=cluster_index_1e9)
        kato_fbx(path, monkeypatch, **edit)
    before = temp_folders()
    out = tmp_path / "out" / "o.bvh"
    run = run_contained(retarget_argv(path, out), tmp_path, out)
    run.assert_error(path, problem)
    run.assert_contained(path, tmp_path / "in")
    assert temp_folders() == before


@pytest.mark.parametrize("case", ["cycle", "index"])
def test_a_crash_of_assimp_itself_is_one_clear_error(tmp_path, monkeypatch, case):
    """Without the scan, assimp crashes on these files (here: SIGSEGV, SIGABRT) in its child
    process, which is one error."""
    edit = dict(skeleton=hips_under_spine) if case == "cycle" else dict(mesh=cluster_index_1e9)
    path = kato_fbx(tmp_path / f"{case}.fbx", monkeypatch, **edit)
    monkeypatch.setattr(fbx, "_scan_binary_fbx", lambda data, path: fbx._Scan())
    with (
        memory_cap(),
        pytest.raises(FBXError, match=r"the FBX reader \(assimp\) crashed on it \(signal SIG"),
    ):
        load_fbx_rig(path)


def test_an_array_declaring_a_billion_doubles_is_refused_before_inflating(tmp_path, monkeypatch):
    def huge(scene):
        geometry = next(n for n in scene.objects.children if n.name == "Geometry")
        vertices = next(r for r in geometry.children if r.name == "Vertices")
        vertices.props = [fbx_write._typed(np.zeros(3))]

    path = kato_fbx(tmp_path / "huge.fbx", monkeypatch, mesh=huge)
    data = bytearray(path.read_bytes())
    at = (
        data.index(b"Vertices") + len(b"Vertices") + 1
    )  # the array's (length, encoding, byte length)
    data[at : at + 4] = struct.pack("<I", 10**9)
    path.write_bytes(bytes(data))
    with (
        memory_cap(),
        pytest.raises(
            LimitError, match=r"huge.fbx: .*\(1,000,000,000\) would take 7.5 GiB, beyond"
        ),
    ):
        load_fbx_rig(path)


def test_a_valid_fbx_still_reads_through_the_child(tmp_path):
    path = kato_fbx(tmp_path / "kato.fbx")
    motion, rig = load_fbx_motion(path)
    assert (
        rig.skeleton.num_joints == 22 and motion.num_frames == 6 and rig.meta["source"] == str(path)
    )


@pytest.mark.parametrize("cut", [100, 5000, 0.5])
def test_a_truncated_fbx(tmp_path, cut):
    data = kato_fbx(tmp_path / "kato.fbx").read_bytes()
    path = tmp_path / "cut.fbx"
    path.write_bytes(data[: cut if isinstance(cut, int) else int(len(data) * cut)])
    with memory_cap(), pytest.raises(FBXError, match="cut.fbx: "):
        load_fbx_rig(path)


@pytest.fixture(scope="module")
def kato_fbx_bytes(tmp_path_factory) -> bytes:
    return kato_fbx(tmp_path_factory.mktemp("fbx") / "kato.fbx").read_bytes()


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_fuzz_fbx(tmp_path_factory, kato_fbx_bytes, data):
    """Random uint32 values written over record headers and array headers, bytes flipped, the file
    cut: each run ends with exit status 0 or 2 and one line, reads nothing else, leaves no
    folder."""
    raw = bytearray(kato_fbx_bytes)
    for _ in range(data.draw(st.integers(1, 4))):
        at = data.draw(st.integers(27, len(raw) - 4))
        if data.draw(st.booleans()):
            value = data.draw(
                st.sampled_from([0, 1, 2**31 - 1, 2**32 - 1, 10**9, 65]) | st.integers(0, 2**32 - 1)
            )
            raw[at : at + 4] = struct.pack("<I", value)
        else:
            raw[at] ^= data.draw(st.integers(1, 255))
    raw = raw[: data.draw(st.integers(27, len(raw)))] if data.draw(st.booleans()) else raw
    root = tmp_path_factory.mktemp("fuzz")
    (root / "in").mkdir()
    path = root / "in" / "fuzz.fbx"
    path.write_bytes(bytes(raw))
    before = temp_folders()
    out = root / "out" / "o.bvh"
    run_contained(retarget_argv(path, out), root, out).assert_contained(path, root / "in")
    assert temp_folders() == before
