"""The real-character validation set (``data/real_characters/``, ``real-characters`` in
``data_manifest.yaml``): every file is intact, loads, maps onto the canonical 22 joints, has a
plausible height, and takes a CMU clip through ``retarget retarget --method copy``.

Standing, facing and floor placement are not asserted here (the readers' axis conventions are
being reworked); ``data/real_characters/README.md`` records how each one loads today.
"""

import csv

import numpy as np
import pytest

from retarget_lib.cli import main
from retarget_lib.core.skeleton import CANONICAL22
from retarget_lib.data.manifest import source
from retarget_lib.data.sources.cmu import cmu_clip_path
from retarget_lib.data.sources.real_characters import (
    PROPORTION_COLUMNS,
    REAL_DIR,
    SOURCE_ID,
    joint_map_path,
    load_real_character,
    measure_proportions,
    real_character_names,
    real_character_path,
)
from retarget_lib.data.status import check_sources
from retarget_lib.files import DataError, sha256_file
from retarget_lib.io import load_bvh, save_bvh
from retarget_lib.io.gltf import load_gltf_motion

NAMES = real_character_names()
FIELDS = ("sha256", "convention", "license", "origin", "converted")


def test_the_set_is_as_the_issue_asks():
    files = source(SOURCE_ID)["files"]
    assert len(files) >= 8
    conventions = {e["convention"].split(" ")[0] for e in files.values()}
    assert len(conventions) >= 3, conventions
    for name, entry in files.items():
        assert all(entry.get(k) for k in FIELDS), (name, [k for k in FIELDS if not entry.get(k)])
        assert "mixamo" not in (entry["origin"] + entry["converted"]).lower(), name
    total = sum(p.stat().st_size for p in REAL_DIR.iterdir())
    assert total <= 25 * 2**20


@pytest.mark.parametrize("name", NAMES)
def test_file_matches_its_sha256(name):
    path = real_character_path(name, verify=False)
    assert sha256_file(path) == source(SOURCE_ID)["files"][f"{name}.glb"]["sha256"]
    real_character_path(name)  # the checked path


@pytest.mark.parametrize("name", NAMES)
def test_loads_onto_the_canonical_22_with_a_plausible_height(name):
    rig = load_real_character(name)
    character = rig.character()
    assert tuple(character.skeleton.joint_names) == tuple(CANONICAL22)
    assert sorted(rig.joint_map.values()) == list(range(22))
    assert 0.5 <= character.skeleton.height() <= 3.0
    assert len(character.rest_vertices) <= 25_000
    assert character.weights.shape == (len(character.rest_vertices), 22)
    np.testing.assert_allclose(character.weights.sum(1), 1.0, atol=1e-5)


@pytest.mark.parametrize("name", NAMES)
def test_stands_upright_facing_plus_z_on_the_floor(name):
    # every file is read standing on y = 0 (its rest mesh's lowest point), head up, facing +Z:
    # the MakeHuman and BCN_Epileptic files are centred on their origin as written
    character = load_real_character(name).character()
    rest = character.skeleton.rest_positions()
    index = character.skeleton.index
    assert character.rest_vertices[:, 1].min() == pytest.approx(
        0.0, abs=1e-6
    )  # float64 after one shift
    assert rest[index("Head"), 1] > rest[index("Hips"), 1] > rest[index("LeftFoot"), 1]
    assert rest[index("LeftUpLeg"), 0] > rest[index("RightUpLeg"), 0]  # the character's left at +X
    toes = rest[index("LeftToeBase")] - rest[index("LeftFoot")]
    assert toes[2] > abs(toes[0])  # toes forward: facing +Z


#: canonical joints whose skin may touch the floor in the rest pose (shins hang low on short legs)
_FLOOR_JOINTS = {"LeftLeg", "LeftFoot", "LeftToeBase", "RightLeg", "RightFoot", "RightToeBase"}


@pytest.mark.parametrize("name", NAMES)
def test_only_the_feet_lie_on_the_floor(name):
    # a part bound through the wrong bone (the goblin's face, the cowboy's hat, which assimp binds
    # to the root) is drawn at the feet and sets the floor: every vertex within 2 % of the height
    # of the floor must be skinned mainly to a leg
    character = load_real_character(name).character()
    v = character.rest_vertices
    low = v[:, 1] <= v[:, 1].min() + 0.02 * np.ptp(v[:, 1])
    names = np.array(character.skeleton.joint_names)
    owners = {str(n) for n in names[character.weights[low].argmax(1)]}
    assert owners <= _FLOOR_JOINTS, (
        f"{name}: vertices on the floor skinned to {owners - _FLOOR_JOINTS}"
    )


@pytest.fixture(scope="module")
def short_source(tmp_path_factory):
    path = tmp_path_factory.mktemp("cmu") / "01_01_short.bvh"
    save_bvh(load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 60), path)  # 0.5 s at 120 fps
    return path


@pytest.mark.data  # the CMU clip (assimp-testmodels)
@pytest.mark.parametrize("name", NAMES)
def test_copy_retarget_of_a_cmu_clip_exits_0_and_reads_back(name, short_source, tmp_path):
    # (MPFB2's Rigify metarig hangs the clavicles under the joint mapped to Neck; writing the
    # result once looped without end there)
    out = tmp_path / f"{name}.glb"
    argv = [
        "retarget",
        "--source",
        str(short_source),
        "--target",
        str(real_character_path(name)),
        "--method",
        "copy",
        "--out",
        str(out),
    ]
    joint_map = joint_map_path(name)
    if joint_map is not None:
        argv += ["--joint-map", str(joint_map)]
    assert main(argv) == 0
    # read back with no joint map: a result on a rig its names do not map carries its map
    motion, rig = load_gltf_motion(out)
    target = load_real_character(name)
    assert {rig.skeleton.joint_names[j]: c for j, c in rig.joint_map.items()} == {
        target.skeleton.joint_names[j]: c for j, c in target.joint_map.items()
    }
    back = rig.motion_to_canonical(motion)
    assert back.num_frames == 60  # every source frame, at the source's 120 fps
    soles = back.global_positions()[
        :, [back.skeleton.index("LeftToeBase"), back.skeleton.index("RightToeBase")], 1
    ]
    assert soles.min() > -0.03  # no foot sinks more than 3 cm under the floor (issue 28's bound)


def test_proportions_csv_matches_the_characters():
    with open(REAL_DIR / "proportions.csv", newline="") as f:
        rows = {r["character"]: r for r in csv.DictReader(f)}
    assert set(rows) == set(NAMES)
    assert tuple(next(iter(rows.values()))) == PROPORTION_COLUMNS
    for name in NAMES:
        measured = measure_proportions(load_real_character(name).character())
        for key, value in measured.items():
            if isinstance(value, str):
                assert rows[name][key] == value, (name, key)
            else:
                assert float(rows[name][key]) == pytest.approx(value, abs=1e-3), (name, key)


def test_data_verify_checks_them_and_names_a_damaged_file(tmp_path, monkeypatch):
    status = {s.id: s for s in check_sources()}[SOURCE_ID]
    assert status.state == "ok", status.detail
    import retarget_lib.data.sources.real_characters as rc

    for f in REAL_DIR.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    damaged = tmp_path / f"{NAMES[0]}.glb"
    damaged.write_bytes(damaged.read_bytes()[:-4] + b"\0\0\0\1")
    monkeypatch.setattr(rc, "REAL_DIR", tmp_path)
    with pytest.raises(DataError, match="sha256"):
        rc.real_character_path(NAMES[0])
    status = {s.id: s for s in check_sources()}[SOURCE_ID]
    assert status.state == "BAD" and NAMES[0] in status.detail
