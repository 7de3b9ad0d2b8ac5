"""Paths along mesh edges, on arrays (numpy and heapq, no ``bpy``): a chain ordered from unordered edges, the
shortest path between two vertices (Dijkstra over edge lengths), a path that follows a layout chain's
course segment by segment, the vertices nearest to points, and arc lengths along a polyline. The curve constraints use them.
"""

import heapq
from typing import NamedTuple

import numpy as np

from .errors import LayoutError


def chain_from_edges(edges) -> np.ndarray:
    """The vertices of ``edges`` ((E, 2) vertex pairs) in order along the one open chain they form.

    Raises :class:`LayoutError` with the reason when there are no edges, when a vertex has more
    than two of them (branching), when they close a loop, or when they form several pieces.
    The chain starts at its end vertex with the lower index.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if not edges.shape[0]:
        raise LayoutError("No edge is selected: select the layout edges of one chain")
    if np.any(edges[:, 0] == edges[:, 1]):
        raise LayoutError("An edge joins a vertex to itself")
    keys = np.unique(np.sort(edges, axis=1), axis=0)
    vertices, degrees = np.unique(keys, return_counts=True)
    branching = vertices[degrees > 2]
    if branching.size:
        raise LayoutError(
            f"The selected edges branch at vertex {int(branching[0])} ({int(degrees[degrees > 2][0])} edges meet "
            "there): select one simple chain"
        )
    ends = vertices[degrees == 1]
    if ends.size == 0:
        raise LayoutError("The selected edges form a closed loop: select an open chain (it needs two ends)")
    neighbours: dict[int, list[int]] = {}
    for first, second in keys.tolist():
        neighbours.setdefault(first, []).append(second)
        neighbours.setdefault(second, []).append(first)
    chain = [int(ends.min())]
    previous = -1
    while True:
        following = [vertex for vertex in neighbours[chain[-1]] if vertex != previous]
        if not following:
            break
        previous = chain[-1]
        chain.append(following[0])
    if len(chain) != vertices.size:
        raise LayoutError("The selected edges form more than one piece: select one connected chain")
    return np.asarray(chain, dtype=np.int64)


class EdgeGraph(NamedTuple):
    """A target's edges as adjacency lists (CSR, both directions) with their lengths, and which
    connected piece each vertex is in: built once, searched many times."""

    offsets: list  # (V + 1) start of each vertex's neighbours in ``neighbours``
    neighbours: list  # the neighbouring vertices, grouped by vertex
    lengths: list  # the length of the edge to each of them
    pieces: np.ndarray  # (V,) int64 label of each vertex's connected piece (equal labels: joined by edges)


def edge_graph(positions, edges) -> EdgeGraph:
    """The :class:`EdgeGraph` of ``edges`` ((E, 2) vertex pairs) over ``positions`` ((V, 3))."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    vertex_count = positions.shape[0]
    sources = np.concatenate([edges[:, 0], edges[:, 1]])
    destinations = np.concatenate([edges[:, 1], edges[:, 0]])
    lengths = np.linalg.norm(positions[sources] - positions[destinations], axis=1)
    order = np.argsort(sources, kind="stable")
    sources, destinations, lengths = sources[order], destinations[order], lengths[order]
    offsets = np.searchsorted(sources, np.arange(vertex_count + 1)).tolist()
    return EdgeGraph(offsets, destinations.tolist(), lengths.tolist(), _pieces(vertex_count, edges))


def _pieces(vertex_count: int, edges: np.ndarray) -> np.ndarray:
    """(V,) the lowest vertex index of each vertex's connected piece (union-find by hooking and
    pointer jumping, vectorised: a few passes over the edges)."""
    parent = np.arange(vertex_count, dtype=np.int64)
    if not edges.shape[0]:
        return parent
    while True:
        first, second = parent[edges[:, 0]], parent[edges[:, 1]]
        joined = first != second
        if not joined.any():
            return parent
        low, high = np.minimum(first[joined], second[joined]), np.maximum(first[joined], second[joined])
        np.minimum.at(parent, high, low)
        while True:
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped


def _check_vertex(vertex: int, vertex_count: int) -> int:
    vertex = int(vertex)
    if not 0 <= vertex < vertex_count:
        raise LayoutError(f"Target vertex {vertex} is out of range: the target has {vertex_count} vertices")
    return vertex


def _unreachable(start: int, end: int) -> LayoutError:
    return LayoutError(f"No chain of target edges joins target vertices {start} and {end}")


def _dijkstra(graph: EdgeGraph, start: int, end: int) -> list:
    """Vertices of the shortest edge path from ``start`` to ``end`` (joined: same piece)."""
    if start == end:
        return [start]
    offsets, neighbours, lengths = graph.offsets, graph.neighbours, graph.lengths
    distances = {start: 0.0}
    previous = {start: -1}
    done = set()
    heap = [(0.0, start)]
    while heap:
        distance, vertex = heapq.heappop(heap)
        if vertex in done:
            continue
        if vertex == end:
            break
        done.add(vertex)
        for slot in range(offsets[vertex], offsets[vertex + 1]):
            neighbour = neighbours[slot]
            candidate = distance + lengths[slot]
            if candidate < distances.get(neighbour, np.inf):
                distances[neighbour] = candidate
                previous[neighbour] = vertex
                heapq.heappush(heap, (candidate, neighbour))
    if end not in previous:
        raise _unreachable(start, end)
    path = [end]
    while previous[path[-1]] != -1:
        path.append(previous[path[-1]])
    return path[::-1]


def shortest_path(positions, edges, start: int, end: int) -> np.ndarray:
    """Vertices of the shortest edge path from ``start`` to ``end`` (Dijkstra over edge lengths).

    ``positions`` (V, 3), ``edges`` (E, 2). Raises :class:`LayoutError` when ``end`` cannot be
    reached. Ties are broken by vertex index, so the result is deterministic.
    """
    graph = edge_graph(positions, edges)
    vertex_count = len(graph.offsets) - 1
    start, end = _check_vertex(start, vertex_count), _check_vertex(end, vertex_count)
    if graph.pieces[start] != graph.pieces[end]:
        raise _unreachable(start, end)
    return np.asarray(_dijkstra(graph, start, end), dtype=np.int64)


def chain_course(chain_positions, start_point, end_point) -> np.ndarray:
    """(C, 3) the chain moved so that its ends sit on ``start_point`` and ``end_point``: each vertex
    by the blend of the two ends' offsets at its fraction of the chain's arc length.

    A template chain beside the target keeps its course, and its ends meet their anchors.
    """
    chain_positions = np.asarray(chain_positions, dtype=np.float64).reshape(-1, 3)
    fractions = length_fractions(chain_positions)[:, None]
    start_offset = np.asarray(start_point, dtype=np.float64).reshape(1, 3) - chain_positions[:1]
    end_offset = np.asarray(end_point, dtype=np.float64).reshape(1, 3) - chain_positions[-1:]
    return chain_positions + (1.0 - fractions) * start_offset + fractions * end_offset


def following_path(positions, graph: EdgeGraph, course, start: int, end: int) -> np.ndarray:
    """Vertices of a target edge path from ``start`` to ``end`` that follows ``course`` ((C, 3),
    a layout chain from start to end, see :func:`chain_course`).

    The path goes through the target vertex nearest to each of the course's inner points in turn
    (only vertices joined to ``start`` by edges count), by the shortest path from one to the next,
    with any loop cut out (a vertex reached again continues from its first visit). The globally
    shortest path between the ends would ignore the course: round the back of a neck, or the
    short way round a ring the chain goes the long way round.

    Raises :class:`LayoutError` when no edge path joins ``start`` and ``end``.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    course = np.asarray(course, dtype=np.float64).reshape(-1, 3)
    vertex_count = positions.shape[0]
    start, end = _check_vertex(start, vertex_count), _check_vertex(end, vertex_count)
    if graph.pieces[start] != graph.pieces[end]:
        raise _unreachable(start, end)
    joined = np.flatnonzero(graph.pieces == graph.pieces[start])
    inner = joined[nearest_vertices(positions[joined], course[1:-1])].tolist() if course.shape[0] > 2 else []
    path = [start]
    visited = {start: 0}
    previous = start
    for waypoint in inner + [end]:
        if waypoint == previous:
            continue
        for vertex in _dijkstra(graph, previous, waypoint)[1:]:
            if vertex in visited:  # a loop (a spike out and back, or a step back): cut it out
                cut = visited[vertex] + 1
                for dropped in path[cut:]:
                    del visited[dropped]
                del path[cut:]
            else:
                visited[vertex] = len(path)
                path.append(vertex)
        previous = waypoint
    return np.asarray(path, dtype=np.int64)


def nearest_vertices(positions, points) -> np.ndarray:
    """(K,) index of the row of ``positions`` (V, 3) nearest to each of ``points`` (K, 3) (ties: the lowest).

    Exact, by blocks of consecutive points (a chain's, so near each other): a sample of the
    vertices bounds how far each point's nearest vertex can be, and only the vertices in the
    block's box grown by that bound are compared.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not positions.shape[0]:
        raise LayoutError("The target has no vertices")
    nearest = np.empty(points.shape[0], dtype=np.int64)
    sample = positions[:: max(1, positions.shape[0] // 2048)]
    for first in range(0, points.shape[0], 64):
        block = points[first : first + 64]
        bound = np.sqrt(((block[:, None, :] - sample[None, :, :]) ** 2).sum(axis=2).min(axis=1).max())
        low, high = block.min(axis=0) - bound, block.max(axis=0) + bound
        candidates = np.flatnonzero(np.all((positions >= low) & (positions <= high), axis=1))
        near = positions[candidates]
        near_squared = (near**2).sum(axis=1)
        rows = max(1, (1 << 21) // candidates.size)  # at most 16 MB of distances at a time
        for row in range(0, block.shape[0], rows):
            part = block[row : row + rows]
            # |p - q|^2 - |q|^2 = |p|^2 - 2 p.q: the same order for each point q.
            closest = np.argmin(near_squared[None, :] - 2.0 * part @ near.T, axis=1)
            nearest[first + row : first + row + part.shape[0]] = candidates[closest]
    return nearest


def nearest_vertex(positions, point) -> int:
    """Index of the row of ``positions`` (V, 3) nearest to ``point`` (ties: the lowest index)."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if not positions.shape[0]:
        raise LayoutError("The target has no vertices")
    return int(np.argmin(((positions - np.asarray(point, dtype=np.float64).reshape(1, 3)) ** 2).sum(axis=1)))


def cumulative_lengths(points: np.ndarray) -> np.ndarray:
    """(P,) arc length at each point of a polyline, from 0."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def length_fractions(chain_positions: np.ndarray) -> np.ndarray:
    """(C,) each vertex's fraction of the chain's arc length (even when the chain has no length)."""
    lengths = cumulative_lengths(chain_positions)
    if lengths[-1] > 0.0:
        return lengths / lengths[-1]
    return np.linspace(0.0, 1.0, chain_positions.shape[0])
