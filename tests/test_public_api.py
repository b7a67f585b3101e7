"""The public contract of docs/architecture.md stays importable from its documented paths, and those
names are the library's own objects (not copies)."""

import pytest

from retarget_lib import kinematics, skeleton
from retarget_lib.core import skeleton as core_skeleton
from retarget_lib.core.kinematics import forward_kinematics as core_fk
from retarget_lib.io import joint_maps, load_bvh, save_bvh
from retarget_lib.io.bvh import load_bvh as bvh_load
from retarget_lib.io.bvh import save_bvh as bvh_save
from retarget_lib.kinematics import forward_kinematics
from retarget_lib.skeleton import to_canonical22

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def test_contract_names_are_the_library_objects():
    assert (load_bvh, save_bvh) == (bvh_load, bvh_save)
    assert to_canonical22 is joint_maps.to_canonical22
    assert forward_kinematics is core_fk


def test_re_export_modules_cover_their_core_modules():
    for name in core_skeleton.__dict__:
        if not name.startswith("_") and name.isupper():
            assert getattr(skeleton, name) is getattr(core_skeleton, name)
    assert set(kinematics.__all__) <= set(dir(kinematics))
    assert set(skeleton.__all__) <= set(dir(skeleton))
