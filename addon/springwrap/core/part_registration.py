"""Rigid parts placed by the target's shape: each rigid piece's own skin (the surface held on the target that is
nearer to it than to any other rigid piece), in its rest shape, registered rigidly onto the target (point-to-plane
ICP, started from that skin's motion in the wrap), and the piece moved with it. Numpy and the kernel's target
queries, no ``bpy``.

Why: the wrap matches the target point-to-plane, so its skin may slide along the target instead of moving as the
target did (an opening jaw's chin and lower lip carry only about half of their true motion, ``benchmarks/parts.py``'s
``carried_share``); a part following that skin's motion lags with it, however the skin is weighted (measured on the
expression cases: wider neighbourhoods, robust reweighting, only the skin nearer to the piece than to another:
lower teeth max 0.86 to 1.2 % of the diagonal). The skin's rest shape (a chin, a lip's edge, a brow) is pinned by
the target's shape where its motion is not: registered, the lower teeth land at 0.43 to 0.47 % max. The other
rigid pieces' own skin separates the skins moving apart (upper from lower teeth).

A piece keeps the follower's motion (:func:`core.parts.follow`) when its own skin is not close around it
(:data:`COVER_RATIO`: a tongue behind the teeth owns only skin far under the chin, which deforms), when that skin
is too small a patch to register, or when the registration would move it farther than :data:`MOVE_LIMIT` or leave
its skin farther from the target than it started.
"""

import numpy as np

COVER_RATIO = 1.5
"""A piece registers by its own skin when the median distance from its vertices to that skin is at most this
many times the median distance to any skin the wrap holds (the skin around it is its own, not another part's)."""
PATCH_REACH = 3.0
"""The skin registered: its own skin within this many of the piece's radii (RMS distance to its centre)."""
SOFTEN = 0.5
"""Each skin vertex weighs 1 / (d² + (SOFTEN r)²), d its distance to the piece, r the piece's radius. Measured
(``benchmarks/parts.py``, lower teeth max on face-expression / expression / head-nose): 0.2 gives 0.63 / 0.54 /
0.07, 0.5 gives 0.47 / 0.43 / 0.09, 1.0 gives 0.40 / 0.41 / 0.15 (the nearest skin, the lips, slides most)."""
ITERATIONS = 100
"""Point-to-plane steps of the registration, at most (face-expression's lower teeth: max 0.472 after 100, 0.479 after
400)."""
PINNED_SHARE = 0.01
"""A step leaves out the motions that the target pins less than this share of the best pinned one (the eigenvalues
of the step's system): a turn of a sphere's patch about its centre stays as the wrap's skin put it (a mirrored
ball stays symmetric: ``tests/addon/test_parts.py``)."""
MOVE_LIMIT = 1.0
"""The registration may move a piece's vertices at most this many of its radii from where the follower put them."""
MIN_PATCH = 12
"""The fewest skin vertices a registration uses."""
BLOCK = 1 << 20
"""Point pairs in one block of distances (memory: 24 bytes each)."""


def nearest_distances(points: np.ndarray, others: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` ((P, 3)), the distance to the nearest of ``others`` ((Q, 3), Q > 0) and its index."""
    distances = np.empty(len(points))
    indices = np.empty(len(points), dtype=np.int64)
    rows = max(1, BLOCK // len(others))
    for start in range(0, len(points), rows):
        block = np.linalg.norm(points[start : start + rows, None, :] - others[None, :, :], axis=2)
        indices[start : start + rows] = np.argmin(block, axis=1)
        distances[start : start + rows] = block[np.arange(len(block)), indices[start : start + rows]]
    return distances, indices


def best_rigid(rest: np.ndarray, now: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R (3, 3), t (3,)): the weighted best rotation and translation taking ``rest`` to ``now`` (Kabsch)."""
    weights = weights / weights.sum()
    rest_centre, now_centre = weights @ rest, weights @ now
    cross = (rest - rest_centre).T @ ((now - now_centre) * weights[:, None])
    u, _s, vt = np.linalg.svd(cross)
    turn = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    rotation = vt.T @ turn @ u.T
    return rotation, now_centre - rotation @ rest_centre


def small_rotation(omega: np.ndarray) -> np.ndarray:
    """The rotation by the vector ``omega`` (axis times angle, Rodrigues)."""
    angle = float(np.linalg.norm(omega))
    if angle == 0.0:
        return np.eye(3)
    k = omega / angle
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * skew + (1.0 - np.cos(angle)) * skew @ skew


def surface_distance(target_mesh, points: np.ndarray, weights: np.ndarray) -> float:
    """The weighted RMS distance of ``points`` to the target (``core.target.CentredMesh``)."""
    hits = target_mesh.closest_points(points)
    found = np.asarray(hits.triangles) >= 0
    gaps = np.where(found, np.linalg.norm(points - np.asarray(hits.positions, dtype=np.float64), axis=1), 0.0)
    return float(np.sqrt((weights * found) @ gaps**2 / max((weights * found).sum(), 1e-300)))


def register(target_mesh, rest: np.ndarray, start, weights: np.ndarray):
    """(R, t): the rigid motion of the skin ``rest`` ((S, 3)) onto the target, point-to-plane, from ``start``;
    each step leaves out the motions the target pins weakly (:data:`PINNED_SHARE`: a patch of a sphere turning about its
    centre stays where the wrap's skin put it)."""
    rotation, translation = start
    normals = np.asarray(target_mesh.kernel.face_normals(), dtype=np.float64)
    centre_rest = weights @ rest / weights.sum()
    size = float(np.sqrt(weights @ np.sum((rest - centre_rest) ** 2, axis=1) / weights.sum()))
    if not size > 0.0:
        return start
    for _step in range(ITERATIONS):
        points = rest @ rotation.T + translation
        centre = rotation @ centre_rest + translation
        hits = target_mesh.closest_points(points)
        triangles = np.asarray(hits.triangles)
        used = weights * (triangles >= 0)
        normal = normals[np.maximum(triangles, 0)]
        residual = np.einsum("ij,ij->i", points - np.asarray(hits.positions, dtype=np.float64), normal)
        # d residual / d (turn about the centre times the size, shift): both in lengths.
        jacobian = np.hstack([np.cross((points - centre) / size, normal), normal])
        system = (jacobian * used[:, None]).T @ jacobian
        values, vectors = np.linalg.eigh(system)
        pinned = values > PINNED_SHARE * values.max()
        if not values.max() > 0.0:
            break
        gradient = vectors.T @ (-(jacobian * used[:, None]).T @ residual)
        step = vectors[:, pinned] @ (gradient[pinned] / values[pinned])
        turn = small_rotation(step[:3] / size)
        rotation, translation = turn @ rotation, turn @ (translation - centre) + centre + step[3:]
        if np.linalg.norm(step) < 1e-9 * size:
            break
    return rotation, translation


def _radius(points: np.ndarray) -> float:
    """The RMS distance of ``points`` to their centre."""
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))


def place_pieces(plan, rest: np.ndarray, positions: np.ndarray, held: np.ndarray, target_mesh) -> np.ndarray:
    """``positions`` ((N, 3), the follower's result) with each rigid piece that its own skin covers moved by that
    skin's registration onto the target (see the module). ``rest`` (N, 3): where the follower was bound; ``held``
    (N,) bool: the surface the wrap holds on the target."""
    positions = np.array(positions, dtype=np.float64)
    rigid = plan.parts & ~plan.soft
    skin = np.flatnonzero(np.asarray(held, dtype=bool) & ~plan.parts)
    if not rigid.any() or skin.size < MIN_PATCH:
        return positions
    rigid_vertices = np.flatnonzero(rigid)
    radii = [
        _radius(rest[rigid_vertices[plan.pieces[rigid_vertices] == piece]])
        for piece in np.unique(plan.pieces[rigid_vertices])
    ]
    reach = PATCH_REACH * max(radii)
    low, high = rest[rigid_vertices].min(axis=0) - reach, rest[rigid_vertices].max(axis=0) + reach
    skin = skin[np.all((rest[skin] >= low) & (rest[skin] <= high), axis=1)]  # the skin near the parts only
    if skin.size < MIN_PATCH:
        return positions
    _gap, nearest = nearest_distances(rest[skin], rest[rigid_vertices])
    owner = plan.pieces[rigid_vertices[nearest]]  # each held skin vertex: the rigid piece nearest to it
    for piece in np.unique(plan.pieces[rigid_vertices]):
        members = rigid_vertices[plan.pieces[rigid_vertices] == piece]
        own = skin[owner == piece]
        if own.size < MIN_PATCH:
            continue
        radius = _radius(rest[members])
        to_any, _index = nearest_distances(rest[members], rest[skin])
        to_own, _index = nearest_distances(rest[members], rest[own])
        if not np.median(to_own) <= COVER_RATIO * np.median(to_any) or radius <= 0.0:
            continue
        distance, _index = nearest_distances(rest[own], rest[members])
        near = distance < PATCH_REACH * radius
        if near.sum() < MIN_PATCH:
            continue
        patch, weights = own[near], 1.0 / (distance[near] ** 2 + (SOFTEN * radius) ** 2)
        start = best_rigid(rest[patch], positions[patch], weights)
        motion = register(target_mesh, rest[patch], start, weights)
        placed = rest[members] @ motion[0].T + motion[1]
        if np.linalg.norm(placed - positions[members], axis=1).max() > MOVE_LIMIT * radius:
            continue
        before = surface_distance(target_mesh, rest[patch] @ start[0].T + start[1], weights)
        if not surface_distance(target_mesh, rest[patch] @ motion[0].T + motion[1], weights) <= before:
            continue
        positions[members] = placed
    return positions
