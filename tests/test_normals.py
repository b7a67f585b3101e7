"""geometry/normals.py: the one vertex-normal function, on NumPy arrays (renderer and FBX writer);
its tensor form is tested with the energy (tests/test_penetration.py)."""

import numpy as np
import pytest

from retarget_lib.geometry.normals import vertex_normals


def test_a_flat_square_points_up_and_an_isolated_vertex_gets_plus_y():
    v = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0], [5, 5, 5]], dtype=float)
    f = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +Y
    n = vertex_normals(v, f)
    assert n[:4] == pytest.approx(np.tile([0.0, 1.0, 0.0], (4, 1)))
    assert n[4] == pytest.approx([0.0, 1.0, 0.0])


def test_a_corner_of_a_cube_points_along_the_diagonal():
    # the three faces meeting at the origin of the unit cube, outward normals -X, -Y, -Z, equal
    # areas
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]])
    assert vertex_normals(v, f)[0] == pytest.approx(-np.ones(3) / np.sqrt(3))
