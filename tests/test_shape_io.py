"""Character shape .npz files (retarget_lib.io.shape)."""

import numpy as np
import pytest

from retarget_lib.core.skeleton import CANONICAL22
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.io.shape import SHAPE_KEYS, load_shape_npz, save_shape_npz

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


@pytest.fixture(scope="module")
def character():
    return make_character("hana")


def _assert_same(a, b, atol=1e-6):
    assert b.skeleton.joint_names == CANONICAL22
    np.testing.assert_allclose(b.skeleton.offsets, a.skeleton.offsets, atol=atol)
    np.testing.assert_allclose(b.rest_vertices, a.rest_vertices, atol=atol)
    np.testing.assert_array_equal(b.faces, a.faces)
    np.testing.assert_allclose(b.weights, a.weights, atol=atol)


@pytest.mark.parametrize("unit", ["cm", "m"])
def test_round_trip_with_inferred_unit(tmp_path, character, unit):
    path = tmp_path / "hana.npz"
    save_shape_npz(character, path, unit=unit)
    loaded = load_shape_npz(path)
    assert loaded.name == "hana"
    _assert_same(character, loaded)
    assert loaded.height == pytest.approx(character.height)


def test_file_layout(tmp_path, character):
    path = tmp_path / "hana.npz"
    save_shape_npz(character, path)  # cm, mixamorig: prefix
    data = np.load(path)
    assert set(data.files) == set(SHAPE_KEYS)
    assert data["joint_names"][0] == "mixamorig:Hips"
    root_cm = data["skeleton"][0]
    np.testing.assert_allclose(root_cm, character.skeleton.offsets[0] * 100.0)
    # vertices are relative to the root: the hips sit at the origin
    np.testing.assert_allclose(data["rest_vertices"].min(0)[1], -root_cm[1], atol=1e-9)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


def test_explicit_unit_and_joint_order(tmp_path, character):
    path = tmp_path / "shuffled.npz"
    save_shape_npz(character, path, unit="mm", prefix="")
    data = dict(np.load(path))
    perm = np.random.default_rng(0).permutation(22)
    data["joint_names"] = data["joint_names"][perm]
    data["skeleton"] = data["skeleton"][perm]
    data["skinning_weights"] = data["skinning_weights"][:, perm]
    np.savez(path, **data)
    _assert_same(character, load_shape_npz(path, unit=0.001))
    _assert_same(character, load_shape_npz(path, unit="mm"))


def _write(tmp_path, character, **changes):
    path = tmp_path / "bad.npz"
    save_shape_npz(character, path)
    data = dict(np.load(path))
    data.update(changes)
    for key in [k for k, v in changes.items() if v is None]:
        del data[key]
    np.savez(path, **data)
    return path


def test_missing_keys_are_named(tmp_path, character):
    path = _write(tmp_path, character, skeleton=None, rest_faces=None)
    with pytest.raises(ValueError, match=r"missing keys \['rest_faces', 'skeleton'\]"):
        load_shape_npz(path)


def test_wrong_shape(tmp_path, character):
    path = _write(
        tmp_path, character, skinning_weights=np.full((character.num_vertices, 24), 1 / 24)
    )
    with pytest.raises(ValueError, match=r"skinning_weights must have shape \(\d+, 22\)"):
        load_shape_npz(path)


def test_weight_rows_not_summing_to_one_are_listed(tmp_path, character):
    w = character.weights.copy()
    w[[3, 17]] *= 0.5
    with pytest.raises(ValueError, match=r"rows \[3, 17\] \(2 in all\)"):
        load_shape_npz(_write(tmp_path, character, skinning_weights=w))


def test_float32_rounded_weights_are_renormalised_once_on_stderr(tmp_path, character, capsys):
    # real Mixamo exports: float32 weights whose rows sum to 0.997-1.0
    w = character.weights.copy()
    w[[5, 9]] *= 0.997
    loaded = load_shape_npz(_write(tmp_path, character, skinning_weights=w))
    # renormalised rows sum to 1 up to float64 rounding
    np.testing.assert_allclose(loaded.weights.sum(1), 1.0, atol=1e-12)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "renormalised 2 skinning-weight rows" in err


@pytest.mark.parametrize(
    "bad, message",
    [
        ("negative", r"must be >= 0; rows \[4\] \(1 in all\)"),
        ("zero", r"rows \[4\] \(1 in all\) are all zero"),
    ],
)
def test_negative_or_empty_weight_rows_stay_errors(tmp_path, character, bad, message):
    w = character.weights.copy()
    w[4] = 0.0
    if bad == "negative":
        w[4, 0], w[4, 1] = -0.5, 1.5
    with pytest.raises(ValueError, match=message):
        load_shape_npz(_write(tmp_path, character, skinning_weights=w))


def test_missing_joints_are_named(tmp_path, character):
    names = np.array(["mixamorig:" + n for n in CANONICAL22])
    names[[5, 17]] = ["mixamorig:HeadTop_End", "mixamorig:LeftHandIndex1"]
    with pytest.raises(ValueError, match=r"\['Head', 'LeftHand'\]"):
        load_shape_npz(_write(tmp_path, character, joint_names=names))


def test_nan_values(tmp_path, character):
    v = character.rest_vertices.copy()
    v[42, 1] = np.nan
    with pytest.raises(ValueError, match=r"rest_vertices has NaN or inf in rows \[42\]"):
        load_shape_npz(_write(tmp_path, character, rest_vertices=v))


def test_face_index_out_of_range(tmp_path, character):
    f = character.faces.copy()
    f[0, 0] = character.num_vertices
    with pytest.raises(ValueError, match="rest_faces index vertices outside"):
        load_shape_npz(_write(tmp_path, character, rest_faces=f))


def test_bad_unit(tmp_path, character):
    with pytest.raises(ValueError, match="unit"):
        save_shape_npz(character, tmp_path / "x.npz", unit="inch")
    save_shape_npz(character, tmp_path / "x.npz")
    with pytest.raises(ValueError, match="unit"):
        load_shape_npz(tmp_path / "x.npz", unit=-1.0)
