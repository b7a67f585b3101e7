"""Virtual joints: the canonical joints a rig does not have, inserted so that the library always
sees 22.

A joint map (:func:`~retarget_lib.io.rig_maps.load_mapping_file`) may mark a canonical joint
``null``: the rig has no such joint. Only the joints in :data:`MAY_BE_ABSENT` may be absent (a rig
with two spine joints, no neck, no clavicles or no toes); the hips, head, legs, feet, arms and hands
are needed.

An absent joint becomes a **virtual joint** of the file's skeleton: a joint between two present ones
(``Spine2`` of a two-spine rig, a clavicle) is placed on the bone between them (evenly, when
several in a row are absent), a leaf (a toe) at its parent with a zero-length bone; it has the
identity rotation in every frame, so every file joint keeps its position and rotation. Writing a
result back on the rig (:func:`~retarget_lib.core.canonical.unfold_from_canonical22` with the
present joints' map) composes the virtual joints out: a present joint takes its kept ancestor's
global rotation undone, then its own, so the file has exactly its own joints (a bend the result puts
at an inserted joint is carried by the bone's end instead). Every fold
(:func:`~retarget_lib.core.canonical.fold_to_canonical22`) inserts them, whatever the file's format:
BVH, glTF/GLB/VRM, FBX and SMPL-X files (:mod:`retarget_lib.io.joint_maps`) and rigs
(:class:`~retarget_lib.core.rig.Rig`) alike; a rig convention that lacks a joint (Biovision's
``Spine2``) gets it the same way.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .motion import Motion
from .skeleton import CANONICAL22, CANONICAL22_PARENTS, J, Skeleton

__all__ = ["MAY_BE_ABSENT", "CHAIN_CHILD", "with_virtual_joints"]

#: canonical joints a joint map may mark ``null`` (absent from the rig)
MAY_BE_ABSENT: tuple[str, ...] = (
    "Spine",
    "Spine1",
    "Spine2",
    "Neck",
    "LeftShoulder",
    "RightShoulder",
    "LeftToeBase",
    "RightToeBase",
)
#: the canonical child that continues each joint's chain (where an absent joint is placed towards)
CHAIN_CHILD: dict[int, int] = {
    J["Hips"]: J["Spine"],
    J["Spine"]: J["Spine1"],
    J["Spine1"]: J["Spine2"],
    J["Spine2"]: J["Neck"],
    J["Neck"]: J["Head"],
    J["LeftShoulder"]: J["LeftArm"],
    J["RightShoulder"]: J["RightArm"],
    J["LeftFoot"]: J["LeftToeBase"],
    J["RightFoot"]: J["RightToeBase"],
}


def _present_end(c: int, present: set[int]) -> int | None:
    """The first present canonical joint down ``c``'s chain, or None (a leaf chain)."""
    while c in CHAIN_CHILD:
        c = CHAIN_CHILD[c]
        if c in present:
            return c
    return None


def _run_of_absent(c: int, present: set[int]) -> list[int]:
    """``c`` and the absent joints after it down its chain, up to the next present one."""
    run = [c]
    while run[-1] in CHAIN_CHILD and CHAIN_CHILD[run[-1]] not in present:
        run.append(CHAIN_CHILD[run[-1]])
    return run


def with_virtual_joints(
    motion: Motion, index_map: Mapping[int, int]
) -> tuple[Motion, dict[int, int]]:
    """Insert the canonical joints ``index_map`` lacks into ``motion``'s skeleton (module
    docstring).

    Args:
        motion: a motion on a file's joints (rest rotations identity, offsets in world axes: BVH).
        index_map: ``{file joint index: canonical index}`` of the joints the rig has; every missing
            one must be in :data:`MAY_BE_ABSENT`.

    Returns:
        ``(motion on the skeleton with the virtual joints, {joint index: canonical index} of all
        22)``; each virtual joint is named ``"<canonical name> (virtual)"``.
    """
    present = set(index_map.values())
    missing = [c for c in range(22) if c not in present]
    if not missing:
        return motion, dict(index_map)
    sk = motion.skeleton
    names, parents = list(sk.joint_names), list(sk.parents)
    rest = sk.rest_positions()
    file_of = {c: i for i, c in index_map.items()}
    #: one chain of virtual joints per run of absent ones: (anchor file joint, [(canonical,
    #: rest position)], the file joint that ends the run or None for a leaf run)
    runs: list[tuple[int, list[tuple[int, np.ndarray]], int | None]] = []
    done: set[int] = set()
    for c in missing:
        if c in done:
            continue
        parent = CANONICAL22_PARENTS[c]
        while parent not in file_of:  # an absent parent is placed first (canonical order)
            parent = CANONICAL22_PARENTS[parent]
        run = _run_of_absent(c, present)
        end = _present_end(run[-1], present) if run[-1] in CHAIN_CHILD else None
        start = rest[file_of[parent]]
        stop = rest[file_of[end]] if end is not None else start
        runs.append(
            (
                file_of[parent],
                [(cc, start + (stop - start) * k / (len(run) + 1)) for k, cc in enumerate(run, 1)],
                file_of[end] if end is not None else None,
            )
        )
        done.update(run)
    # the new joint order: each run's joints right after its anchor, chained; the file joint on the
    # path from the anchor to the run's present end re-parented under the run's last joint
    after: dict[int, list[int]] = {}
    for r, (anchor, _, _) in enumerate(runs):
        after.setdefault(anchor, []).append(r)
    new_order: list[tuple[str, int]] = []
    for i in range(len(names)):
        new_order.append(("file", i))
        new_order += [("virtual", cc) for r in after.get(i, []) for cc, _ in runs[r][1]]
    index_of = {item: k for k, item in enumerate(new_order)}
    n = len(new_order)
    new_names, new_parents = [""] * n, [-1] * n
    new_rest = np.zeros((n, 3))
    virtual_pos = {cc: pos for _, run, _ in runs for cc, pos in run}
    reparent: dict[int, int] = {}  # file joint -> new parent
    for anchor, chain, end in runs:
        prev = index_of[("file", anchor)]
        for cc, _ in chain:
            new_parents[index_of[("virtual", cc)]] = prev
            prev = index_of[("virtual", cc)]
        if end is not None:
            x = end
            while parents[x] != anchor:
                x = parents[x]
            reparent[x] = prev
    for k, (kind, i) in enumerate(new_order):
        if kind == "file":
            new_names[k] = names[i]
            new_parents[k] = reparent.get(
                i, index_of[("file", parents[i])] if parents[i] >= 0 else -1
            )
            new_rest[k] = rest[i]
        else:
            new_names[k] = f"{CANONICAL22[i]} (virtual)"
            new_rest[k] = virtual_pos[i]
    offsets = new_rest.copy()
    for k, p in enumerate(new_parents):
        if p >= 0:
            offsets[k] = new_rest[k] - new_rest[p]
    file_rows = [i for kind, i in new_order if kind == "file"]
    rotations = np.zeros((motion.num_frames, n, 4))
    rotations[..., 0] = 1.0  # virtual joints: identity
    rotations[:, [index_of[("file", i)] for i in file_rows]] = motion.rotations[:, file_rows]
    skeleton = Skeleton(tuple(new_names), tuple(new_parents), offsets)
    full = {index_of[("file", i)]: c for i, c in index_map.items()}
    full.update({index_of[("virtual", cc)]: cc for cc in virtual_pos})
    return motion.copy(skeleton=skeleton, rotations=rotations), full
