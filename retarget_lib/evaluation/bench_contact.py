"""Speed benchmarks of the contact-aware energies (listed in ``retarget bench`` by
:mod:`retarget_lib.evaluation.bench`): each timing beside a reference measured in the same run.

``E_int`` (Villegas et al. 2021, Eq. 4) + backward, per frame, on a ~3,000-vertex synthetic
character whose left forearm is bent into the torso, broken down into detection (BVH broad phase +
exact triangle test), energy, and energy + backward. The reference detection compares every pair of
triangle boxes (``F^2 / 2`` tests) before the same narrow phase — what the BVH replaces.

The energy is a few hundred tiny tensor operations; with several torch threads on a busy machine
each can stall for milliseconds in the thread pool, so when the process runs more than one torch
thread the full pipeline is also timed with one.
"""

from __future__ import annotations

import numpy as np
import torch

from ..core.rotations import quat_from_axis_angle
from ..core.skeleton import J
from ..data.manifest import checkpoint_entries
from ..data.sources.mannequin import load_mannequin
from ..data.sources.real_characters import load_real_character
from ..data.synthetic.characters import make_character
from ..data.synthetic.motions import body_radii_from_mesh, make_motion
from ..geometry.collision import brute_force_candidate_pairs, triangles_intersect
from ..geometry.contacts import transfer_contacts
from ..geometry.geodesic import geodesic_distances
from ..geometry.penetration import InterpenetrationEnergy
from ..methods.contact import contact_clip, load_contact_model, retarget_with_network
from ..methods.eso import eso_throughput
from ..methods.registry import get_method
from ..models.georet import GeometryConditionedRNN
from .real import welded
from .timing import BenchRow, time_it


def forearm_in_torso_pose(
    character, arm_down_deg: float = 80.0, forearm_deg: float = 100.0, dtype=torch.float32
) -> torch.Tensor:
    """The character's mesh with the left arm lowered and the forearm bent across the belly.

    Args:
        character: a :class:`~retarget_lib.core.character.Character`.
        arm_down_deg: ``LeftArm`` rotation about -Z (degrees; 90 lowers a T-pose arm to the side).
        forearm_deg: ``LeftForeArm`` rotation about -Z (degrees; about 100 bends it into the torso).
        dtype: float dtype of the result.

    Returns:
        ``(V, 3)`` posed vertices (metres), root at its rest position.
    """
    axis_angle = torch.zeros(22, 3, dtype=torch.float64)
    axis_angle[J["LeftArm"], 2] = -np.radians(arm_down_deg)
    axis_angle[J["LeftForeArm"], 2] = -np.radians(forearm_deg)
    rot = quat_from_axis_angle(axis_angle).to(dtype)
    root = torch.as_tensor(character.skeleton.offsets[0], dtype=dtype)
    return character.skinned(rot, root)


def _brute_force_pairs(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    cand = brute_force_candidate_pairs(vertices, faces)
    return cand[triangles_intersect(vertices[faces[cand[:, 0]]], vertices[faces[cand[:, 1]]])]


def bench_eint(quick: bool = False) -> list[BenchRow]:
    """``E_int`` + backward per frame on a self-penetrating ~3k-vertex character, with its
    breakdown, beside all-pairs box detection (same run). Medians over repeats."""
    character = make_character("ada")
    energy = InterpenetrationEnergy(character.faces, character.rest_vertices)
    posed = forearm_in_torso_pose(character).detach()
    posed_np = posed.numpy().astype(np.float64)
    pairs = energy.pairs(posed_np)
    repeat = 5 if quick else 21
    vertices = posed.clone().requires_grad_()

    def full():
        vertices.grad = None
        energy(vertices).backward()

    def energy_only():
        with torch.no_grad():
            energy.energy_of_pairs(posed[None], [pairs])

    def energy_backward():
        vertices.grad = None
        energy.energy_of_pairs(vertices[None], [pairs]).sum().backward()

    t_full = time_it(full, repeat=repeat)
    t_detect = time_it(lambda: energy.pairs(posed_np), repeat=repeat)
    t_energy = time_it(energy_only, repeat=repeat)
    t_energy_backward = time_it(energy_backward, repeat=repeat)
    t_brute = time_it(
        lambda: _brute_force_pairs(posed_np, energy.faces), repeat=1 if quick else 3, warmup=0
    )
    label = (
        f"{character.num_vertices} vertices, {len(energy.faces)} faces, "
        f"{len(pairs)} colliding pairs"
    )
    reference = "all-pairs box test + same narrow phase"
    threads = torch.get_num_threads()
    rows = [
        BenchRow(
            f"E_int + backward per frame ({label}), {threads} torch thread(s)",
            t_full,
            f"{reference}, + same energy",
            t_brute + t_full - t_detect,
            "<= 50 ms",
        ),
        BenchRow("E_int detection (BVH + exact triangle test)", t_detect, reference, t_brute),
        BenchRow("E_int energy forward (Eq. 4 + Eq. 5 weights)", t_energy),
        BenchRow("E_int energy forward + backward (detection excluded)", t_energy_backward),
    ]
    if threads > 1:
        try:
            torch.set_num_threads(1)
            t_single = time_it(full, repeat=repeat)
        finally:
            torch.set_num_threads(threads)
        rows.append(
            BenchRow(
                "E_int + backward per frame, 1 torch thread",
                t_single,
                f"{threads} torch threads",
                t_full,
                "<= 50 ms",
            )
        )
    return rows


def bench_eso(quick: bool = False) -> list[BenchRow]:
    """Encoder-space optimisation throughput (Sec. 3.3: 30 Adam steps per frame) on a contact-rich
    clip retargeted from ``mannequin-x`` to the bulky ~3k-vertex ``otto``, with its detected hand
    contacts and Eint; the reference is the network alone on the same frames (same run).

    Uses the ``contact`` method's default checkpoint (the shipped ``Efull``) when present, else a
    randomly initialised network of the same size (the cost per frame is the same).
    """
    frames = 8 if quick else 30
    source, target = load_mannequin(), make_character("otto")
    motion = make_motion(
        "pray",
        source.skeleton,
        8,
        body_radii=body_radii_from_mesh(source.skeleton, source.rest_vertices, source.weights),
    )
    motion = motion.slice(30, 30 + frames)
    source_contacts = contact_clip(motion, source).self_contacts
    contacts = transfer_contacts(source_contacts, source, target)
    shipped = get_method("contact").default_checkpoint()
    if shipped is not None:
        model, _ = load_contact_model(shipped)
        which = f"shipped {checkpoint_entries()[shipped].row}"
    else:
        model, which = GeometryConditionedRNN().eval(), "untrained"
    eint = InterpenetrationEnergy(target.faces, target.rest_vertices)
    stats = eso_throughput(
        model, motion, target, frames=frames, interpenetration=eint, contacts=contacts
    )
    per_frame = stats["seconds"] / frames
    network = (
        time_it(lambda: retarget_with_network(model, motion, target), repeat=3 if quick else 5)
        / frames
    )
    rows = [
        BenchRow(
            f"ESO per frame, 30 iterations ({which} network, {target.num_vertices} vertices, "
            f"{frames} frames, {stats['colliding_pairs']:.0f} colliding pairs/frame)",
            per_frame,
            "network alone, per frame",
            network,
            "<= 0.5 s (>= 2 frames/s)",
        )
    ]
    return rows + _bench_eso_real_body(model, which, motion, source, source_contacts, frames, quick)


#: the real body of the full-mesh ESO rows: MakeHuman's default character, 13,380 vertices
REAL_BODY = "makehuman_default"


def _bench_eso_real_body(
    model, which: str, motion, source, source_contacts, frames: int, quick: bool
) -> list[BenchRow]:
    """ESO on a real body: MakeHuman's 13,380 vertices decimated to 10,000 (issue 24's size),
    compiled (``compile=True``: the whole step fused by ``torch.compile``, compilation in the
    untimed warm-up) beside the same uncompiled (what ran before); then the full 13,380 vertices
    compiled beside the 3,000-vertex decimated copy ``--method contact`` runs above
    ``ESO_MAX_VERTICES`` (Eint's geodesics searched on demand, each step skinning only the vertices
    its energy reads); and the cost of building its Eint: on demand, against the all-pairs geodesic
    table it replaced (34 s and 716 MB on an idle core; not run with ``quick``)."""
    body = welded(load_real_character(REAL_BODY).character())
    per_frame = {}
    for name, target in (
        ("10k", body.decimated(10_000)),
        ("full", body),
        ("small", body.decimated(3000)),
    ):
        contacts = transfer_contacts(source_contacts, source, target)
        eint = InterpenetrationEnergy(target.faces, target.rest_vertices)
        for compile in (True, False) if name == "10k" else (True,):
            stats = eso_throughput(
                model,
                motion,
                target,
                frames=frames,
                interpenetration=eint,
                contacts=contacts,
                compile=compile,
            )
            per_frame[name, compile] = (
                stats["seconds"] / frames,
                stats["colliding_pairs"],
                target.num_vertices,
            )
    setup = time_it(
        lambda: InterpenetrationEnergy(body.faces, body.rest_vertices), repeat=1 if quick else 3
    )
    table = (
        None
        if quick
        else time_it(lambda: geodesic_distances(body.rest_vertices, body.faces), repeat=1, warmup=0)
    )
    ten_k, full, small = per_frame["10k", True], per_frame["full", True], per_frame["small", True]
    return [
        BenchRow(
            f"ESO per frame, 30 iterations, compiled ({which} network, real body {REAL_BODY} "
            "decimated to "
            f"{ten_k[2]} vertices, {ten_k[1]:.0f} colliding pairs/frame): {1 / ten_k[0]:.1f} "
            "frames/s",
            ten_k[0],
            "the same uncompiled",
            per_frame["10k", False][0],
            ">= 10 frames/s on 10k vertices (issue 24)",
        ),
        BenchRow(
            f"ESO per frame, compiled, full real body ({full[2]} vertices, {full[1]:.0f} colliding "
            f"pairs/frame)",
            full[0],
            f"the same on its decimated copy ({small[2]} vertices)",
            small[0],
        ),
        BenchRow(
            f"Eint setup on {body.num_vertices} vertices (BVH, Eq. 5 geodesics on demand)",
            setup,
            "all-pairs geodesic table",
            table,
        ),
    ]
