"""A Mixamo clip downloaded "Without Skin" as a source (issue 28): it must stand on its floor.

The file is built here with the structure of Mixamo's skinless downloads (binary FBX 7.4 in
centimetres, ``mixamorig:`` joints with a ``PreRotation`` on every joint but the hips, no mesh, no
deformer, no bind pose, one animation stack), optionally under a Blender-style ``Armature`` null
turned -90 degrees about X and scaled 100. assimp turns each pre-rotated joint into a chain of
``$AssimpFbx$`` helper nodes *and* bakes that chain into the joint's keys: applied twice, the legs
folded up (a body 0.8 m tall, its feet at the hips' height) and the retargeted character floated
or sank by a metre.
"""

import numpy as np
import pytest
import torch

from retarget_lib.cli import main
from retarget_lib.core.ground import clip_floor, foot_positions, sole_heights, standing_feet
from retarget_lib.core.rig import Rig
from retarget_lib.core.rotations import matrix_to_quat, quat_to_matrix
from retarget_lib.data.sources.mixamo_fixture import extend_motion_to_mixamo
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.io import fbx_write as fw
from retarget_lib.io import load_bvh, save_glb
from retarget_lib.io.fbx import fbx_missing, load_fbx_animation
from retarget_lib.io.gltf import load_gltf_animation, load_gltf_motion, load_gltf_rig
from retarget_lib.io.joint_maps import fold_to_canonical22, to_canonical22

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

needs_assimp = pytest.mark.skipif(
    fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}"
)
FRAMES = 40


def _euler_xyz_matrix(deg: np.ndarray) -> np.ndarray:
    """FBX ``eEulerXYZ``: ``Rz(z) Ry(y) Rx(x)`` of ``(3,)`` degrees."""
    x, y, z = np.radians(deg)
    rx = np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])
    ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    rz = np.array([[np.cos(z), -np.sin(z), 0], [np.sin(z), np.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _write_skinless_mixamo_fbx(path, motion, armature: bool, seed: int = 0) -> None:
    """``motion`` (metres, +Y up, on Mixamo's joints) as a skinless Mixamo-style FBX (cm)."""
    sk = motion.skeleton
    rots = quat_to_matrix(torch.from_numpy(motion.rotations)).numpy()  # (T, J, 3, 3)
    offsets, root = sk.offsets * 100.0, motion.root_positions * 100.0  # cm
    if armature:  # joints in the armature's axes and units: Z up, file units / 100
        turn = _euler_xyz_matrix(np.array([-90.0, 0.0, 0.0]))
        offsets, root = offsets @ turn / 100.0, root @ turn / 100.0  # turn^T p, row-wise
        rots = turn.T @ rots @ turn
    rng = np.random.default_rng(seed)
    pre = rng.uniform(-40.0, 40.0, (sk.num_joints, 3))
    for j, name in enumerate(sk.joint_names):
        if name.endswith("UpLeg"):
            pre[j] = (0.0, 0.0, 180.0)  # Mixamo's legs point down from a turned frame
    if not armature:
        pre[0] = 0.0  # Mixamo's own hips have none; under the armature they have one here
    scene = fw._Scene()
    world = np.empty((sk.num_joints, 3, 3))  # rest world rotations (Lcl Rotation 0 at rest)
    ids: list[int] = []
    if armature:
        arm_id, arm = scene.new("Model", "Armature", "Model", "Null")
        arm.children.append(
            fw._properties(
                fw._vec3("Lcl Rotation", "Lcl Rotation", (-90.0, 0.0, 0.0)),
                fw._vec3("Lcl Scaling", "Lcl Scaling", (100.0, 100.0, 100.0)),
            )
        )
        scene.link(arm_id, 0)
    lcl_rot = np.empty((motion.num_frames, sk.num_joints, 3, 3))
    for j, name in enumerate(sk.joint_names):
        p = sk.parents[j]
        above = world[p] if p >= 0 else np.eye(3)
        world[j] = above @ _euler_xyz_matrix(pre[j])
        # the file's local rotation turning the library's q_j: W_j^T q_j W_j
        lcl_rot[:, j] = world[j].T @ rots[:, j] @ world[j]
        attr_id, attr = scene.new("NodeAttribute", name, "NodeAttribute", "LimbNode")
        attr.add("TypeFlags", "Skeleton")
        model_id, model = scene.new("Model", name, "Model", "LimbNode")
        model.add("Version", fw._i32(232))
        model.children.append(
            fw._properties(
                ("RotationActive", "bool", "", "", fw._i32(1)),
                ("PreRotation", "Vector3D", "Vector", "", *map(float, pre[j])),
                fw._vec3("Lcl Translation", "Lcl Translation", above.T @ offsets[j]),
                fw._vec3("Lcl Rotation", "Lcl Rotation", (0.0, 0.0, 0.0)),
                fw._vec3("Lcl Scaling", "Lcl Scaling", (1.0, 1.0, 1.0)),
            )
        )
        scene.link(attr_id, model_id)
        scene.link(model_id, ids[p] if p >= 0 else (arm_id if armature else 0))
        ids.append(model_id)
    times = np.round(np.arange(motion.num_frames) * fw.KTIME_PER_SECOND / motion.fps)
    times = times.astype(np.int64)
    stack_id, stack = scene.new("AnimationStack", "mixamo.com", "AnimStack", "")
    stack.children.append(fw._properties(("LocalStop", "KTime", "Time", "", int(times[-1]))))
    layer_id, _ = scene.new("AnimationLayer", "BaseLayer", "AnimLayer", "")
    scene.link(layer_id, stack_id)
    quats = matrix_to_quat(torch.from_numpy(lcl_rot)).numpy()
    euler = fw._continuous_euler_xyz(quats)
    channels = [(j, "R", "Lcl Rotation", euler[:, j]) for j in range(sk.num_joints)]
    channels.insert(0, (0, "T", "Lcl Translation", root))
    for j, short, prop, values in channels:
        node_id, node = scene.new("AnimationCurveNode", short, "AnimCurveNode", "")
        node.children.append(
            fw._properties(
                *[(f"d|{a}", "Number", "", "A", float(values[0, k])) for k, a in enumerate("XYZ")]
            )
        )
        scene.link(node_id, layer_id)
        scene.link(node_id, ids[j], prop)
        for k, a in enumerate("XYZ"):
            curve_id, curve = scene.new("AnimationCurve", "", "AnimCurve", "")
            curve.add("Default", float(values[0, k]))
            curve.add("KeyVer", fw._i32(4008))
            curve.add("KeyTime", times)
            curve.add("KeyValueFloat", values[:, k].astype(np.float32))
            curve.add("KeyAttrFlags", np.array([fw._LINEAR_KEY], dtype=np.int32))
            curve.add("KeyAttrDataFloat", np.zeros(4, dtype=np.float32))
            curve.add("KeyAttrRefCount", np.array([len(times)], dtype=np.int32))
            scene.link(curve_id, node_id, f"d|{a}")
    top = [
        fw._header(),
        fw._Node("FileId", fw._Typed("R", fw._FILE_ID)),
        fw._Node("CreationTime", fw._CREATION_TIME),
        fw._Node("Creator", "retarget-notebooks"),
        fw._global_settings(motion.fps, int(times[-1]), 1.0),  # centimetres, as Mixamo
        fw._documents("mixamo.com"),
        fw._Node("References"),
        fw._definitions(scene.counts),
        scene.objects,
        scene.connections,
        fw._takes(motion.copy(name="mixamo.com"), int(times[-1])),
    ]
    path.write_bytes(fw._file_bytes(top))


@pytest.fixture(scope="module")
def clip():
    """A walk of a synthetic character on Mixamo's joints (feet on y = 0) and its canonical 22."""
    character = make_character("cleo")
    walk = make_motion("walk", character.skeleton, 3, duration=(FRAMES + 1) / 30.0)
    walk = walk.slice(0, FRAMES)
    return extend_motion_to_mixamo(walk), walk


@needs_assimp
@pytest.mark.parametrize("armature", [False, True], ids=["mixamo", "armature"])
def test_a_skinless_mixamo_fbx_stands_as_the_file_says(clip, tmp_path, armature):
    motion, walk = clip
    path = tmp_path / "Walking.fbx"
    _write_skinless_mixamo_fbx(path, motion, armature)
    got, joint_map = load_fbx_animation(path)
    assert got.num_frames == FRAMES and got.fps == 30.0
    names = got.skeleton.joint_names  # in the order of assimp's nodes
    assert sorted(names) == sorted(motion.skeleton.joint_names)
    order = [names.index(n) for n in motion.skeleton.joint_names]
    # the rest pose: the file's own (the character's height, its hips' height)
    rest = got.skeleton.rest_positions()[order]
    expected = motion.skeleton.rest_positions()
    np.testing.assert_allclose(rest - rest[0], expected - expected[0], atol=1e-4)
    # every frame as authored: hips at the file's height in metres, feet on its floor
    pos, want = got.global_positions()[:, order], motion.global_positions()
    np.testing.assert_allclose(pos, want, atol=1e-4)  # float32 cm keys
    np.testing.assert_allclose(pos[:, 0, 1], walk.root_positions[:, 1], atol=1e-4)
    assert np.abs(pos[..., 1].min(axis=1) - want[..., 1].min(axis=1)).max() < 1e-4
    assert np.ptp(pos[0, :, 1]) > 0.8 * np.ptp(expected[:, 1])  # standing, not folded up
    folded = fold_to_canonical22(got, joint_map)
    np.testing.assert_allclose(folded.global_positions(), walk.global_positions(), atol=1e-4)


@needs_assimp
@pytest.mark.parametrize("suffix", [".bvh", ".glb"])
def test_a_skinless_mixamo_fbx_source_retargets_onto_the_floor(clip, tmp_path, suffix):
    """Retargeted with ``copy``: every frame kept, each standing foot on the target's floor."""
    motion, walk = clip
    source = tmp_path / "Walking.fbx"
    _write_skinless_mixamo_fbx(source, motion, armature=False)
    target = tmp_path / "gus.glb"
    save_glb(Rig.from_character(make_character("gus")), target)
    out = tmp_path / f"out{suffix}"
    args = ["retarget", "--source", str(source), "--target", str(target)]
    assert main([*args, "--method", "copy", "--out", str(out)]) == 0
    if suffix == ".glb":
        read, rig = load_gltf_motion(out)
        result = rig.motion_to_canonical(read)
    else:
        result = to_canonical22(load_bvh(out))
    assert result.num_frames == FRAMES
    # the source's sole heights above its floor and where it stands (the authored walk)
    src = walk.global_positions()
    src_soles = sole_heights(src, walk.skeleton)
    floor = clip_floor(src_soles)
    standing = standing_feet(
        foot_positions(src, walk.skeleton), src_soles, floor, walk.skeleton.height(), walk.fps
    )
    assert standing.any(axis=1).mean() > 0.5
    target_rest = load_gltf_rig(target).character().rest_vertices
    soles = sole_heights(result.global_positions(), result.skeleton, target_rest)
    ratio = result.skeleton.height() / walk.skeleton.height()
    error = soles - (src_soles - floor) * ratio
    lowest = np.where(standing, error, np.inf).min(axis=1)[standing.any(axis=1)]
    assert np.abs(lowest).max() <= 0.03, np.abs(lowest).max()
    hips = result.global_positions()[:, 0, 1]
    assert 0.5 * ratio * walk.root_positions[:, 1].min() < hips.min()
    assert hips.max() < 1.5 * ratio * walk.root_positions[:, 1].max()


@needs_assimp
def test_a_skinless_glb_converted_by_assimp_stands_too(clip, tmp_path):
    """The same clip converted to GLB by assimp (``assimp export x.fbx x.glb``) keeps the helper
    nodes and the baked keys: read as a GLB it must stand the same."""
    import impasse

    motion, walk = clip
    fbx, glb = tmp_path / "Walking.fbx", tmp_path / "Walking.glb"
    _write_skinless_mixamo_fbx(fbx, motion, armature=False)
    glb.write_bytes(bytes(impasse.export_blob(impasse.load(str(fbx)), "glb2")[0].data))
    got, joint_map = load_gltf_animation(glb)
    assert got.num_frames == FRAMES
    folded = fold_to_canonical22(got, joint_map)  # centimetres: assimp does not convert
    np.testing.assert_allclose(
        folded.global_positions() / 100.0, walk.global_positions(), atol=1e-4
    )
