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
SAMPLES = 2048
"""Distances to a piece (its skin's owner, how close its skin is, the skin's weights) are measured to at most this many
of its vertices, spread over its numbering; a registration fits at most this many skin vertices, likewise. A layout
with bigger pieces or patches (a detailed set of teeth on a film character) then costs about what these do: on an
egg of 240,000 vertices with a 21,600-vertex ball inside, every vertex measured took 366 s, sampled
(``tests/core/test_parts_logic.py``'s large case, ``benchmarks/parts.py`` unchanged: its pieces and patches are
smaller)."""


def sampled(indices: np.ndarray, count: int | None = None) -> np.ndarray:
    """At most ``count`` (default :data:`SAMPLES`) of ``indices``, evenly spread over them (all when there are no
    more)."""
    count = SAMPLES if count is None else count
    if len(indices) <= count:
        return indices
    return indices[np.linspace(0, len(indices) - 1, count).round().astype(np.int64)]


def nearest_distances(points: np.ndarray, others: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` ((P, 3)), the distance to the nearest of ``others`` ((Q, 3), Q > 0) and its index.

    Blocks of :data:`BLOCK` pairs, each found by one matrix product (|p - q|² = |p|² + |q|² - 2 p·q: about forty
    times faster than differences in numpy), its nearest distance then measured directly."""
    points = np.asarray(points, dtype=np.float64)
    others = np.asarray(others, dtype=np.float64)
    distances = np.empty(len(points))
    indices = np.empty(len(points), dtype=np.int64)
    rows = max(1, BLOCK // len(others))
    squared = np.einsum("ij,ij->i", others, others)
    for start in range(0, len(points), rows):
        block = points[start : start + rows]
        gaps = squared[None, :] - 2.0 * (block @ others.T)  # + |p|², the same along a row
        nearest = np.argmin(gaps, axis=1)
        indices[start : start + rows] = nearest
        distances[start : start + rows] = np.linalg.norm(block - others[nearest], axis=1)
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


def place_pieces(
    plan, rest: np.ndarray, positions: np.ndarray, held: np.ndarray, target_mesh, placed: list | None = None
) -> np.ndarray:
    """``positions`` ((N, 3), the follower's result) with each rigid piece that its own skin covers moved by that
    skin's registration onto the target (see the module). ``rest`` (N, 3): where the follower was bound; ``held``
    (N,) bool: the surface the wrap holds on the target; ``placed`` (optional): a list the pieces so placed are
    appended to (their ``plan.pieces`` numbers, for the report)."""
    positions = np.array(positions, dtype=np.float64)
    rigid = plan.parts & ~plan.soft
    finite = np.isfinite(positions).all(axis=1) & np.isfinite(rest).all(axis=1)
    skin = np.flatnonzero(np.asarray(held, dtype=bool) & ~plan.parts & finite)  # a lost point pins nothing
    if not rigid.any() or skin.size < MIN_PATCH:
        return positions
    rigid_vertices = np.flatnonzero(rigid)
    numbers = np.unique(plan.pieces[rigid_vertices])
    pieces = [rigid_vertices[plan.pieces[rigid_vertices] == piece] for piece in numbers]
    centres = [rest[members].mean(axis=0) for members in pieces]
    radii = [_radius(rest[members]) for members in pieces]
    # Each piece's bounding ball, and a sample of its vertices to measure distances to.
    extents = [float(np.linalg.norm(rest[members] - centre, axis=1).max()) for members, centre in zip(pieces, centres)]
    samples = [sampled(members) for members in pieces]
    for index, members in enumerate(pieces):
        radius = radii[index]
        if not radius > 0.0:
            continue
        reach = extents[index] + PATCH_REACH * radius
        near = skin[np.linalg.norm(rest[skin] - centres[index], axis=1) < reach]  # the skin its patch can use
        if near.size < MIN_PATCH:
            continue
        # Its own skin: nearer to it than to any other rigid piece (only pieces whose balls come that close count).
        to_piece, _index = nearest_distances(rest[near], rest[samples[index]])
        own_mask = np.ones(len(near), dtype=bool)
        for other, centre in enumerate(centres):
            if other != index and np.linalg.norm(centre - centres[index]) < reach + extents[other]:
                to_other, _index = nearest_distances(rest[near], rest[samples[other]])
                own_mask &= to_piece <= to_other
        own = near[own_mask]
        if own.size < MIN_PATCH:
            continue
        # Covered by its own skin (not another part's): a sample of its vertices, to all near skin and to its own.
        probe = rest[samples[index]]
        to_any, _index = nearest_distances(probe, rest[near])
        to_own, _index = nearest_distances(probe, rest[own])
        if not np.median(to_own) <= COVER_RATIO * np.median(to_any):
            continue
        distance = to_piece[own_mask]
        close = distance < PATCH_REACH * radius
        if close.sum() < MIN_PATCH:
            continue
        patch, weights = own[close], 1.0 / (distance[close] ** 2 + (SOFTEN * radius) ** 2)
        fitted = sampled(np.arange(len(patch)))
        patch, weights = patch[fitted], weights[fitted]
        start = best_rigid(rest[patch], positions[patch], weights)
        motion = register(target_mesh, rest[patch], start, weights)
        moved = rest[members] @ motion[0].T + motion[1]
        if np.linalg.norm(moved - positions[members], axis=1).max() > MOVE_LIMIT * radius:
            continue
        before = surface_distance(target_mesh, rest[patch] @ start[0].T + start[1], weights)
        if not surface_distance(target_mesh, rest[patch] @ motion[0].T + motion[1], weights) <= before:
            continue
        positions[members] = moved
        if placed is not None:
            placed.append(int(numbers[index]))
    return positions
