"""The benchmark code runs and reports ratios (no timing is asserted: speed lives in `retarget
bench`)."""

import numpy as np
import pytest
import torch

from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.core.skeleton import CANONICAL22_PARENTS
from retarget_lib.evaluation.bench import bench_fk, bench_tdcn, numpy_fk_loop, torch_fk_per_joint
from retarget_lib.evaluation.timing import format_table


def test_references_compute_the_same_fk():
    rng = np.random.default_rng(0)
    rot = rng.normal(size=(4, 22, 4))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    off, root = rng.normal(size=(22, 3)), rng.normal(size=(4, 3))
    expected = forward_kinematics(rot, off, CANONICAL22_PARENTS, root).positions
    np.testing.assert_allclose(
        numpy_fk_loop(rot, off, CANONICAL22_PARENTS, root), expected, atol=1e-12
    )
    got = torch_fk_per_joint(
        torch.from_numpy(rot), torch.from_numpy(off), CANONICAL22_PARENTS, torch.from_numpy(root)
    )
    np.testing.assert_allclose(got.numpy(), expected, atol=1e-12)


def test_bench_rows_and_table():
    rows = bench_fk(clips=2, frames=8, quick=True) + bench_tdcn(quick=True, frames=40)
    assert all(r.seconds > 0 and r.reference_seconds > 0 for r in rows)
    table = format_table(rows)
    assert table.count("\n") == len(rows) + 1 and "TDCN inference 40 frames" in table


@pytest.mark.slow
def test_eso_bench_row_reports_per_frame_cost_against_the_network():
    from retarget_lib.evaluation.bench_contact import bench_eso

    row, ten_k, full, setup = bench_eso(quick=True)
    assert "ESO per frame" in row.name and row.seconds > 0 and row.reference_seconds > 0
    assert "1/" in format_table([row]) or row.speedup >= 0.1
    # compiled against uncompiled on the 10k-vertex real body; the full 13,380-vertex body against
    # its decimated copy; its Eint setup (quick: without the all-pairs table it replaced, 30 s)
    assert "compiled" in ten_k.name and "10000 vertices" in ten_k.name and "frames/s" in ten_k.name
    assert ten_k.seconds > 0 and ten_k.reference_seconds > 0
    assert "full real body (13380 vertices" in full.name
    assert full.seconds > 0 and full.reference_seconds > 0
    assert (
        "Eint setup on 13380 vertices" in setup.name
        and setup.seconds > 0
        and setup.reference_seconds is None
    )


@pytest.mark.slow
@pytest.mark.data
def test_contact_training_bench_reports_windows_per_second():
    from retarget_lib.evaluation.bench import bench_contact_training

    compiled, eager = bench_contact_training(quick=True)
    for row in (compiled, eager):
        assert "windows/s" in row.name and row.seconds > 0 and row.reference_seconds > 0
    assert "compiled" in compiled.name and compiled.reference_seconds == eager.seconds
