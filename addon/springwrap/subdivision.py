"""The wrap's internal spring resolution: a layout's faces subdivided k x k (pure numpy, no bpy).

Krishnamurthy & Levoy relax a coarse spring mesh, then subdivide it and relax again. With a
spring resolution k > 1 the wrap does the same: it relaxes the layout itself, then a finer grid
in which every quad is a k x k grid of quads (every edge cut in k, other polygons keep their
corners and take the cut edges' points), and writes the layout's own vertices back from it.

The fine layout numbers the layout's vertices first (0 .. n-1, so anchors and results keep their
indices), then the points inside the edges (k - 1 per edge, edge by edge), then the points inside
the quads ((k - 1)^2 per quad). Every fine point is a blend of at most four layout vertices:
:attr:`FineLayout.sources` and :attr:`FineLayout.weights` say which and how much, so positions,
rest shapes and anything else per vertex carry over with :meth:`FineLayout.interpolate`.
"""

from typing import NamedTuple

import numpy as np

MAX_RESOLUTION = 8
"""The largest spring resolution: each quad 8 x 8."""


class LayoutTopology(NamedTuple):
    """A layout mesh's connectivity: faces flat (``face_sizes[f]`` corners each) and edges."""

    vertex_count: int
    face_corners: np.ndarray  # (sum of sizes,) uint32
    face_sizes: np.ndarray  # (F,) uint32
    edges: np.ndarray  # (E, 2) uint32, every edge of the mesh (those on no face are loose curves)
    seams: np.ndarray  # (S, 2) uint32, the edges marked as patch boundaries


class FineLayout(NamedTuple):
    """A layout subdivided for the wrap (see the module docstring)."""

    topology: LayoutTopology
    sources: np.ndarray  # (M, 4) int64: the layout vertices each fine point blends
    weights: np.ndarray  # (M, 4) float64: their weights (rows sum to 1)
    edge_points: dict  # (a, b) with a < b -> the fine points inside that layout edge, from a to b

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` of the layout ((n,) or (n, c)) blended onto every fine point."""
        values = np.asarray(values, dtype=np.float64)
        gathered = values[self.sources]
        if values.ndim == 1:
            return np.einsum("mk,mk->m", gathered, self.weights)
        return np.einsum("mkc,mk->mc", gathered, self.weights)

    def expand_chain(self, chain: np.ndarray) -> np.ndarray:
        """A chain of layout vertices (consecutive ones joined by edges) with the fine points of its edges put in."""
        chain = np.asarray(chain, dtype=np.int64)
        pieces = [chain[:1]]
        for a, b in zip(chain[:-1], chain[1:]):
            inside = self.edge_points.get((min(a, b), max(a, b)))
            if inside is not None:
                pieces.append(inside if a < b else inside[::-1])
            pieces.append(np.array([b], dtype=np.int64))
        return np.concatenate(pieces)


def subdivide(topology: LayoutTopology, resolution: int) -> FineLayout:
    """Cut every edge of the layout in ``resolution`` and every quad into ``resolution`` x ``resolution``.

    Raises ``ValueError`` for a resolution outside 1 .. :data:`MAX_RESOLUTION`.
    """
    k = int(resolution)
    if not 1 <= k <= MAX_RESOLUTION:
        raise ValueError(f"The spring resolution must be within 1 .. {MAX_RESOLUTION}, not {resolution}")
    n = int(topology.vertex_count)
    sizes = np.asarray(topology.face_sizes, dtype=np.int64)
    corners = np.asarray(topology.face_corners, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)

    # Every undirected edge, from the faces and the edge list; k - 1 points inside each.
    face_edges = []
    for start, size in zip(starts, sizes):
        ring = corners[start:start + size]
        face_edges.append(np.stack([ring, np.roll(ring, -1)], axis=1))
    listed = np.asarray(topology.edges, dtype=np.int64).reshape(-1, 2)
    all_edges = np.concatenate(face_edges + [listed]) if face_edges else listed
    all_edges = np.unique(np.sort(all_edges, axis=1), axis=0)
    inner = k - 1
    sources = [np.stack([np.arange(n)] * 4, axis=1)]
    weights = [np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))]
    edge_points = {}
    if inner:
        steps = np.arange(1, k) / k  # along each edge, from its lower vertex
        for index, (a, b) in enumerate(all_edges):
            edge_points[(int(a), int(b))] = n + index * inner + np.arange(inner, dtype=np.int64)
        a = np.repeat(all_edges[:, 0], inner)
        b = np.repeat(all_edges[:, 1], inner)
        t = np.tile(steps, len(all_edges))
        sources.append(np.stack([a, b, a, a], axis=1))
        weights.append(np.stack([1.0 - t, t, np.zeros_like(t), np.zeros_like(t)], axis=1))
    next_index = n + len(all_edges) * inner

    def edge_point(u: int, v: int, step: int) -> int:
        """The fine point ``step`` / k of the way from layout vertex u to v (steps 0 and k are u and v)."""
        if step == 0:
            return int(u)
        if step == k:
            return int(v)
        inside = edge_points[(min(u, v), max(u, v))]
        return int(inside[step - 1] if u < v else inside[k - step - 1])

    fine_corners, fine_sizes = [], []
    quad_sources, quad_weights = [], []
    for start, size in zip(starts, sizes):
        ring = corners[start:start + size]
        if size == 4 and k > 1:
            c0, c1, c2, c3 = (int(c) for c in ring)
            grid = np.empty((k + 1, k + 1), dtype=np.int64)  # grid[i, j]: u = i / k along c0 -> c1, v = j / k
            for i in range(k + 1):
                grid[i, 0] = edge_point(c0, c1, i)
                grid[i, k] = edge_point(c3, c2, i)
            for j in range(k + 1):
                grid[0, j] = edge_point(c0, c3, j)
                grid[k, j] = edge_point(c1, c2, j)
            count = inner * inner
            grid[1:k, 1:k] = (next_index + np.arange(count)).reshape(inner, inner)
            next_index += count
            u, v = np.meshgrid(steps, steps, indexing="ij")
            u, v = u.reshape(-1), v.reshape(-1)
            quad_sources.append(np.tile([c0, c1, c2, c3], (count, 1)))
            quad_weights.append(np.stack([(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v], axis=1))
            cells = np.stack(
                [grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1
            ).reshape(-1, 4)
            fine_corners.append(cells.reshape(-1))
            fine_sizes.append(np.full(len(cells), 4, dtype=np.int64))
        else:
            # Other polygons (and quads at resolution 1) keep their corners, with the cut edges' points.
            polygon = []
            for u, v in zip(ring, np.roll(ring, -1)):
                polygon.extend(edge_point(int(u), int(v), step) for step in range(k))
            fine_corners.append(np.array(polygon, dtype=np.int64))
            fine_sizes.append(np.array([len(polygon)], dtype=np.int64))
    sources.extend(quad_sources)
    weights.extend(quad_weights)

    def cut(edges: np.ndarray) -> np.ndarray:
        """The fine edges along the given layout edges."""
        pieces = []
        for a, b in np.asarray(edges, dtype=np.int64).reshape(-1, 2):
            chain = [edge_point(a, b, step) for step in range(k + 1)]
            pieces.extend(zip(chain[:-1], chain[1:]))
        return np.array(pieces, dtype=np.uint32).reshape(-1, 2)

    fine = LayoutTopology(
        vertex_count=next_index,
        face_corners=np.ascontiguousarray(np.concatenate(fine_corners) if fine_corners else [], dtype=np.uint32),
        face_sizes=np.ascontiguousarray(np.concatenate(fine_sizes) if fine_sizes else [], dtype=np.uint32),
        edges=cut(topology.edges),
        seams=cut(topology.seams),
    )
    return FineLayout(
        topology=fine,
        sources=np.concatenate(sources).astype(np.int64),
        weights=np.concatenate(weights).astype(np.float64),
        edge_points=edge_points,
    )
