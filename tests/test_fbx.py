"""FBX in through the optional extra (Debian libassimp5 + PyPI impasse); skipped, with the reason,
when the extra is not installed."""

import numpy as np
import pytest

from retarget_lib.core.rig import Rig
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.errors import FBXError, GLTFError
from retarget_lib.io.fbx import fbx_missing, load_fbx_motion, load_fbx_rig

FBX = "/usr/share/assimp/models/FBX"
pytestmark = pytest.mark.skipif(fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}")


def test_a_real_rigged_fbx_is_read_and_checked():
    """assimp's test rig (14 bones in two chains, Bone ... and Bone.007 ...) parses; it is not one
    skeleton, and the error names the FBX (not the temporary GLB) and both roots."""
    with pytest.raises(GLTFError, match=r"animation_with_skeleton.fbx: the skin's joints form 2 trees "
                                        r"\(roots \['Bone', 'Bone.007'\]\)") as e:
        load_fbx_rig(f"{FBX}/animation_with_skeleton.fbx")
    assert ".glb" not in str(e.value)


def test_fbx_without_a_skin_and_not_fbx(tmp_path):
    with pytest.raises(GLTFError, match="box.fbx: no skin"):
        load_fbx_rig(f"{FBX}/box.fbx")
    text = tmp_path / "notes.fbx"
    text.write_text("not an fbx file")
    with pytest.raises(FBXError, match="cannot read it as FBX"):
        load_fbx_rig(text)


def test_an_ascii_fbx_character_with_animation_reads_like_its_glb(tmp_path):
    """A character converted to FBX by assimp itself reads back with the same skeleton, mesh and
    key count (assimp's own FBX export is used only here, to make an FBX with a humanoid rig)."""
    import impasse

    from retarget_lib.io.gltf_write import save_glb
    from test_gltf import random_motion

    character = make_character("hana")
    glb, fbx = tmp_path / "hana.glb", tmp_path / "hana.fbx"
    save_glb(Rig.from_character(character), glb, random_motion(character.skeleton, frames=5))
    impasse.export(impasse.load(str(glb)), str(fbx), "fbxa")
    rig = load_fbx_rig(fbx)
    assert rig.meta["rig"] == "mixamo" and rig.meta["source"] == str(fbx)
    got = rig.character()
    np.testing.assert_allclose(got.skeleton.offsets, character.skeleton.offsets, atol=1e-5)
    np.testing.assert_allclose(np.sort(got.rest_vertices, axis=0), np.sort(character.rest_vertices, axis=0), atol=1e-5)
    motion, _ = load_fbx_motion(fbx)
    assert motion.skeleton.num_joints == 22
