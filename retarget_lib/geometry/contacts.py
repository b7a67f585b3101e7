"""Contact detection in the source motion and vertex correspondence between characters
(Villegas et al. 2021, Sec. 3.4 and Appendix F).

**Foot contacts** (:func:`detect_foot_contacts`) are read from the skeleton with simple thresholds
(:mod:`retarget_lib.core.ground`'s Sec. 3.4 constants). At the paper's scale of a 180 cm character:
a toe joint (``*ToeBase``) is in contact when its height above the ground is at most 3 cm and it
moved at most 1 cm since the previous frame; a heel joint (``*Foot``, the ankle) only needs the 1 cm
displacement (some Mixamo subjects wear high heels, so a heel height says little). A sliding window
of 5 frames then fills short gaps (false negatives). These contacts feed the foot term ``Efoot``
(Eq. 6).

**Self-contacts** (:func:`detect_self_contacts`) are read from the skinned mesh. Each joint owns a
*vertex group*, the vertices whose skinning weight for it is at least 0.5, and the triangles among
them. In every frame each hand group is tested against the other groups for intersection with a
bounding volume hierarchy; an intersecting pair is a contact if the two groups move together
(mean cosine similarity of their per-vertex velocities > 0.9) or if their nearest vertices are
closer than 0.2 cm (at 138 cm, the paper's shortest character). Each contact becomes the top-3
closest vertex pairs ``(i, j)``: the set ``V`` of the self-contact term ``Ej2j`` (Eq. 3).

**Contact transfer** (:func:`transfer_contacts`): source and target meshes differ in shape and
topology, so each source vertex is matched to the target vertex with the most similar feature
vector -- its skinning weights and its offset to its joint divided by the character's height
(Appendix F) -- by a KD-tree search.

Conventions: metres, +Y up, ground at ``y = 0``, canonical 22 joints, 30 fps unless stated.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import fcl
import numpy as np
import torch
from scipy.spatial import cKDTree

from ..core.ground import REFERENCE_FPS, REFERENCE_HEIGHT_M, STAND_BAND_M, STILL_STEP_M
from ..core.kinematics import forward_kinematics
from ..core.measures import foot_rest_heights
from ..core.retarget_pose import pose_local_rotations, retarget_pose
from ..core.skeleton import CANONICAL22, CANONICAL22_PARENTS, FOOT_CONTACT_JOINTS, J, Skeleton

__all__ = [
    "FOOT_JOINTS",
    "SelfContacts",
    "authored_contact_frames",
    "correspondence_features",
    "detect_foot_contacts",
    "detect_self_contacts",
    "fill_contacts",
    "frame_precision_recall",
    "group_faces",
    "transfer_contacts",
    "vertex_correspondence",
    "vertex_groups",
]

#: column order of foot contacts: heels (``*Foot``, the ankle joints) then toes (``*ToeBase``)
FOOT_JOINTS: tuple[str, ...] = FOOT_CONTACT_JOINTS


# ----------------------------------------------------------------------------- foot contacts
def fill_contacts(contacts: np.ndarray, window: int = 5) -> np.ndarray:
    """Fill short gaps in contact tracks by a centred sliding-window majority (Sec. 3.4).

    A frame that is not in contact becomes contact if more than half of the frames in the window
    centred on it are in contact. As in the paper the step only removes false negatives: a contact
    frame is never removed (an isolated contact frame stays). At the clip's edges the window is
    truncated to the frames that exist and the majority is taken over those (frame 0 with
    ``window = 5`` looks at frames 0-2 and needs 2 of them). With ``window = 5`` gaps of one or two
    frames between contacts are filled; a gap of three is not.

    Args:
        contacts: ``(T,)`` or ``(T, C)`` bool, one column per joint.
        window: odd window length in frames (1 = no filling).

    Returns:
        Filled contacts, same shape, bool.
    """
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.ndim not in (1, 2) or len(contacts) == 0:
        raise ValueError(f"contacts must be (T,) or (T, C) with T >= 1, got {contacts.shape}")
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd number of frames, got {window}")
    half, T = window // 2, len(contacts)
    cumulative = np.concatenate(
        [np.zeros((1,) + contacts.shape[1:], int), np.cumsum(contacts, axis=0)]
    )
    lo = np.clip(np.arange(T) - half, 0, T)
    hi = np.clip(np.arange(T) + half + 1, 0, T)
    in_contact = cumulative[hi] - cumulative[lo]
    size = (hi - lo).reshape((T,) + (1,) * (contacts.ndim - 1))
    return contacts | (2 * in_contact > size)


def _frame_displacements(points: np.ndarray) -> np.ndarray:
    """``(T, K)`` distance each of ``K`` points moved since the previous frame; frame 0 (which has
    none) takes its displacement to frame 1. ``points``: ``(T, K, 3)``, ``T >= 2``."""
    step = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    return np.concatenate([step[:1], step])


def detect_foot_contacts(
    positions: np.ndarray,
    skeleton: Skeleton,
    character_height: float,
    window: int = 5,
    fps: float = REFERENCE_FPS,
) -> np.ndarray:
    """Heel and toe contacts with the ground (Villegas et al. 2021, Sec. 3.4), for ``Efoot`` (Eq.
    6).

    Thresholds at 180 cm scale, multiplied by ``character_height / 1.80``:

    * toe (``*ToeBase``): height above the ground at most 3 cm **and** displacement from the
      previous frame at most 1 cm;
    * heel (``*Foot``): displacement from the previous frame at most 1 cm.

    A toe's height above the ground is its ``y`` minus the toe joint's rest height above the
    rest ground (:func:`~retarget_lib.core.measures.foot_rest_heights`) -- the convention of
    ``Efoot``, which takes heel and toe heights from the T-pose (Sec. 3.1.1) -- so a toe joint
    resting on a flat foot reads 0.
    Displacements are 3-D and per frame at 30 fps (Mixamo's rate); at another ``fps`` the 1 cm
    is scaled by ``30 / fps`` (the same speed, 0.3 m/s at 180 cm). Frame 0 has no previous frame
    and uses its displacement to frame 1. Finally :func:`fill_contacts` (``window`` frames)
    fills short gaps.

    Args:
        positions: ``(T, J, 3)`` global joint positions (metres, +Y up, ground ``y = 0``),
            ``T >= 2``, joints in ``skeleton``'s order.
        skeleton: the skeleton of ``positions`` (needs the canonical foot joint names); its rest
            pose gives the toe rest heights.
        character_height: the character's standing height in metres, the thresholds' scale;
            every caller in the library passes
            :func:`~retarget_lib.core.measures.estimated_standing_height` of ``skeleton``.
        window: sliding-window length of the gap filling (odd; 1 = none).
        fps: frame rate of ``positions``.

    Returns:
        ``(T, 4)`` bool in :data:`FOOT_JOINTS` order (left heel, right heel, left toe, right toe).
    """
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (skeleton.num_joints, 3) or len(positions) < 2:
        raise ValueError(
            f"positions must be (T >= 2, {skeleton.num_joints}, 3), got {positions.shape}"
        )
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    height = float(character_height)
    if height <= 0:
        raise ValueError(f"character_height must be positive, got {height}")
    scale = height / REFERENCE_HEIGHT_M
    idx = [skeleton.index(n) for n in FOOT_JOINTS]
    feet = positions[:, idx]  # (T, 4, 3)
    still = _frame_displacements(feet) <= STILL_STEP_M * scale * REFERENCE_FPS / fps
    toe_rest = foot_rest_heights(skeleton)[2:]
    low = feet[:, 2:, 1] - toe_rest <= STAND_BAND_M * scale
    raw = still.copy()
    raw[:, 2:] &= low
    return fill_contacts(raw, window)


# ----------------------------------------------------------------------------- vertex groups
def vertex_groups(weights: np.ndarray, threshold: float = 0.5) -> list[np.ndarray]:
    """Per joint, the vertices it dominates (Sec. 3.4: skinning weight at least 0.5).

    Args:
        weights: ``(V, J)`` skinning weights.
        threshold: minimum weight.

    Returns:
        ``J`` sorted int64 arrays of vertex indices (a vertex is in at most one group when
        ``threshold > 0.5``; at exactly 0.5 it can be in two).
    """
    weights = np.asarray(weights)
    if weights.ndim != 2:
        raise ValueError(f"weights must be (V, J), got {weights.shape}")
    return [np.flatnonzero(weights[:, j] >= threshold) for j in range(weights.shape[1])]


def group_faces(
    faces: np.ndarray, groups: Sequence[np.ndarray], num_vertices: int | None = None
) -> list[np.ndarray]:
    """Per group, the triangles whose three vertices all belong to it ("each group also includes
    the triangles formed by its vertices", Sec. 3.4).

    Args:
        faces: ``(F, 3)`` int triangles.
        groups: per joint, vertex indices (:func:`vertex_groups`).
        num_vertices: ``V`` (default: one more than the largest index in ``faces``).

    Returns:
        Per group, sorted int64 face indices into ``faces``.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {faces.shape}")
    n = int(faces.max()) + 1 if num_vertices is None else int(num_vertices)
    out = []
    for g in groups:
        member = np.zeros(n, dtype=bool)
        member[np.asarray(g, dtype=np.int64)] = True
        out.append(np.flatnonzero(member[faces].all(axis=1)))
    return out


# ----------------------------------------------------------------------------- self-contacts
@dataclass
class SelfContacts:
    """Vertex-pair contact constraints over a clip (the sets ``V`` of Eq. 3, one per frame).

    Attributes:
        num_frames: ``T``, frames of the clip.
        frames: ``(K,)`` int64 frame of each constraint.
        pairs: ``(K, 2)`` int64 vertex indices ``(i, j)`` that should touch.
        groups: ``(K, 2)`` int64 joint index of the group of ``i`` and of ``j`` (``i`` is on a
            hand group).
    """

    num_frames: int
    frames: np.ndarray
    pairs: np.ndarray
    groups: np.ndarray

    def __post_init__(self) -> None:
        self.frames = np.asarray(self.frames, dtype=np.int64).reshape(-1)
        self.pairs = np.asarray(self.pairs, dtype=np.int64).reshape(-1, 2)
        self.groups = np.asarray(self.groups, dtype=np.int64).reshape(-1, 2)
        k = len(self.frames)
        if len(self.pairs) != k or len(self.groups) != k:
            raise ValueError(
                f"SelfContacts: {k} frames, {len(self.pairs)} pairs, {len(self.groups)} groups"
            )
        if k and (self.frames.min() < 0 or self.frames.max() >= self.num_frames):
            raise ValueError(f"SelfContacts: frames must lie in [0, {self.num_frames})")

    def __len__(self) -> int:
        return len(self.frames)

    def at(self, frame: int) -> np.ndarray:
        """``(n, 2)`` vertex pairs of one frame."""
        return self.pairs[self.frames == frame]

    def frame_mask(self, joint: int | str | None = None) -> np.ndarray:
        """``(T,)`` bool: frames with any contact (only those involving ``joint``'s group if given,
        as an index or a canonical name)."""
        keep = np.ones(len(self.frames), dtype=bool)
        if joint is not None:
            j = J[joint] if isinstance(joint, str) else int(joint)
            keep = (self.groups == j).any(axis=1)
        mask = np.zeros(self.num_frames, dtype=bool)
        mask[self.frames[keep]] = True
        return mask

    def remap(self, correspondence: np.ndarray) -> SelfContacts:
        """The constraints on another mesh: each vertex id mapped through ``correspondence``.

        Rows that become identical within a frame are kept once, and a pair whose two vertices map
        to the same target vertex (an empty constraint) is dropped.

        Args:
            correspondence: ``(V_src,)`` int, target vertex of each source vertex
                (:func:`vertex_correspondence`).
        """
        correspondence = np.asarray(correspondence, dtype=np.int64)
        if correspondence.ndim != 1 or (
            len(self.pairs) and self.pairs.max() >= len(correspondence)
        ):
            raise ValueError(
                f"correspondence must be (V_src,) covering vertex {self.pairs.max(initial=-1)}, "
                f"got {correspondence.shape}"
            )
        pairs = correspondence[self.pairs]
        rows = np.column_stack([self.frames, pairs, self.groups])
        rows = rows[pairs[:, 0] != pairs[:, 1]]
        _, first = np.unique(rows, axis=0, return_index=True)
        rows = rows[np.sort(first)]
        return SelfContacts(self.num_frames, rows[:, 0], rows[:, 1:3], rows[:, 3:5])


def _joint_index(joint: int | str) -> int:
    return J[joint] if isinstance(joint, str) else int(joint)


def _tested_group_pairs(hands: Sequence[int], has_faces: Sequence[bool]) -> list[tuple[int, int]]:
    """``(hand, other)`` pairs to test: every hand against every other group with triangles, the
    hand-hand pair once, skipping the hand's own forearm (always touching across the wrist)."""
    out = []
    for n, hand in enumerate(hands):
        skipped = {
            hand,
            CANONICAL22_PARENTS[hand],
            *hands[:n],
        }  # hand-hand: tested from the first hand
        out += [
            (hand, other)
            for other in range(len(has_faces))
            if has_faces[hand] and has_faces[other] and other not in skipped
        ]
    return out


def _group_boxes(
    vertices: np.ndarray, groups: Sequence[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """``(T, G, 3)`` lower and upper corners of each group's axis-aligned box per frame (empty
    groups get an inverted box that overlaps nothing)."""
    T = len(vertices)
    lo = np.full((T, len(groups), 3), np.inf)
    hi = np.full((T, len(groups), 3), -np.inf)
    for g, idx in enumerate(groups):
        if len(idx):
            part = vertices[:, idx]
            lo[:, g], hi[:, g] = part.min(axis=1), part.max(axis=1)
    return lo, hi


def _bvh(vertices: np.ndarray, faces: np.ndarray):
    """A python-fcl collision object: a bounding volume hierarchy (``BVHModel``, OBBRSS) of the
    triangles ``faces (n, 3)`` over ``vertices (N, 3)``."""
    used, local = np.unique(faces, return_inverse=True)  # only the vertices the triangles use
    model = fcl.BVHModel()
    model.beginModel(len(used), len(faces))
    model.addSubModel(vertices[used], local.reshape(-1, 3))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


def _longest_edge(vertices: np.ndarray, faces: np.ndarray) -> float:
    tri = vertices[faces]
    return float(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1).max())


def _meshes_within(
    verts_a: np.ndarray,
    faces_a: np.ndarray,
    verts_b: np.ndarray,
    faces_b: np.ndarray,
    margin: float,
    nearest_b_of_a: np.ndarray,
) -> bool:
    """Whether two triangle meshes intersect or come closer than ``margin`` (metres).

    Two vertices closer than ``margin`` settle it at once. Otherwise, broad phase: a point of a
    triangle is at most the triangle's longest edge away from each of its corners, so two
    triangles within ``margin`` of each other have corners within ``margin + e_a + e_b`` (``e`` =
    the longest edge of each mesh); only the triangles with such a corner are kept. Narrow phase:
    fcl bounding volume hierarchies of the kept triangles, a collision test and, when they do not
    collide, a distance query.

    Args:
        verts_a, verts_b: ``(Na, 3)``, ``(Nb, 3)`` vertices.
        faces_a, faces_b: ``(Fa, 3)``, ``(Fb, 3)`` triangles indexing them.
        margin: proximity margin (metres).
        nearest_b_of_a: ``(Na,)`` distance of each vertex of ``a`` to its nearest vertex of ``b``.
    """
    if nearest_b_of_a.min() <= margin:
        return True  # two vertices, points of both surfaces, are already that close
    reach = margin + _longest_edge(verts_a, faces_a) + _longest_edge(verts_b, faces_b)
    near_a = nearest_b_of_a <= reach
    near_b = (
        np.isfinite(cKDTree(verts_a[near_a]).query(verts_b, distance_upper_bound=reach)[0])
        if near_a.any()
        else np.zeros(len(verts_b), bool)
    )
    faces_a, faces_b = faces_a[near_a[faces_a].any(axis=1)], faces_b[near_b[faces_b].any(axis=1)]
    if len(faces_a) == 0 or len(faces_b) == 0:
        return False
    a, b = _bvh(verts_a, faces_a), _bvh(verts_b, faces_b)
    if fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()):
        return True
    return margin > 0 and fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult()) <= margin


def _velocity_similarity(vel_a: np.ndarray, vel_b: np.ndarray, still_step: float) -> float:
    """Mean cosine similarity of paired velocities ``(n, 3)``. A pair in which both vertices move
    less than ``still_step`` per frame counts as moving together (similarity 1): resting contact."""
    na, nb = np.linalg.norm(vel_a, axis=1), np.linalg.norm(vel_b, axis=1)
    cos = (vel_a * vel_b).sum(axis=1) / np.maximum(na * nb, 1e-30)
    cos = np.where((na < still_step) & (nb < still_step), 1.0, cos)
    return float(cos.mean())


def detect_self_contacts(
    vertices: np.ndarray,
    faces: np.ndarray,
    weights: np.ndarray,
    character_height: float,
    fps: float = REFERENCE_FPS,
    hands: Sequence[int | str] = ("LeftHand", "RightHand"),
    cosine: float = 0.9,
    distance_cm: float = 0.2,
    reference_height_cm: float = 138.0,
    top_k: int = 3,
    margin_cm: float = 1.0,
    still_speed_cm: float = 1.0,
    threshold: float = 0.5,
) -> SelfContacts:
    """Hand self-contacts in a skinned source motion (Villegas et al. 2021, Sec. 3.4).

    1. Vertex groups: per joint the vertices with weight ``>= threshold`` and the triangles among
       them (:func:`vertex_groups`, :func:`group_faces`).
    2. Per frame, each hand group is tested against every other group with triangles (the other
       hand included, once); the hand's own forearm is skipped, it always touches the hand across
       the wrist. A pair of groups is a *candidate* when their triangle meshes intersect or come
       within ``margin_cm`` of each other: axis-aligned boxes first, then python-fcl bounding
       volume hierarchies (``BVHModel``) for a collision test and, failing that, a distance
       query. The margin (1 cm at 138 cm) is our addition: the synthetic clips' hands are solved
       to *touch* a surface, not to sink into it, and on the performer's mesh they stop 0.03-0.9
       cm short of it (a few clips more); a real mocap clip rarely intersects exactly either.
    3. A candidate is a contact if the mean cosine similarity of the global per-vertex velocities
       (backward differences; frame 0 uses frame 1) over its ``top_k`` closest vertex pairs is
       ``> cosine``, or if its nearest vertices are closer than ``distance_cm``. Two vertices that
       both move slower than ``still_speed_cm`` per second count as moving together (resting
       contact: the direction of a near-zero velocity is noise).
    4. Each contact yields its ``top_k`` closest vertex pairs (KD-tree: each hand vertex paired
       with its nearest vertex in the other group; ties go to the lower hand vertex index).

    Every length is given at ``reference_height_cm`` (the paper's shortest character, 138 cm) and
    multiplied by ``character_height / reference_height``.

    Cost: the velocity and distance rules are checked first (one KD-tree query per candidate), and
    a BVH is built only for a pair that passes them and whose vertices are not already within the
    margin, from the triangles that can reach the other group. 300 frames of a 3k-vertex
    synthetic character take 0.1-2 s on one core (most for a boxing guard, where both fists
    hover at the chin), mannequin-x (24k vertices) with hands on the hips about 2.5 s.

    Args:
        vertices: ``(T, V, 3)`` the skinned source motion (metres), ``T >= 2``.
        faces: ``(F, 3)`` int triangles.
        weights: ``(V, 22)`` skinning weights (canonical joint order).
        character_height: standing height in metres; the library's callers pass
            :func:`~retarget_lib.core.measures.mesh_standing_height` of the rest mesh.
        fps: frame rate (for ``still_speed_cm``).
        hands: the hand joints, as canonical names or indices.
        cosine: velocity cosine-similarity threshold.
        distance_cm: nearest-vertex distance threshold (cm at the reference height).
        reference_height_cm: the height the lengths are given at.
        top_k: vertex pairs kept per contact.
        margin_cm: proximity margin of the intersection test (cm at the reference height).
        still_speed_cm: speed below which a vertex counts as at rest (cm/s at the reference height).
        threshold: vertex-group weight threshold.

    Returns:
        :class:`SelfContacts`, constraints sorted by frame; in each row ``i`` is on the hand.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    weights = np.asarray(weights, dtype=np.float64)
    if vertices.ndim != 3 or vertices.shape[2] != 3 or len(vertices) < 2:
        raise ValueError(f"vertices must be (T >= 2, V, 3), got {vertices.shape}")
    if weights.shape != (vertices.shape[1], len(CANONICAL22)):
        raise ValueError(f"weights must be ({vertices.shape[1]}, 22), got {weights.shape}")
    if character_height <= 0 or fps <= 0 or top_k < 1:
        raise ValueError("character_height, fps and top_k must be positive")
    scale = character_height / (reference_height_cm / 100.0)
    margin, near = margin_cm / 100.0 * scale, distance_cm / 100.0 * scale
    still_step = still_speed_cm / 100.0 * scale / fps
    hand_ids = [_joint_index(h) for h in hands]

    groups = vertex_groups(weights, threshold)
    local_faces = []  # per group, its triangles indexing the group's own vertex list
    for idx, face_ids in zip(groups, group_faces(faces, groups, len(weights)), strict=False):
        local = np.full(len(weights), -1, dtype=np.int64)
        local[idx] = np.arange(len(idx))
        local_faces.append(local[faces[face_ids]])
    tested = _tested_group_pairs(hand_ids, [len(f) > 0 for f in local_faces])
    lo, hi = _group_boxes(vertices, groups)

    candidates = []  # (frame, hand, other)
    for hand, other in tested:
        close = (
            (lo[:, hand] - margin <= hi[:, other]) & (lo[:, other] - margin <= hi[:, hand])
        ).all(axis=1)
        candidates += [(int(f), hand, other) for f in np.flatnonzero(close)]
    candidates.sort()

    rows = []
    for f, hand, other in candidates:
        pa, pb = vertices[f, groups[hand]], vertices[f, groups[other]]
        dist, nearest = cKDTree(pb).query(
            pa
        )  # each hand vertex's nearest vertex of the other group
        ia = np.lexsort((np.arange(len(pa)), dist))[:top_k]  # the top_k closest pairs
        i, j = groups[hand][ia], groups[other][nearest[ia]]
        prev, cur = (f - 1, f) if f > 0 else (0, 1)
        similarity = _velocity_similarity(
            vertices[cur, i] - vertices[prev, i], vertices[cur, j] - vertices[prev, j], still_step
        )
        # the cheap contact criteria first, the BVH test only for the pairs that pass them
        if (similarity > cosine or dist[ia[0]] < near) and _meshes_within(
            pa, local_faces[hand], pb, local_faces[other], margin, dist
        ):
            rows += [(f, a, b, hand, other) for a, b in zip(i, j, strict=False)]
    rows = np.asarray(rows, dtype=np.int64).reshape(-1, 5)
    return SelfContacts(len(vertices), rows[:, 0], rows[:, 1:3], rows[:, 3:5])


# ----------------------------------------------------------------------------- correspondence
def _canonical_rest_vertices(character) -> tuple[np.ndarray, np.ndarray]:
    """The character's mesh and joints re-posed into its retarget pose
    (:func:`~retarget_lib.core.retarget_pose.retarget_pose`): ``(V, 3)``, ``(22, 3)``."""
    skeleton = character.skeleton
    pose = retarget_pose(skeleton, character.rest_vertices, character.weights)
    rotations = pose_local_rotations(torch.from_numpy(pose)).numpy()
    root = skeleton.offsets[0]
    joints = forward_kinematics(rotations[None], skeleton.offsets, skeleton.parents, root[None])[0][
        0
    ]
    return character.skinned(rotations, root), np.asarray(joints)


def correspondence_features(
    character, offset_weight: float = 1.0, canonical_pose: bool = True
) -> np.ndarray:
    """Per-vertex features for mesh correspondence (Villegas et al. 2021, Appendix F).

    ``[w_v (22), offset_weight * (x_j - v) / h]``: the vertex's skinning weights and the offset
    from the vertex to the rest position of its *dominant* joint ``j = argmax w_v`` (the joint
    that moves it -- the paper's "parent joint" of a vertex; the weight rows already say which
    joints a vertex blends between, the offset says where it sits on that joint's body part),
    divided by the character's NKN/TDCN height ``h`` so that tall and short bodies compare.

    The paper's Mixamo characters all share the T-pose. Ours do not (A-pose arms, bent knees,
    curved spines), and a world-space offset turns with the bone, so with ``canonical_pose``
    (default) both are measured with the mesh re-posed into its retarget pose
    (:func:`~retarget_lib.core.retarget_pose.retarget_pose`: the canonical T-pose, each
    character's own shape kept) by linear blend skinning.

    Args:
        character: a :class:`~retarget_lib.core.character.Character` (``rest_vertices (V, 3)``,
            ``weights (V, 22)``, ``skeleton``, ``height``).
        offset_weight: factor on the offset part (0 = skinning weights alone, Fig. 7 left).
        canonical_pose: measure offsets in the canonical T-pose instead of the character's rest
            pose.

    Returns:
        ``(V, 25)`` float64.
    """
    weights = np.asarray(character.weights, dtype=np.float64)
    if canonical_pose:
        vertices, joints = _canonical_rest_vertices(character)
    else:
        vertices, joints = character.rest_vertices, character.rest_joint_positions()
    offsets = joints[weights.argmax(axis=1)] - vertices
    return np.hstack([weights, offset_weight * offsets / character.height])


def vertex_correspondence(
    source, target, offset_weight: float = 1.0, canonical_pose: bool = True
) -> np.ndarray:
    """For each source vertex, the target vertex with the nearest feature vector (Appendix F:
    :func:`correspondence_features`, KD-tree nearest neighbour, Euclidean).

    Args:
        source, target: :class:`~retarget_lib.core.character.Character` objects.
        offset_weight, canonical_pose: see :func:`correspondence_features`.

    Returns:
        ``(V_source,)`` int64 target vertex indices.
    """
    src = correspondence_features(source, offset_weight, canonical_pose)
    tgt = correspondence_features(target, offset_weight, canonical_pose)
    return cKDTree(tgt).query(src)[1].astype(np.int64)


def transfer_contacts(
    contacts: SelfContacts, source, target, offset_weight: float = 1.0
) -> SelfContacts:
    """Source self-contact constraints expressed on the target mesh (Sec. 3.4): vertices ``(vA_i,
    vA_j)`` in contact become ``(vB_i, vB_j)`` through :func:`vertex_correspondence`."""
    return contacts.remap(vertex_correspondence(source, target, offset_weight))


# ----------------------------------------------------------------------------- evaluation
def authored_contact_frames(
    hand_contacts: Iterable, num_frames: int, hand: str | None = None
) -> np.ndarray:
    """``(T,)`` bool: frames inside any authored hand-contact interval ``[start, stop)`` (the
    synthetic clips' :class:`~retarget_lib.data.synthetic.authoring.HandContact` list), optionally
    only those of one ``hand`` (``"LeftHand"`` / ``"RightHand"``)."""
    mask = np.zeros(num_frames, dtype=bool)
    for c in hand_contacts:
        if hand is None or c.hand == hand:
            mask[c.start : c.stop] = True
    return mask


def frame_precision_recall(detected: np.ndarray, expected: np.ndarray) -> tuple[float, float]:
    """Frame-level precision and recall of a detected contact track against the expected one.

    Args:
        detected, expected: ``(T,)`` bool.

    Returns:
        ``(precision, recall)``; ``nan`` where the denominator is 0.
    """
    detected, expected = np.asarray(detected, dtype=bool), np.asarray(expected, dtype=bool)
    if detected.shape != expected.shape:
        raise ValueError(f"shapes differ: {detected.shape} vs {expected.shape}")
    hits = float((detected & expected).sum())
    precision = hits / detected.sum() if detected.any() else float("nan")
    recall = hits / expected.sum() if expected.any() else float("nan")
    return precision, recall
