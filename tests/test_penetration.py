"""Interpenetration (Villegas et al. 2021, Eqs. 4-5): detection (``collision``), cone field,
geodesic weights, energy and gradients, penetration metrics — on hand-made meshes with hand-computed
answers."""

import math

import numpy as np
import pytest
import torch
import trimesh

from retarget_lib.core.skeleton import J
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.geometry.collision import (
    SPLIT_DEPTH,
    TriangleBVH,
    brute_force_candidate_pairs,
    colliding_triangle_pairs,
    triangles_intersect,
)
from retarget_lib.geometry.cone_field import circumcircle, cone_distance_field
from retarget_lib.geometry.geodesic import (
    GeodesicDistances,
    geodesic_distances,
    geodesic_pair_weights,
)
from retarget_lib.geometry.normals import vertex_normals
from retarget_lib.geometry.penetration import (
    InterpenetrationEnergy,
    interpenetration_energy,
    interpenetration_score,
    plan_energy,
)
from retarget_lib.geometry.penetration_rate import (
    cap_holes,
    limb_vertices_inside,
    penetration_rate,
    ray_winding_numbers,
)

FLAT = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]  # normal +z, circumcentre (.5, .5, 0)
# a vertical triangle in the plane y = 0.25 whose edge x = z-axis-parallel pierces FLAT at (0.25,
# 0.25, 0)
PIERCING = [[0.2, 0.25, -1.0], [0.3, 0.25, -1.0], [0.25, 0.25, 1.0]]


def two_triangles(second):
    return np.array(FLAT + second), np.array([[0, 1, 2], [3, 4, 5]])


def box(size, centre, subdivisions=0):
    mesh = trimesh.creation.box(extents=[size] * 3)
    v, f = mesh.vertices, mesh.faces
    for _ in range(subdivisions):
        v, f = trimesh.remesh.subdivide(v, f)
    return np.asarray(v) + centre, np.asarray(f)


def merged(*meshes):
    vs, fs, n = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs)


# ----------------------------------------------------------------------------- detection
def test_crossing_touching_and_apart_triangles():
    v, f = two_triangles(PIERCING)
    np.testing.assert_array_equal(colliding_triangle_pairs(v, f), [[0, 1]])
    apart, _ = two_triangles((np.array(PIERCING) + [5.0, 0.0, 0.0]).tolist())
    assert colliding_triangle_pairs(apart, f).shape == (0, 2)
    # sharing vertex 0 and crossing FLAT's plane there: geometrically touching, excluded as
    # neighbours
    shared_v = np.array(FLAT + [[0.3, 0.3, -0.5], [0.3, 0.3, 0.5]])
    shared_f = np.array([[0, 1, 2], [0, 3, 4]])
    assert triangles_intersect(shared_v[shared_f[:1]], shared_v[shared_f[1:]])[0]
    assert colliding_triangle_pairs(shared_v, shared_f).shape == (0, 2)


def test_triangle_test_is_symmetric_and_sees_edge_through_interior():
    flat, pierce = np.array([FLAT]), np.array([PIERCING])
    assert triangles_intersect(flat, pierce)[0] and triangles_intersect(pierce, flat)[0]
    # same plane as PIERCING but shifted up: its lowest point z = 0.1 stays above FLAT
    above = pierce + [0.0, 0.0, 1.1]
    assert not triangles_intersect(flat, above)[0]
    # crosses FLAT's plane at x + y = 1.2 > 1, outside FLAT
    beside = np.array([[[0.6, 0.6, -1.0], [0.7, 0.6, -1.0], [0.65, 0.6, 1.0]]])
    assert not triangles_intersect(flat, beside)[0]


def test_bvh_finds_the_same_pairs_as_all_pairs():
    rng = np.random.default_rng(0)
    centres = rng.uniform(0, 1, (300, 1, 3))
    v = (centres + rng.normal(0, 0.06, (300, 3, 3))).reshape(-1, 3)
    f = np.arange(900).reshape(300, 3)
    bvh = TriangleBVH(f, v)
    cand = {tuple(p) for p in bvh.candidate_pairs(v)}
    brute = {tuple(p) for p in brute_force_candidate_pairs(v, f)}
    assert brute <= cand and len(brute) > 50
    hit = {
        tuple(p)
        for p in brute_force_candidate_pairs(v, f)
        if triangles_intersect(v[f[[p[0]]]], v[f[[p[1]]]])[0]
    }
    assert {tuple(p) for p in colliding_triangle_pairs(v, f, bvh)} == hit and len(hit) > 5


def test_detection_rejects_bad_input():
    v, f = two_triangles(PIERCING)
    with pytest.raises(ValueError, match="faces index"):
        colliding_triangle_pairs(v, f + 1)
    with pytest.raises(ValueError, match="vertices must be"):
        colliding_triangle_pairs(v[:, :2], f)


# ----------------------------------------------------------------------------- cone field
def test_cone_field_known_values():
    tri = torch.tensor(FLAT, dtype=torch.float64)
    sigma, height = 0.1, 0.2

    def psi(p, **kw):
        return float(
            cone_distance_field(torch.tensor(p, dtype=torch.float64), tri, sigma, height, **kw)
        )

    # on the axis: deep (linear zone) U = d - sigma/2, shallow (quadratic zone) U = d^2 / (2 sigma)
    assert psi([0.5, 0.5, -0.3]) == pytest.approx(0.3 - 0.05)
    assert psi([0.5, 0.5, -0.05]) == pytest.approx(0.05**2 / 0.2)
    # off the axis by rho = 0.5 at depth 0.05: r = sqrt(.5) (1 + .05 / .2), falloff 1 - rho^2 / r^2
    r_sq = 0.5 * 1.25**2
    assert psi([1.0, 0.5, -0.05]) == pytest.approx(0.0125 * (1 - 0.25 / r_sq))
    assert psi([1.0, 0.5, -0.05], radius_scale=2.0) == pytest.approx(
        0.0125 * (1 - 0.25 / (4 * r_sq))
    )
    # in front of the triangle, on its plane, and outside the cone: zero
    assert psi([0.5, 0.5, 0.1]) == 0.0
    assert psi([0.5, 0.5, 0.0]) == 0.0
    assert psi([3.0, 0.5, -0.05]) == 0.0


def test_circumcircle_of_a_right_triangle():
    centre, radius, normal = circumcircle(torch.tensor(FLAT, dtype=torch.float64))
    np.testing.assert_allclose(centre.numpy(), [0.5, 0.5, 0.0])  # midpoint of the hypotenuse
    assert float(radius) == pytest.approx(math.sqrt(0.5))
    np.testing.assert_allclose(normal.numpy(), [0.0, 0.0, 1.0])


def test_cone_field_broadcasts_and_rejects_bad_parameters():
    tris = torch.tensor([FLAT, PIERCING], dtype=torch.float64)  # (2, 3, 3)
    points = torch.zeros(4, 1, 3, dtype=torch.float64)  # (4, 1, 3)
    assert cone_distance_field(points, tris).shape == (4, 2)
    with pytest.raises(ValueError, match="positive"):
        cone_distance_field(points, tris, sigma=0.0)


def test_gradcheck_cone_field_and_energy():
    torch.manual_seed(0)
    tri = torch.tensor(FLAT, dtype=torch.float64).add(0.01 * torch.randn(3, 3, dtype=torch.float64))
    pts = torch.tensor([[0.4, 0.45, -0.3], [0.55, 0.5, -0.04]], dtype=torch.float64)
    assert torch.autograd.gradcheck(
        lambda p, t: cone_distance_field(p, t, 0.1, 0.2),
        (pts.requires_grad_(), tri.requires_grad_()),
    )
    v, f = two_triangles(PIERCING)
    pairs = colliding_triangle_pairs(v, f)
    verts = torch.tensor(v).add(0.01 * torch.randn(6, 3, dtype=torch.float64)).requires_grad_()
    assert torch.autograd.gradcheck(
        lambda x: interpenetration_energy(x, f, pairs, [0.7], sigma=0.1), (verts,)
    )


# ----------------------------------------------------------------------------- geodesic weights
def strip():
    """Two rows of 4 vertices 1 m apart, quads split along (i, 0)-(i+1, 1); plus a lone triangle."""
    bottom = [[i, 0.0, 0.0] for i in range(4)]
    top = [[i, 1.0, 0.0] for i in range(4)]
    lone = [[10.0, 0.0, 0.0], [11.0, 0.0, 0.0], [10.0, 1.0, 0.0]]
    faces = (
        [[i, i + 1, i + 5] for i in range(3)] + [[i, i + 5, i + 4] for i in range(3)] + [[8, 9, 10]]
    )
    return np.array(bottom + top + lone), np.array(faces)


def test_geodesic_distances_on_a_strip():
    v, f = strip()
    d = geodesic_distances(v, f)
    assert d.dtype == np.float32 and d.shape == (11, 11)
    assert d[0, 3] == pytest.approx(3.0)  # along the bottom row
    assert d[0, 7] == pytest.approx(2.0 + math.sqrt(2.0))  # one diagonal + two unit edges
    assert d[4, 3] == pytest.approx(4.0)  # diagonals point the wrong way
    assert d[0, 1] == pytest.approx(1.0) and d[0, 5] == pytest.approx(math.sqrt(2.0))
    assert np.isinf(d[0, 8]) and d[8, 10] == pytest.approx(1.0)


def test_geodesic_pair_weights_eq5():
    v, f = strip()
    d = geodesic_distances(v, f)
    # eta = largest finite distance = D(v4, v3) = 4. Face 0 = (0, 1, 5) vs face 2 = (2, 3, 7):
    # closest v1 - v2, 1 m. Face 3 = (0, 5, 4) vs face 2: v0 - v2, v5 - v2 and v5 - v7 all 2 m.
    # Face 6 lies on another piece: weight 1.
    w = geodesic_pair_weights([[0, 2], [2, 3], [0, 6]], f, d)
    np.testing.assert_allclose(w, [1.0 / 4.0, 2.0 / 4.0, 1.0], rtol=1e-6)
    np.testing.assert_allclose(geodesic_pair_weights([[0, 2]], f, d, eta=2.0), [0.5])


def test_geodesic_distances_on_demand_match_the_table():
    # the strip: eta = D(v4, v3) = 4 on the big piece (the lone triangle's diameter is 1.41)
    v, f = strip()
    lazy = GeodesicDistances(v, f)
    assert lazy.eta == pytest.approx(4.0) and lazy.cached_bytes == 0
    np.testing.assert_allclose(
        geodesic_pair_weights([[0, 2], [2, 3], [0, 6]], f, lazy), [0.25, 0.5, 1.0]
    )
    assert lazy.cached_bytes == 2 * 4 * len(v)  # faces 0 and 2 searched once each, 4 bytes a vertex


def test_geodesic_eta_is_the_exact_diameter_on_a_body():
    # the eccentricity bounds give the all-pairs maximum (farthest-point sweeps alone fall short by
    # 0.3-1% on these bodies); weights agree to float32 rounding of the table (1e-7 relative)
    for name in ("ada", "bram"):
        c = make_character(name)
        table, lazy = (
            geodesic_distances(c.rest_vertices, c.faces),
            GeodesicDistances(c.rest_vertices, c.faces),
        )
        assert lazy.eta == pytest.approx(float(table[np.isfinite(table)].max()), rel=1e-6)
        pairs = np.random.default_rng(0).integers(0, len(c.faces), (200, 2))
        np.testing.assert_allclose(
            geodesic_pair_weights(pairs, c.faces, lazy),
            geodesic_pair_weights(pairs, c.faces, table),
            rtol=1e-6,
            atol=1e-7,
        )
    with pytest.raises(ValueError, match="other faces"):
        geodesic_pair_weights([[0, 1]], c.faces[:-1], lazy)


# ----------------------------------------------------------------------------- energy
def boxes(depth):
    """A 1 m box (subdivided to 0.125 m triangles) and a 0.2 m box pushed ``depth`` into its +x
    face."""
    return merged(box(1.0, [0.0, 0.0, 0.0], 3), box(0.2, [0.6 - depth, 0.0, 0.0]))


def test_disjoint_boxes_have_zero_energy():
    v, f = merged(box(1.0, [0.0, 0.0, 0.0], 1), box(0.2, [2.0, 0.0, 0.0]))
    energy = InterpenetrationEnergy(f, v)
    assert len(energy.pairs(v)) == 0 and float(energy(v)) == 0.0


def test_box_pushed_in_energy_grows_with_depth_and_gradient_pushes_it_out():
    v, f = boxes(0.0)
    n_big = len(box(1.0, [0, 0, 0], 3)[0])
    energy = InterpenetrationEnergy(f, v, geodesic_weights=False)
    values = [float(energy(boxes(d)[0])) for d in (0.02, 0.05, 0.08)]
    assert 0 < values[0] < values[1] < values[2]
    verts = torch.tensor(boxes(0.05)[0], requires_grad=True)
    e0 = energy(verts)
    e0.backward()
    step = torch.zeros_like(verts)
    step[n_big:] = -verts.grad[n_big:]
    step *= 0.005 / step.norm(dim=1).max()  # move the small box's vertices <= 5 mm
    assert float(energy(verts.detach() + step)) < float(e0.detach())
    assert step[n_big:, 0].mean() > 0  # out of the big box, along +x


def test_eint_reads_only_its_support():
    # ESO skins only support(pairs): Eq. 4 on a mesh where every other vertex is zeroed is
    # unchanged, and the support holds more than the pairs' corners (their normals need the faces
    # around them)
    v, f = boxes(0.05)
    energy = InterpenetrationEnergy(f, v)
    pairs = energy.pairs(v)
    support = energy.support(pairs)
    assert len(support) > len(np.unique(f[pairs]))
    masked = torch.zeros(len(v), 3, dtype=torch.float64)
    masked[support] = torch.tensor(v[support])
    whole = energy.energy_of_pairs(torch.tensor(v)[None], [pairs])
    assert float(whole) > 0
    torch.testing.assert_close(energy.energy_of_pairs(masked[None], [pairs]), whole)
    assert len(energy.support(np.zeros((0, 2), np.int64))) == 0


def test_a_plan_on_the_support_alone_padded_gives_the_same_energy_and_gradient():
    # ESO plans Eq. 4 once per frame on the vertices it skins (the support, renumbered) and pads
    # the pairs with zero-weight copies for a compiled step: neither changes the energy or its
    # gradient
    v, f = boxes(0.05)
    energy = InterpenetrationEnergy(f, v)
    pairs = energy.pairs(v)
    whole = torch.tensor(v, requires_grad=True)
    reference = energy.energy_of_pairs(whole[None], [pairs])
    reference.sum().backward()
    support = energy.support(pairs)
    where = np.full(len(v), -1)
    where[support] = np.arange(len(support))
    part = torch.tensor(v[support], requires_grad=True)
    plan = energy.plan([pairs], vertex_index=where, min_pairs=len(pairs) + 3)
    assert plan.weights.shape == (len(pairs) + 3,) and (plan.weights[len(pairs) :] == 0).all()
    planned = plan_energy(part[None], plan, energy.cone)
    planned.sum().backward()
    torch.testing.assert_close(planned, reference)
    torch.testing.assert_close(part.grad, whole.grad[support])
    assert (
        float(whole.grad.abs().sum()) > 0
        and not whole.grad[np.setdiff1d(np.arange(len(v)), support)].any()
    )


def test_energy_class_matches_function_and_batches():
    v, f = boxes(0.05)
    energy = InterpenetrationEnergy(f, v)
    pairs = energy.pairs(v)
    t = torch.tensor(v)
    direct = interpenetration_energy(t, f, pairs, energy.pair_weights(pairs))
    assert float(energy(t)) == pytest.approx(float(direct)) and float(direct) > 0
    full_normals = vertex_normals(t, f)  # normals of every vertex, not only the colliding ones
    assert float(
        interpenetration_energy(t, f, pairs, energy.pair_weights(pairs), full_normals)
    ) == pytest.approx(float(direct))
    # the two boxes are separate pieces: infinite geodesic distance, every weight 1
    np.testing.assert_array_equal(energy.pair_weights(pairs), 1.0)
    assert float(interpenetration_energy(t, f, pairs)) == pytest.approx(float(direct))
    batch = torch.stack([t, torch.tensor(boxes(0.02)[0])])
    np.testing.assert_allclose(
        energy(batch).numpy(), [float(energy(batch[0])), float(energy(batch[1]))]
    )
    assert energy(batch[None].expand(3, 2, -1, -1)).shape == (3, 2)  # any leading dims
    np.testing.assert_array_equal(energy.penetrating_faces(v), np.unique(pairs))
    with pytest.raises(ValueError, match="vertices must be"):
        energy(t[:10])
    with pytest.raises(ValueError, match=r"\(T, V, 3\)"):
        interpenetration_score(energy, v, 1.7)


def test_vertex_normals_are_area_weighted():
    # vertex 0 is shared by a triangle of area 0.5 facing +z and one of area 2 facing +x
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 2, 0], [0, 0, 2]], dtype=torch.float64)
    n = vertex_normals(v, [[0, 1, 2], [0, 3, 4]])
    np.testing.assert_allclose(
        n[0].numpy(), np.array([2.0, 0.0, 0.5]) / math.hypot(2.0, 0.5), atol=1e-12
    )
    np.testing.assert_allclose(n[1].numpy(), [0.0, 0.0, 1.0])


def test_score_is_energy_over_height_squared_and_scale_invariant():
    v, f = boxes(0.05)
    energy = InterpenetrationEnergy(f, v)
    frames = np.stack([v, boxes(0.02)[0]])
    expected = float(energy(frames).mean()) / 1.7**2
    assert interpenetration_score(energy, frames, 1.7) == pytest.approx(expected)
    # twice the size, cone lengths twice as long: the same score at twice the height
    big = InterpenetrationEnergy(f, 2 * v, sigma=0.02, height=0.2)
    assert interpenetration_score(big, 2 * frames, 3.4) == pytest.approx(expected)


# ----------------------------------------------------------------------------- penetration rate
def test_cap_holes_closes_an_open_box():
    v, f = box(1.0, [0.0, 0.0, 0.0])
    open_faces = f[~np.isclose(v[f][:, :, 0], 0.5).all(1)]  # drop the two +x triangles
    cv, cf = cap_holes(v, open_faces)
    assert len(cv) == 9 and len(cf) == 14
    np.testing.assert_allclose(cv[8], [0.5, 0.0, 0.0])
    capped = trimesh.Trimesh(cv, cf, process=False)
    assert capped.is_watertight and capped.volume == pytest.approx(1.0)


def test_ray_winding_counts_overlapping_parts():
    v, f = merged(box(1.0, [0.0, 0.0, 0.0]), box(1.0, [0.5, 0.2, 0.1]))  # no coplanar faces
    w = ray_winding_numbers([[-0.3, 0.1, 0.1], [0.25, 0.1, 0.1], [2.0, 0.0, 0.0]], v, f)
    np.testing.assert_array_equal(w, [1, 2, 0])


def test_penetration_rate_of_a_box_half_inside():
    big_v, big_f = box(1.0, [0.0, 0.0, 0.0])
    v, f = merged((big_v, big_f), box(0.2, [0.5, 0.0, 0.0]))  # straddles the +x face
    weights = np.zeros((len(v), 22))
    weights[: len(big_v), J["Spine"]] = 1.0
    weights[len(big_v) :, J["LeftForeArm"]] = 1.0
    rates = penetration_rate(v, f, weights)
    assert rates["left_arm"] == pytest.approx(0.5)  # 4 of its 8 corners inside the big box
    assert math.isnan(rates["right_arm"])
    assert penetration_rate(v + [[0.0, 0.0, 0.0]], f, weights, {"arm": ["LeftForeArm"]}) == {
        "arm": 0.5
    }
    with pytest.raises(ValueError, match="unknown joints"):
        penetration_rate(v, f, weights, {"tail": ["Tail"]})


def test_penetration_rate_leaves_out_what_the_rest_pose_already_has_inside():
    big_v, big_f = box(1.0, [0.0, 0.0, 0.0])
    rest, f = merged((big_v, big_f), box(0.2, [0.5, 0.0, 0.0]))  # 4 arm corners inside at rest
    weights = np.zeros((len(rest), 22))
    weights[: len(big_v), J["Spine"]] = 1.0
    weights[len(big_v) :, J["LeftForeArm"]] = 1.0
    arm = {"arm": ["LeftForeArm"]}
    assert penetration_rate(rest, f, weights, arm, rest_vertices=rest) == {"arm": 0.0}
    assert not limb_vertices_inside(rest, f, weights, arm, rest_vertices=rest).any()
    # the arm pushed 0.2 in -x: all 8 corners inside; the 4 outside at rest count, 4 of 4
    pushed = rest.copy()
    pushed[len(big_v) :, 0] -= 0.2
    assert penetration_rate(pushed, f, weights, arm) == {"arm": 1.0}
    assert penetration_rate(pushed, f, weights, arm, rest_vertices=rest) == {"arm": 1.0}
    assert limb_vertices_inside(pushed, f, weights, arm, rest_vertices=rest).sum() == 4
    # pulled 0.2 in +x: every corner outside, whichever way it is counted
    pulled = rest.copy()
    pulled[len(big_v) :, 0] += 0.2
    assert penetration_rate(pulled, f, weights, arm, rest_vertices=rest) == {"arm": 0.0}
    # an arm wholly inside at rest has nothing left to count
    inside = rest.copy()
    inside[len(big_v) :, 0] -= 0.3
    assert math.isnan(penetration_rate(inside, f, weights, arm, rest_vertices=inside)["arm"])


def test_limb_vertices_inside_of_a_stack_is_each_frame_and_averages_to_the_rate():
    big_v, big_f = box(1.0, [0.0, 0.0, 0.0])
    rest, f = merged((big_v, big_f), box(0.2, [0.5, 0.0, 0.0]))
    weights = np.zeros((len(rest), 22))
    weights[: len(big_v), J["Spine"]] = 1.0
    weights[len(big_v) :, J["LeftForeArm"]] = 1.0
    arm = {"arm": ["LeftForeArm"]}
    pushed, pulled = rest.copy(), rest.copy()
    pushed[len(big_v) :, 0] -= 0.2
    pulled[len(big_v) :, 0] += 0.2
    stack = np.stack([rest, pushed, pulled])
    masks = limb_vertices_inside(stack, f, weights, arm, rest_vertices=rest)
    assert masks.shape == (3, len(rest))
    for frame, mask in zip(stack, masks, strict=True):
        np.testing.assert_array_equal(
            mask, limb_vertices_inside(frame, f, weights, arm, rest_vertices=rest)
        )
    assert masks.sum(1).tolist() == [0, 4, 0]  # only the 4 corners outside at rest count
    # the rate averages the frames' shares of those 4 counted corners: (0 + 1 + 0) / 3
    rate = penetration_rate(stack, f, weights, arm, rest_vertices=rest)["arm"]
    assert rate == pytest.approx(1 / 3)


# ---------------------------------------------------------------------------- a synthetic character
def test_character_rest_pose_is_clean_and_forearm_in_torso_is_not():
    from retarget_lib.data.synthetic.characters import make_character
    from retarget_lib.evaluation.bench_contact import forearm_in_torso_pose

    character = make_character("ada")
    energy = InterpenetrationEnergy(character.faces, character.rest_vertices)
    assert float(energy(character.rest_vertices)) < 1e-6
    posed = forearm_in_torso_pose(character, dtype=torch.float64)
    assert float(energy(posed)) > 1e-3 and len(energy.pairs(posed)) > 50
    rates = penetration_rate(posed, character.faces, character.weights)
    assert rates["left_arm"] > 0.1 and rates["right_arm"] == 0.0
    assert (
        penetration_rate(character.rest_vertices, character.faces, character.weights)["left_arm"]
        == 0.0
    )


def test_bench_eint_rows():
    from retarget_lib.evaluation.bench_contact import bench_eint

    rows = bench_eint(quick=True)
    assert [r.reference_seconds is not None for r in rows[:4]] == [True, True, False, False]
    assert all(r.seconds > 0 for r in rows) and rows[1].speedup > 1


def test_detection_on_two_threads_finds_the_same_pairs():
    # the hierarchy's lower levels dealt to two threads: the same sorted pairs as one thread
    v, f = boxes(0.05)
    bvh = TriangleBVH(f, v)
    assert bvh.depth > SPLIT_DEPTH
    one = colliding_triangle_pairs(v, f, bvh)
    assert len(one) > 10
    np.testing.assert_array_equal(colliding_triangle_pairs(v, f, bvh, workers=2), one)
    np.testing.assert_array_equal(colliding_triangle_pairs(v, f, bvh, workers=3), one)


def test_intersections_of_the_rest_pose_can_be_left_out():
    # a mesh built intersecting (a small box through a big one's face, as a belt through a trunk):
    # with ignore_rest_intersections those pairs are not detected in any frame, new ones are
    v, f = boxes(0.05)
    kept = InterpenetrationEnergy(f, v)
    ignored = InterpenetrationEnergy(f, v, ignore_rest_intersections=True)
    at_rest = kept.pairs(v)
    assert len(at_rest) > 0 and len(kept.rest_pairs) == 0
    np.testing.assert_array_equal(ignored.rest_pairs, at_rest)
    assert len(ignored.pairs(v)) == 0 and float(ignored(v)) == 0.0
    deeper = v.copy()
    small = np.arange(len(v)) >= len(box(1.0, [0.0, 0.0, 0.0], 3)[0])
    deeper[small, 0] -= (
        0.1  # the small box pushed 10 cm further in: its side faces cross the big face elsewhere
    )
    new = ignored.pairs(deeper)
    assert len(new) > 0
    both = kept.pairs(deeper)
    codes = lambda p: set(map(tuple, p))  # noqa: E731
    assert codes(new) == codes(both) - codes(at_rest)
