"""glTF/GLB characters in and out (issue 12): rig maps, the reader, the skinned animated GLB writer.

Every GLB written here is checked by the Khronos glTF validator (0 errors); the tests that need
it skip, naming the reason, only when Node or the npm package is missing.
"""

import json
import struct

import numpy as np
import pygltflib
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from retarget_lib.core.motion import Motion
from retarget_lib.core.rig import Rig
from retarget_lib.core.rotations import matrix_to_quat, quat_from_euler, quat_to_matrix
from retarget_lib.core.skeleton import CANONICAL22, J, JointSetError, Skeleton
from retarget_lib.data.sources.mannequin import load_mannequin
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.errors import GLTFError, RetargetInputError
from retarget_lib.io.gltf import (
    NoSkinError,
    key_rate,
    load_gltf_animation,
    load_gltf_motion,
    load_gltf_rig,
)
from retarget_lib.io.gltf_validator import validate_gltf, validator_missing
from retarget_lib.io.gltf_write import _Builder, save_glb
from retarget_lib.io.rig_maps import RIG_MAPS, map_joints

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

ASSIMP = "/usr/share/assimp/models/glTF2"
#: float32 storage: positions of a ~2 m body to ~1e-6 m; FK through 22 float32 rotations ~1e-5 m
F32_POS, F32_FK = 2e-6, 5e-5


def assert_valid(path):
    """The Khronos validator finds 0 errors in ``path``."""
    reason = validator_missing()
    if reason:
        pytest.skip(reason)
    report = validate_gltf(path)
    errors = [m for m in report["issues"]["messages"] if m["severity"] == 0]
    assert report["issues"]["numErrors"] == 0, errors


def random_motion(skeleton, frames=12, seed=0, deg=25.0, fps=30.0):
    rng = np.random.default_rng(seed)
    rot = quat_from_euler(
        torch.from_numpy(rng.normal(0, deg, (frames, skeleton.num_joints, 3))), "ZXY", degrees=True
    ).numpy()
    root = skeleton.offsets[0] + np.cumsum(rng.normal(0, 0.02, (frames, 3)), axis=0)
    return Motion(skeleton, rot, root, fps, name="random")


@pytest.mark.parametrize("name", ["hana", "kato"])
def test_synthetic_character_round_trip(tmp_path, name):
    character = make_character(name)
    rig = Rig.from_character(character)
    motion = random_motion(rig.skeleton)
    path = tmp_path / f"{name}.glb"
    save_glb(rig, path, motion)
    assert_valid(path)
    back = load_gltf_rig(path)
    assert back.skeleton.joint_names == CANONICAL22 and back.meta["rig"] == "mixamo"
    got = back.character()
    np.testing.assert_allclose(got.rest_vertices, character.rest_vertices, atol=F32_POS)
    np.testing.assert_array_equal(got.faces, character.faces)
    np.testing.assert_allclose(
        got.weights, character.weights, atol=1e-6
    )  # float32 weights renormalised
    np.testing.assert_allclose(got.skeleton.offsets, character.skeleton.offsets, atol=F32_POS)
    read, _ = load_gltf_motion(path)
    assert read.num_frames == motion.num_frames and read.fps == motion.fps
    np.testing.assert_allclose(read.global_positions(), motion.global_positions(), atol=F32_FK)
    # the skinned meshes agree frame by frame, so a viewer shows what the library computed
    np.testing.assert_allclose(back.posed_vertices(read), rig.posed_vertices(motion), atol=1e-4)


def test_mannequin_round_trip(tmp_path):
    character = load_mannequin()
    path = tmp_path / "mannequin-x.glb"
    save_glb(Rig.from_character(character), path)
    assert_valid(path)
    got = load_gltf_rig(path).character()
    np.testing.assert_allclose(got.rest_vertices, character.rest_vertices, atol=F32_POS)
    np.testing.assert_allclose(got.weights, character.weights, atol=1e-6)
    with pytest.raises(GLTFError, match="has 0 animations"):
        load_gltf_motion(path)


def _armature_file(rig, motion, path, scale=0.01, seed=1):
    """Write ``rig`` and ``motion`` the way Blender's exporter lays out a Mixamo character: each
    joint with its own rest orientation, an ``Armature`` parent node that scales centimetres to
    metres and turns the body, inverse bind matrices = inverses of the joints' world transforms."""
    sk, rng = rig.skeleton, np.random.default_rng(seed)
    q = rng.normal(size=(sk.num_joints, 4))
    b_rest = quat_to_matrix(
        torch.from_numpy(q / np.linalg.norm(q, axis=1, keepdims=True))
    ).numpy()  # joint frames
    arm_rot = quat_to_matrix(torch.tensor([np.cos(0.3), 0.0, np.sin(0.3), 0.0])).numpy()
    arm_t = np.array([0.1, 0.0, -0.2])
    to_arm = lambda x: (x - arm_t) @ arm_rot / scale  # world -> armature space  # noqa: E731
    p = to_arm(sk.rest_positions())
    fk = motion.fk()
    s_rot = (
        np.swapaxes(arm_rot, -1, -2)
        @ quat_to_matrix(torch.from_numpy(fk.rotations)).numpy()
        @ arm_rot
        @ b_rest
    )
    xyzw = lambda m: matrix_to_quat(torch.from_numpy(np.ascontiguousarray(m))).numpy()[  # noqa: E731
        ..., [1, 2, 3, 0]
    ]
    build = _Builder()
    g = build.gltf
    local_rot = b_rest.copy()
    local_t = p.copy()
    anim_rot = s_rot.copy()
    for j, par in enumerate(sk.parents[1:], 1):
        local_rot[j] = b_rest[par].T @ b_rest[j]
        local_t[j] = b_rest[par].T @ (p[j] - p[par])
        anim_rot[:, j] = np.swapaxes(s_rot[:, par], -1, -2) @ s_rot[:, j]
    for j, name in enumerate(sk.joint_names):
        g.nodes.append(
            pygltflib.Node(
                name=f"mixamorig:{name}",
                translation=local_t[j].tolist(),
                rotation=xyzw(local_rot[j]).astype(np.float32).tolist(),
                children=sk.children(j) or None,
            )
        )
    world = np.tile(np.eye(4), (sk.num_joints, 1, 1))
    world[:, :3, :3] = scale * arm_rot @ b_rest
    world[:, :3, 3] = sk.rest_positions()
    ibm = np.linalg.inv(world).astype(np.float32)
    attrs = pygltflib.Attributes(
        POSITION=build.add(rig.rest_vertices.astype(np.float32), 5126, 34962, True)
    )
    order = np.argsort(-rig.weights, axis=1)[:, :4]
    attrs.JOINTS_0 = build.add(order.astype(np.uint16), 5123, 34962)
    w = np.take_along_axis(rig.weights, order, 1).astype(np.float32)
    attrs.WEIGHTS_0 = build.add(w / w.sum(1, keepdims=True), 5126, 34962)
    faces = build.add(rig.faces.astype(np.uint32).reshape(-1, 1), 5125, 34963)
    g.meshes.append(
        pygltflib.Mesh(primitives=[pygltflib.Primitive(attributes=attrs, indices=faces)])
    )
    g.skins.append(
        pygltflib.Skin(
            joints=list(range(sk.num_joints)),
            inverseBindMatrices=build.add(ibm.transpose(0, 2, 1).copy(), 5126),
        )
    )
    n = sk.num_joints
    g.nodes.append(
        pygltflib.Node(
            name="Armature",
            children=[0],
            scale=[scale] * 3,
            translation=arm_t.tolist(),
            rotation=xyzw(arm_rot).tolist(),
        )
    )
    g.nodes.append(pygltflib.Node(name="Body", mesh=0, skin=0))
    g.scenes.append(pygltflib.Scene(nodes=[n, n + 1]))
    times = build.add(
        (np.arange(motion.num_frames) / motion.fps).astype(np.float32).reshape(-1, 1),
        5126,
        bounds=True,
    )
    samplers = [
        pygltflib.AnimationSampler(
            input=times, output=build.add(to_arm(motion.root_positions).astype(np.float32), 5126)
        )
    ]
    channels = [
        pygltflib.AnimationChannel(
            sampler=0, target=pygltflib.AnimationChannelTarget(node=0, path="translation")
        )
    ]
    for j in range(n):
        samplers.append(
            pygltflib.AnimationSampler(
                input=times, output=build.add(xyzw(anim_rot[:, j]).astype(np.float32), 5126)
            )
        )
        channels.append(
            pygltflib.AnimationChannel(
                sampler=j + 1, target=pygltflib.AnimationChannelTarget(node=j, path="rotation")
            )
        )
    g.animations.append(pygltflib.Animation(samplers=samplers, channels=channels))
    path.write_bytes(build.to_bytes())


def test_joint_rest_orientations_and_armature_scale(tmp_path):
    """A Blender/Mixamo-style file (rotated joint frames, a 0.01-scaled, turned armature) reads to
    the same world rest pose, mesh and animation as the library's own layout."""
    rig = Rig.from_character(make_character("hana"))
    motion = random_motion(rig.skeleton, frames=10)
    path = tmp_path / "blender_style.glb"
    _armature_file(rig, motion, path)
    assert_valid(path)
    read, back = load_gltf_motion(path)
    assert back.skeleton.joint_names == tuple(f"mixamorig:{n}" for n in CANONICAL22)
    np.testing.assert_allclose(
        back.rest_vertices, rig.rest_vertices, atol=1e-5
    )  # cm-scale float32 matrices
    np.testing.assert_allclose(
        back.skeleton.rest_positions(), rig.skeleton.rest_positions(), atol=1e-5
    )
    np.testing.assert_allclose(read.global_positions(), motion.global_positions(), atol=1e-4)


def _unreal_rig(character):
    """The character renamed to the Unreal mannequin's joints, with a ``root`` joint on the ground
    above ``pelvis``, a ``spine_04`` between ``spine_03`` and ``neck_01``, and two fingers per
    hand."""
    sk = character.skeleton
    names22 = {v: k for k, v in RIG_MAPS["unreal"].items()}
    rest = sk.rest_positions()
    names, parents, pos = ["root"], [-1], [np.array([rest[0, 0], 0.0, rest[0, 2]])]
    index = {}
    for c, name in enumerate(CANONICAL22):
        p = sk.parents[c]
        if name == "Neck":  # spine_04 halfway between spine_03 and neck_01
            (
                names.append("spine_04"),
                parents.append(index[p]),
                pos.append(0.5 * (rest[p] + rest[c])),
            )
            p_idx = len(names) - 1
        else:
            p_idx = index[p] if p >= 0 else 0
        index[c] = len(names)
        names.append(names22[name]), parents.append(p_idx), pos.append(rest[c])
    for side, hand in (("l", "LeftHand"), ("r", "RightHand")):
        h = index[CANONICAL22.index(hand)]
        direction = rest[CANONICAL22.index(hand)] - rest[sk.parents[CANONICAL22.index(hand)]]
        for k in (1, 2):
            names.append(f"index_0{k}_{side}"), parents.append(len(names) - 2 if k == 2 else h)
            pos.append(pos[parents[-1]] + 0.3 * direction)
    pos = np.array(pos)
    offsets = pos.copy()
    offsets[1:] -= pos[parents[1:]]
    full = Skeleton(names, parents, offsets)
    weights = np.zeros((character.num_vertices, len(names)))
    for c in range(22):
        weights[:, index[c]] = character.weights[:, c]
    return Rig(
        "manny",
        full,
        character.rest_vertices,
        character.faces,
        weights,
        {index[c]: c for c in range(22)},
    ), index


def test_extra_joints_are_kept_and_follow_their_parents(tmp_path):
    character = make_character("kato")
    rig, index = _unreal_rig(character)
    path = tmp_path / "manny.glb"
    save_glb(rig, path)
    back = load_gltf_rig(path)
    assert back.meta["rig"] == "unreal" and back.skeleton.joint_names == rig.skeleton.joint_names
    np.testing.assert_allclose(
        back.character().skeleton.offsets, character.skeleton.offsets, atol=F32_POS
    )
    motion22 = random_motion(character.skeleton, frames=8)
    full = back.motion_from_canonical(motion22)
    out = tmp_path / "manny_anim.glb"
    save_glb(back, out, full)
    assert_valid(out)
    read, _ = load_gltf_motion(out)
    pos = read.global_positions()
    np.testing.assert_allclose(
        pos[:, [index[c] for c in range(22)]], motion22.global_positions(), atol=F32_FK
    )
    # the fingers move rigidly with the hand; the root stays under the hips
    hand, finger = (
        index[CANONICAL22.index("LeftHand")],
        rig.skeleton.joint_names.index("index_02_l"),
    )
    bone = np.linalg.norm(pos[:, finger] - pos[:, hand], axis=-1)
    np.testing.assert_allclose(
        bone,
        np.linalg.norm(rig.skeleton.rest_positions()[finger] - rig.skeleton.rest_positions()[hand]),
        atol=F32_FK,
    )
    np.testing.assert_allclose(read.rotations[:, 0], np.tile([1.0, 0, 0, 0], (8, 1)), atol=1e-6)
    folded = back.motion_to_canonical(read)
    np.testing.assert_allclose(folded.global_positions(), motion22.global_positions(), atol=F32_FK)


@pytest.mark.parametrize(
    "rig_name", ["mixamo", "smplx", "smpl", "vrm", "vroid", "unreal", "rigify", "cmu"]
)
def test_every_rig_naming_maps(rig_name):
    names22 = {v: k for k, v in RIG_MAPS[rig_name].items()}
    prefix = "DEF-" if rig_name == "rigify" else ("mixamorig:" if rig_name == "mixamo" else "")
    names = [prefix + names22[n] for n in CANONICAL22]
    joint_map, found = map_joints(names, make_character("hana").skeleton.parents)
    assert joint_map == {c: c for c in range(22)}
    assert found == rig_name or (rig_name == "smpl" and found == "smplx")  # same names up to case


def test_mapping_file_completes_a_custom_rig(tmp_path):
    parents = make_character("hana").skeleton.parents
    names = list(CANONICAL22)
    names[5], names[17] = "Skull", "L_Palm"
    with pytest.raises(
        JointSetError, match=r"cannot map joints \['Head', 'LeftHand'\].*give a joint map"
    ):
        map_joints(names, parents)
    mapping = tmp_path / "map.yaml"
    mapping.write_text("Head: Skull\nLeftHand: L_Palm\n")
    from retarget_lib.io.rig_maps import load_mapping_file

    joint_map, found = map_joints(names, parents, load_mapping_file(mapping))
    assert joint_map == {c: c for c in range(22)} and found == "mixamo+mapping"
    with pytest.raises(JointSetError, match="'Hed', not a canonical joint"):
        map_joints(names, parents, {"Hed": "Skull"})
    with pytest.raises(JointSetError, match="is not below"):
        map_joints(names, parents, {"Head": "L_Palm", "LeftHand": "Skull"})


def test_bad_files_give_one_clear_error(tmp_path):
    with pytest.raises(GLTFError, match="no skin"):
        load_gltf_rig(f"{ASSIMP}/BoxTextured-glTF-Binary/BoxTextured.glb")
    with pytest.raises(JointSetError, match=r"cannot map joints \['Hips'.*'joint1', 'joint2'"):
        load_gltf_rig(f"{ASSIMP}/simple_skin/simple_skin.gltf")
    good = tmp_path / "hana.glb"
    save_glb(Rig.from_character(make_character("hana")), good)
    truncated = tmp_path / "truncated.glb"
    truncated.write_bytes(good.read_bytes()[:5000])
    with pytest.raises(GLTFError, match="truncated"):
        load_gltf_rig(truncated)
    text = tmp_path / "notes.glb"
    text.write_text("hello")
    with pytest.raises(GLTFError, match="not a readable glTF"):
        load_gltf_rig(text)
    # a GLB whose magic is damaged: said in glTF's terms, not as a text decoding error
    damaged = tmp_path / "damaged.glb"
    damaged.write_bytes(b"\x98\x98\x98\x98" + good.read_bytes()[4:])
    with pytest.raises(
        GLTFError,
        match=r"damaged.glb: not a glTF 2.0 file: a binary .glb starts with the bytes 'glTF'",
    ):
        load_gltf_rig(damaged)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_corrupted_glb_loads_or_raises_an_input_error(tmp_path_factory, data):
    """Any byte-level corruption of a valid GLB either loads or raises a RetargetInputError."""
    folder = tmp_path_factory.mktemp("fuzz")
    good = folder / "good.glb"
    save_glb(
        Rig.from_character(make_character("kato")),
        good,
        random_motion(make_character("kato").skeleton, 3),
    )
    raw = bytearray(good.read_bytes())
    for _ in range(data.draw(st.integers(1, 8))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    bad = folder / "bad.glb"
    bad.write_bytes(bytes(raw[: data.draw(st.integers(1, len(raw)))]))
    try:
        load_gltf_motion(bad)
    except RetargetInputError:
        pass


def test_a_motion_without_a_skin_round_trips(tmp_path):
    """``save_glb(..., skin=False)`` writes joints and animation only (a Mixamo "Without Skin"
    clip); :func:`load_gltf_animation` reads it like the skinned file, the rig readers refuse it
    with :class:`NoSkinError`, and a file with neither skin nor animation is refused by name."""
    character = make_character("hana")
    rig = Rig.from_character(character)
    motion = random_motion(rig.skeleton, frames=9)
    bare, skinned = tmp_path / "bare.glb", tmp_path / "skinned.glb"
    save_glb(rig, bare, motion, skin=False)
    save_glb(rig, skinned, motion)
    assert_valid(bare)
    got, joint_map = load_gltf_animation(bare)
    ref, _ = load_gltf_motion(skinned)
    assert (
        joint_map == {c: c for c in range(22)}
        and got.skeleton.joint_names == ref.skeleton.joint_names
    )
    np.testing.assert_allclose(got.skeleton.offsets, ref.skeleton.offsets, atol=0)
    np.testing.assert_allclose(got.global_positions(), ref.global_positions(), atol=0)
    np.testing.assert_allclose(got.global_positions(), motion.global_positions(), atol=F32_FK)
    with pytest.raises(NoSkinError, match="bare.glb: no skin"):
        load_gltf_rig(bare)
    with pytest.raises(RetargetInputError, match="needs a motion"):
        save_glb(rig, tmp_path / "nothing.glb", skin=False)
    gltf = pygltflib.GLTF2().load(str(bare))
    gltf.animations = []
    gltf.save(str(tmp_path / "still.glb"))
    with pytest.raises(GLTFError, match="still.glb: has no skin and 0 animations"):
        load_gltf_animation(tmp_path / "still.glb")


def test_a_blender_style_clip_without_a_skin_at_60_fps(tmp_path):
    """The Blender/Mixamo layout (rotated joint frames under a 0.01-scaled, turned ``Armature``)
    with the mesh node removed, keyed at 60 fps without the library's ``extras``: the joints are
    the animated nodes (the ``Armature`` stays a non-joint ancestor), the rate is the keys'."""
    rig = Rig.from_character(make_character("hana"))
    motion = random_motion(rig.skeleton, frames=10, fps=60.0)
    path = tmp_path / "blender_style.glb"
    _armature_file(rig, motion, path)
    gltf = pygltflib.GLTF2().load(str(path))
    body = next(n for n, node in enumerate(gltf.nodes) if node.mesh is not None)
    gltf.scenes[0].nodes = [n for n in gltf.scenes[0].nodes if n != body]
    gltf.nodes[body].mesh = gltf.nodes[body].skin = None
    gltf.save(str(path))
    read, joint_map = load_gltf_animation(path)
    assert (
        read.fps == 60.0
        and read.num_frames == 10
        and read.skeleton.joint_names[0] == "mixamorig:Hips"
    )
    assert joint_map == {c: c for c in range(22)}
    np.testing.assert_allclose(
        read.global_positions(), motion.global_positions(), atol=1e-4
    )  # as the skinned file


def test_key_rate_of_baked_keys():
    frames = np.arange(50)
    assert (
        key_rate([frames / 30.0]) == 30.0 and key_rate([(frames / 60.0).astype(np.float32)]) == 60.0
    )
    assert key_rate([frames / 29.97]) == pytest.approx(29.97)
    assert key_rate([np.array([0.0, 1.0])]) is None  # two keys: no grid
    assert key_rate([np.array([0.0, 0.1, 0.25, 0.3])]) is None  # keys off any one grid
    assert key_rate([frames * 33.3]) is None  # 0.03 fps: not a frame rate


def _with_prop_armature(src, dst, at, joints=1):
    """``src`` plus a prop rigged to its own armature (as Blender exports a hat): a chain of
    ``joints`` nodes at the scene root starting at ``at``, its own skin, and a triangle skinned to
    the chain's first joint."""
    data = src.read_bytes()
    json_len = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20 : 20 + json_len])
    binary = bytearray(data[20 + json_len + 8 :])

    def add(array, target=None):
        while len(binary) % 4:
            binary.append(0)
        view = {"buffer": 0, "byteOffset": len(binary), "byteLength": array.nbytes}
        binary.extend(array.tobytes())
        gltf["bufferViews"].append(view)
        return len(gltf["bufferViews"]) - 1

    def accessor(array, kind, component, **extra):
        gltf["accessors"].append(
            {
                "bufferView": add(array),
                "componentType": component,
                "count": len(array),
                "type": kind,
                **extra,
            }
        )
        return len(gltf["accessors"]) - 1

    tri = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.05, 0.1]], np.float32)
    position = accessor(tri, "VEC3", 5126, min=tri.min(0).tolist(), max=tri.max(0).tolist())
    joint_ids = accessor(np.zeros((3, 4), np.uint8), "VEC4", 5121)
    weights = accessor(np.tile(np.array([1, 0, 0, 0], np.float32), (3, 1)), "VEC4", 5126)
    indices = accessor(np.array([0, 1, 2], np.uint16), "SCALAR", 5123)
    gltf["meshes"].append(
        {
            "primitives": [
                {
                    "attributes": {
                        "POSITION": position,
                        "JOINTS_0": joint_ids,
                        "WEIGHTS_0": weights,
                    },
                    "indices": indices,
                }
            ]
        }
    )
    first = len(gltf["nodes"])
    chain = [
        {
            "name": f"PropBone{k}",
            "translation": list(map(float, at)) if k == 0 else [0.0, 0.05, 0.0],
        }
        for k in range(joints)
    ]
    for k in range(joints - 1):
        chain[k]["children"] = [first + k + 1]
    gltf["nodes"] += chain + [
        {"name": "Prop", "mesh": len(gltf["meshes"]) - 1, "skin": len(gltf["skins"])}
    ]
    gltf["skins"].append({"joints": list(range(first, first + joints))})
    gltf["scenes"][gltf.get("scene", 0)]["nodes"] += [first, first + joints]
    gltf["buffers"][0]["byteLength"] = len(binary)
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    while len(binary) % 4:
        binary.append(0)
    out = struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(binary))
    out += (
        struct.pack("<II", len(text), 0x4E4F534A)
        + text
        + struct.pack("<II", len(binary), 0x004E4942)
        + binary
    )
    dst.write_bytes(out)


def test_a_prop_on_its_own_armature_hangs_under_the_nearest_joint(tmp_path):
    # a hat rigged to a second armature (two joint trees) is read as part of the character: its
    # bone's parent is the joint nearest to it (the head), nothing moves, and the hat's vertices
    # follow the head; a second tree as large as the skeleton is another character and is refused
    character = make_character("hana")
    src = tmp_path / "hana.glb"
    save_glb(Rig.from_character(character), src)
    head = character.skeleton.rest_positions()[J["Head"]] + [0.0, 0.12, 0.0]
    hat = tmp_path / "hat.glb"
    _with_prop_armature(src, hat, head)
    assert_valid(hat)
    rig = load_gltf_rig(hat)
    names = rig.skeleton.joint_names
    assert names[rig.skeleton.parents[names.index("PropBone0")]] == "Head"
    np.testing.assert_allclose(
        rig.skeleton.rest_positions()[names.index("PropBone0")], head, atol=F32_POS
    )
    body = rig.character()
    assert body.num_vertices == character.num_vertices + 3
    np.testing.assert_allclose(
        body.rest_vertices[-3:] - head, [[0, 0, 0], [0.1, 0, 0], [0, 0.05, 0.1]], atol=F32_POS
    )
    np.testing.assert_allclose(body.weights[-3:, J["Head"]], 1.0)
    twin = tmp_path / "twin.glb"
    _with_prop_armature(src, twin, head, joints=len(CANONICAL22))
    with pytest.raises(
        GLTFError,
        match=r"twin.glb: the skin's joints form 2 trees .* a character needs one skeleton",
    ):
        load_gltf_rig(twin)


def test_a_biped_style_clip_without_a_skin(tmp_path):
    """3ds Max's Biped exported without a skin (assimp's ASE motion capture): every bone carries a
    box mesh and no skin, one inner bone (the neck) has no channel of its own, an end site is
    mirrored (scale -1), and a prop mesh hangs unanimated from a hand. The bones are the joints,
    the mirrored end site is kept, the prop is not a joint, and the motion is the file's."""
    rig = Rig.from_character(make_character("hana"))
    motion = random_motion(rig.skeleton, frames=8)
    skinned, path = tmp_path / "skinned.glb", tmp_path / "biped.glb"
    save_glb(rig, skinned, motion)
    gltf = pygltflib.GLTF2().load(str(skinned))
    body = next(n for n, node in enumerate(gltf.nodes) if node.mesh is not None)
    box = gltf.nodes[body].mesh
    gltf.scenes[0].nodes = [n for n in gltf.scenes[0].nodes if n != body]
    gltf.nodes[body].mesh = gltf.nodes[body].skin = None
    gltf.skins = []
    names = [node.name for node in gltf.nodes]
    for name in CANONICAL22:
        gltf.nodes[names.index(name)].mesh = box  # each bone drawn as a mesh
    neck = names.index("Neck")
    anim = gltf.animations[0]
    anim.channels = [c for c in anim.channels if c.target.node != neck]  # the neck is never keyed
    hand = names.index("LeftHand")
    gltf.nodes.append(
        pygltflib.Node(name="LeftHandNub", translation=[0.0, 0.05, 0.0], scale=[-1.0, -1.0, -1.0])
    )
    gltf.nodes.append(pygltflib.Node(name="Sword", mesh=box, translation=[0.0, 0.1, 0.0]))
    gltf.nodes[hand].children = list(gltf.nodes[hand].children or []) + [
        len(gltf.nodes) - 2,
        len(gltf.nodes) - 1,
    ]
    gltf.save(str(path))
    read, joint_map = load_gltf_animation(path)
    assert set(read.skeleton.joint_names) == set(CANONICAL22) | {"LeftHandNub"}
    assert joint_map == {read.skeleton.joint_names.index(n): c for c, n in enumerate(CANONICAL22)}
    still = motion.copy()
    still.rotations[:, J["Neck"]] = [1.0, 0.0, 0.0, 0.0]  # unkeyed: its rest rotation throughout
    got = read.global_positions()[:, [read.skeleton.joint_names.index(n) for n in CANONICAL22]]
    np.testing.assert_allclose(got, still.global_positions(), atol=F32_FK)
