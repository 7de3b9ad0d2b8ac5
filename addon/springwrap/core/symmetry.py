"""Each layout vertex's twin across a symmetry plane (for symmetric anchors; numpy only, no ``bpy``).

The plane is the one the mirror uses (``mirroring.plane_from_matrix``: the layout's local X, Y or Z
plane, or an empty's, carried to world space). A vertex's **twin** is found:

1. **By topology**: a mirror symmetry of the mesh is a map of faces onto faces that reverses their
   winding. It is grown face by face from a *seed*: an edge lying on the plane (both ends within
   :data:`POSITION_TOLERANCE` of their mean edge length of it, a face on each side: each face maps to
   the other, the edge's ends to themselves), or an edge crossing the plane (its ends about as far on
   either side: they swap, each of its faces maps to itself); nearest the plane first. Across every edge of a mapped
   face the neighbour's image is the face across the image edge, so the whole edge-connected piece
   follows from the seed without looking at positions. The map must be consistent (a vertex gets one
   twin, twins are mutual, faces have the same size) and must send at least
   :data:`MIN_SIDE_AGREEMENT` of the piece's vertices to the other side of the plane (or keep them on
   it); else the next seed is tried (:data:`MAX_SEEDS_PER_PIECE` per piece) and then the piece is left
   to the position rule. Vertex order does not matter, and neither does how far a wrap has moved the
   vertices off exact symmetry.
2. **By position**, failing that (asymmetric topology, loose curves): a vertex within
   :data:`ON_PLANE_FRACTION` of its mean edge length of the plane is its own twin; otherwise the layout
   vertex nearest to its reflection, when it lies within :data:`POSITION_TOLERANCE` times that length.
3. **None** otherwise.

A vertex that is its own twin lies on the plane (its anchor has no separate twin).
"""

from collections import deque
from typing import NamedTuple

import numpy as np

from .errors import LayoutError
from .mirroring import DEFAULT_WELD_FRACTION, Plane, reflect, signed_distances, vertex_edge_lengths

ON_PLANE_FRACTION = DEFAULT_WELD_FRACTION
"""A vertex this close to the plane, as a fraction of the mean length of its edges, is on it (the mirror's seam)."""
POSITION_TOLERANCE = 0.25
"""By position, a twin is the vertex nearest to the reflection within this fraction of the mean edge length."""
MIN_SIDE_AGREEMENT = 0.9
"""A topological map is kept when at least this fraction of its vertices go to the other side (or stay on the plane)."""
MAX_SEEDS_PER_PIECE = 8
"""Seeds tried per edge-connected piece before it is left to the position rule."""

NO_TWIN = 0
BY_TOPOLOGY = 1
BY_POSITION = 2
HOW = ("no twin", "by topology", "by position")
"""What :attr:`Twins.how` values mean, for reports."""


class Twins(NamedTuple):
    """Every layout vertex's twin across the plane."""

    twins: np.ndarray  # (N,) int64 the twin vertex, the vertex itself on the plane, -1 when there is none
    how: np.ndarray  # (N,) int8 NO_TWIN, BY_TOPOLOGY or BY_POSITION
    distances: np.ndarray  # (N,) float64 signed distance from the plane (world units)
    on_plane: np.ndarray  # (N,) bool within ON_PLANE_FRACTION of the mean edge length of the plane


def vertex_twins(
    world_positions: np.ndarray,
    face_corners: np.ndarray,
    face_sizes: np.ndarray,
    edges: np.ndarray,
    plane: Plane,
    use_topology: bool = True,
) -> Twins:
    """Every vertex's twin across ``plane``: by topology where the mesh's faces allow, else by position.

    ``face_corners`` / ``face_sizes``: the faces' vertices one face after another (consistent winding);
    ``edges``: every edge (for the edge lengths). Raises :class:`LayoutError` for non-finite positions.
    """
    positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(positions).all():
        raise LayoutError("The layout has NaN or infinite coordinates: its twins cannot be found")
    count = positions.shape[0]
    distances = signed_distances(positions, plane)
    lengths = vertex_edge_lengths(positions, edges)
    if count and not np.any(lengths > 0.0):
        lengths = np.full(count, _diagonal(positions) * 1e-3)
    on_plane = np.abs(distances) <= ON_PLANE_FRACTION * lengths
    twins = np.full(count, -1, dtype=np.int64)
    how = np.zeros(count, dtype=np.int8)
    if use_topology:
        topological = topological_twins(face_corners, face_sizes, count, distances, lengths)
        found = topological >= 0
        twins[found] = topological[found]
        how[found] = BY_TOPOLOGY
    missing = np.flatnonzero(twins < 0)
    if missing.size:
        by_position = position_twins(positions, missing, distances, lengths, on_plane, plane)
        found = by_position >= 0
        twins[missing[found]] = by_position[found]
        how[missing[found]] = BY_POSITION
    return Twins(twins, how, distances, on_plane)


def _diagonal(points: np.ndarray) -> float:
    if not points.shape[0]:
        return 0.0
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


# ---------------------------------------------------------------- by position


def position_twins(
    positions: np.ndarray,
    queries: np.ndarray,
    distances: np.ndarray,
    lengths: np.ndarray,
    on_plane: np.ndarray,
    plane: Plane,
) -> np.ndarray:
    """(Q,) int64 the twin of each vertex in ``queries`` by position (itself on the plane), -1 for none."""
    queries = np.asarray(queries, dtype=np.int64).reshape(-1)
    result = np.full(queries.size, -1, dtype=np.int64)
    result[on_plane[queries]] = queries[on_plane[queries]]
    off = np.flatnonzero(~on_plane[queries])
    if off.size:
        vertices = queries[off]
        radii = POSITION_TOLERANCE * lengths[vertices]
        nearest = nearest_within(positions, reflect(positions[vertices], plane), radii)
        # A twin lies on the other side (or on the plane), never the vertex itself.
        valid = (nearest >= 0) & (nearest != vertices)
        valid[valid] &= (distances[nearest[valid]] * distances[vertices[valid]] <= 0.0) | on_plane[nearest[valid]]
        result[off[valid]] = nearest[valid]
    return result


def nearest_within(points: np.ndarray, queries: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(Q,) int64 the index of the point nearest to each query within its radius, -1 when none is.

    A grid of cells as large as the largest radius (searched in sorted order, 27 cells per query),
    so it is linear in the number of points and queries.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    queries = np.asarray(queries, dtype=np.float64).reshape(-1, 3)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    result = np.full(queries.shape[0], -1, dtype=np.int64)
    if not points.shape[0] or not queries.shape[0]:
        return result
    everything = np.concatenate([points, queries])
    low = everything.min(axis=0)
    cell = max(float(radii.max()), _diagonal(everything) * 1e-5, 1e-12)
    point_cells = np.floor((points - low) / cell).astype(np.int64) + 1
    query_cells = np.floor((queries - low) / cell).astype(np.int64) + 1
    extent = int(max(point_cells.max(), query_cells.max())) + 2

    def key(cells):
        return (cells[:, 0] * extent + cells[:, 1]) * extent + cells[:, 2]

    point_keys = key(point_cells)
    order = np.argsort(point_keys, kind="stable")
    sorted_keys = point_keys[order]
    best = np.full(queries.shape[0], np.inf)
    steps = (-1, 0, 1)
    for offset in [(dx, dy, dz) for dx in steps for dy in steps for dz in steps]:
        keys = key(query_cells + np.asarray(offset))
        starts = np.searchsorted(sorted_keys, keys, side="left")
        counts = np.searchsorted(sorted_keys, keys, side="right") - starts
        total = int(counts.sum())
        if not total:
            continue
        owner = np.repeat(np.arange(queries.shape[0]), counts)
        within = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        candidates = order[np.repeat(starts, counts) + within]
        lengths = np.linalg.norm(points[candidates] - queries[owner], axis=1)
        by_distance = np.lexsort((lengths, owner))
        first = by_distance[np.unique(owner[by_distance], return_index=True)[1]]
        closer = lengths[first] < best[owner[first]]
        best[owner[first][closer]] = lengths[first][closer]
        result[owner[first][closer]] = candidates[first][closer]
    result[best > radii] = -1
    return result


# ---------------------------------------------------------------- by topology


def topological_twins(
    face_corners: np.ndarray,
    face_sizes: np.ndarray,
    vertex_count: int,
    distances: np.ndarray,
    lengths: np.ndarray,
) -> np.ndarray:
    """(N,) int64 each vertex's twin under a winding-reversing symmetry of the faces, -1 where none was found.

    Grown from seeds on the plane (module docstring); ``distances`` and ``lengths`` (per vertex) only
    choose the seeds and check the side agreement.
    """
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    twins = np.full(vertex_count, -1, dtype=np.int64)
    if not sizes.size:
        return twins
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    faces = [corners[start : start + size].tolist() for start, size in zip(starts.tolist(), sizes.tolist())]
    half_edges: dict[tuple[int, int], tuple[int, int]] = {}
    broken = set()
    for face_index, face in enumerate(faces):
        for position, vertex in enumerate(face):
            directed = (vertex, face[(position + 1) % len(face)])
            if directed in half_edges:
                broken.add(directed)  # non-manifold or inconsistent winding: not walked across
            half_edges[directed] = (face_index, position)
    for directed in broken:
        del half_edges[directed]
    pieces = _pieces(faces, half_edges)
    attempts = np.zeros(int(pieces.max()) + 1, dtype=np.int64)
    done = np.zeros(attempts.size, dtype=bool)
    for seed in _seeds(half_edges, distances, lengths):
        piece = pieces[seed[0]]
        if done[piece] or attempts[piece] >= MAX_SEEDS_PER_PIECE:
            continue
        attempts[piece] += 1
        mapping = _grow(faces, half_edges, seed)
        if mapping is None or not _sides_agree(mapping, distances, lengths):
            continue
        done[piece] = True
        for vertex, twin in mapping.items():
            twins[vertex] = twin
    return twins


def _pieces(faces: list, half_edges: dict) -> np.ndarray:
    """(F,) the edge-connected piece of each face (across the half-edges that can be walked)."""
    labels = np.full(len(faces), -1, dtype=np.int64)
    label = 0
    for start in range(len(faces)):
        if labels[start] >= 0:
            continue
        labels[start] = label
        queue = deque([start])
        while queue:
            face = faces[queue.popleft()]
            for position, vertex in enumerate(face):
                across = half_edges.get((face[(position + 1) % len(face)], vertex))
                if across is not None and labels[across[0]] < 0:
                    labels[across[0]] = label
                    queue.append(across[0])
        label += 1
    return labels


def _seeds(half_edges: dict, distances: np.ndarray, lengths: np.ndarray):
    """``(face, shift)`` seeds, best first: the face's image is ``(image face, shift)`` (see :func:`_grow`).

    An edge on the plane maps onto itself with its ends fixed (its face goes to the face across); an
    edge crossing the plane maps onto itself with its ends swapped (its face goes to itself).
    """
    scored = []
    reach = POSITION_TOLERANCE  # a wrapped layout's midline is only near the plane
    for (a, b), (face, position) in half_edges.items():
        scale = max(lengths[a], lengths[b])
        if not scale > 0.0:
            continue
        da, db = distances[a], distances[b]
        if abs(da) <= reach * lengths[a] and abs(db) <= reach * lengths[b]:
            across = half_edges.get((b, a))
            if across is not None and a < b:
                scored.append(((abs(da) + abs(db)) / scale, face, across[0], across[1] + 1 + position))
        elif da * db < 0.0 and abs(da + db) <= reach * scale and abs(da - db) >= 0.5 * scale:
            # across the plane (not along it), its ends about as far on either side
            scored.append((abs(da + db) / scale, face, face, 2 * position + 1))
    scored.sort(key=lambda entry: entry[0])
    return [(face, image, shift) for _score, face, image, shift in scored]


def _grow(faces: list, half_edges: dict, seed) -> dict | None:
    """The vertex map ``{vertex: twin}`` grown over the seed's piece, or None when it is inconsistent.

    A face ``f`` maps to ``(g, s)``: corner ``t`` of ``f`` goes to corner ``(s - t) mod k`` of ``g``
    (the winding reversed). Then ``g`` maps back to ``(f, s)``, and the face across ``f``'s edge
    ``(f[t], f[t+1])`` maps to the face across ``g``'s edge ``(g[s-t-1], g[s-t])``.
    """
    start, image, shift = seed
    face_map: dict[int, tuple[int, int]] = {}
    vertex_map: dict[int, int] = {}
    queue = deque()

    def assign(face, target_face, target_shift) -> bool:
        known = face_map.get(face)
        if known is not None:
            size = len(faces[face])
            return known[0] == target_face and (known[1] - target_shift) % size == 0
        if len(faces[face]) != len(faces[target_face]) or face_map.get(target_face, (face,))[0] != face:
            return False
        face_map[face] = (target_face, target_shift)
        face_map[target_face] = (face, target_shift)
        queue.append(face)
        if target_face != face:
            queue.append(target_face)  # its edges are walked too: a border on one side only is found from either
        return True

    if not assign(start, image, shift):
        return None
    while queue:
        face_index = queue.popleft()
        face = faces[face_index]
        image_index, shift = face_map[face_index]
        image_face = faces[image_index]
        size = len(face)
        for position, vertex in enumerate(face):
            twin = image_face[(shift - position) % size]
            if vertex_map.setdefault(vertex, twin) != twin or vertex_map.setdefault(twin, vertex) != vertex:
                return None
        for position, vertex in enumerate(face):
            following = face[(position + 1) % size]
            across = half_edges.get((following, vertex))
            if across is None:
                continue
            image_edge = (image_face[(shift - position) % size], image_face[(shift - position - 1) % size])
            image_across = half_edges.get(image_edge)
            if image_across is None:
                return None  # a border on one side only: not a symmetry
            if not assign(across[0], image_across[0], image_across[1] + 1 + across[1]):
                return None
    return vertex_map


def _sides_agree(mapping: dict, distances: np.ndarray, lengths: np.ndarray) -> bool:
    """Whether enough of the map's vertices go to the other side of the plane (or stay on it)."""
    vertices = np.fromiter(mapping.keys(), dtype=np.int64, count=len(mapping))
    twins = np.fromiter(mapping.values(), dtype=np.int64, count=len(mapping))
    itself = vertices == twins
    agree = np.where(
        itself,
        np.abs(distances[vertices]) <= lengths[vertices],
        distances[vertices] * distances[twins] <= 0.0,
    )
    return bool(agree.mean() >= MIN_SIDE_AGREEMENT)
