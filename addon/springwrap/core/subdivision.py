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
    edges: np.ndarray  # (E, 2) int64: the layout's edges, each as (lower, higher), sorted; edge e's
    # k - 1 inner points are the fine points first_edge_point + e (k - 1) ... from its lower vertex
    first_edge_point: int
    resolution: int
    edge_keys: np.ndarray  # (E,) int64: lower * first_edge_point + higher per edge, sorted (for lookups)

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` of the layout ((n,) or (n, c)) blended onto every fine point."""
        values = np.asarray(values, dtype=np.float64)
        gathered = values[self.sources]
        if values.ndim == 1:
            return np.einsum("mk,mk->m", gathered, self.weights)
        return np.einsum("mkc,mk->mc", gathered, self.weights)

    def points_inside(self, a: int, b: int) -> np.ndarray | None:
        """The fine points cut into the layout edge a-b, in order from a to b; None when there is no such edge."""
        inner = self.resolution - 1
        low, high = min(a, b), max(a, b)
        index = int(np.searchsorted(self.edge_keys, low * self.first_edge_point + high))
        if index >= len(self.edges) or tuple(self.edges[index]) != (low, high):
            return None
        points = self.first_edge_point + index * inner + np.arange(inner, dtype=np.int64)
        return points if a < b else points[::-1]

    def expand_chain(self, chain: np.ndarray) -> np.ndarray:
        """A chain of layout vertices (consecutive ones joined by edges) with the fine points of its edges put in."""
        chain = np.asarray(chain, dtype=np.int64)
        pieces = [chain[:1]]
        for a, b in zip(chain[:-1].tolist(), chain[1:].tolist()):
            inside = self.points_inside(a, b)
            if inside is not None:
                pieces.append(inside)
            pieces.append(np.array([b], dtype=np.int64))
        return np.concatenate(pieces)


def _edge_keys(edges: np.ndarray, vertex_count: int) -> np.ndarray:
    """One sortable integer per (lower, higher) edge."""
    return edges[:, 0] * vertex_count + edges[:, 1]


def _ring_next(sizes: np.ndarray) -> np.ndarray:
    """For the corners of faces laid one after another, the index of the next corner in the same face."""
    total = int(sizes.sum())
    starts = np.repeat(np.concatenate([[0], np.cumsum(sizes)[:-1]]), sizes)
    following = np.arange(1, total + 1)
    return np.where(following == starts + np.repeat(sizes, sizes), starts, following)


def subdivide(topology: LayoutTopology, resolution: int) -> FineLayout:
    """Cut every edge of the layout in ``resolution`` and every quad into ``resolution`` x ``resolution``.

    The fine faces are the quads' cells (quad by quad), then the other polygons. Raises ``ValueError``
    for a resolution outside 1 .. :data:`MAX_RESOLUTION`.
    """
    k = int(resolution)
    if not 1 <= k <= MAX_RESOLUTION:
        raise ValueError(f"The spring resolution must be within 1 .. {MAX_RESOLUTION}, not {resolution}")
    n = int(topology.vertex_count)
    sizes = np.asarray(topology.face_sizes, dtype=np.int64)
    corners = np.asarray(topology.face_corners, dtype=np.int64)
    inner = k - 1

    # Every undirected edge, from the faces and the edge list; k - 1 points inside each.
    face_edges = np.stack([corners, corners[_ring_next(sizes)]], axis=1) if corners.size else np.zeros((0, 2), int)
    listed = np.asarray(topology.edges, dtype=np.int64).reshape(-1, 2)
    edges = np.unique(np.sort(np.concatenate([face_edges, listed]), axis=1), axis=0)
    keys = _edge_keys(edges, n)

    def along(u: np.ndarray, v: np.ndarray, step: int) -> np.ndarray:
        """The fine points ``step`` / k of the way from layout vertices u to v (steps 0 and k are u and v)."""
        if step == 0:
            return u
        if step == k:
            return v
        index = np.searchsorted(keys, np.minimum(u, v) * n + np.maximum(u, v))
        base = n + index * inner
        return np.where(u < v, base + step - 1, base + k - step - 1)

    sources = [np.stack([np.arange(n)] * 4, axis=1)]
    weights = [np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))]
    steps = np.arange(1, k) / k
    if inner:
        a, b = np.repeat(edges[:, 0], inner), np.repeat(edges[:, 1], inner)
        t = np.tile(steps, len(edges))
        sources.append(np.stack([a, b, a, a], axis=1))
        weights.append(np.stack([1.0 - t, t, np.zeros_like(t), np.zeros_like(t)], axis=1))
    next_index = n + len(edges) * inner

    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    is_quad = (sizes == 4) & (k > 1)
    quad_corners = corners[starts[is_quad][:, None] + np.arange(4)] if is_quad.any() else np.zeros((0, 4), int)
    fine_corners, fine_sizes = [], []
    if len(quad_corners):
        c0, c1, c2, c3 = quad_corners.T
        count = len(quad_corners)
        grid = np.empty((count, k + 1, k + 1), dtype=np.int64)  # grid[q, i, j]: u = i / k along c0 -> c1, v = j / k
        for i in range(k + 1):
            grid[:, i, 0] = along(c0, c1, i)
            grid[:, i, k] = along(c3, c2, i)
            grid[:, 0, i] = along(c0, c3, i)
            grid[:, k, i] = along(c1, c2, i)
        per_quad = inner * inner
        grid[:, 1:k, 1:k] = (next_index + np.arange(count * per_quad)).reshape(count, inner, inner)
        next_index += count * per_quad
        u, v = np.meshgrid(steps, steps, indexing="ij")
        u, v = u.reshape(-1), v.reshape(-1)
        sources.append(np.repeat(quad_corners, per_quad, axis=0))
        weights.append(np.tile(np.stack([(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v], axis=1), (count, 1)))
        cells = np.stack([grid[:, :-1, :-1], grid[:, 1:, :-1], grid[:, 1:, 1:], grid[:, :-1, 1:]], axis=-1)
        fine_corners.append(cells.reshape(-1))
        fine_sizes.append(np.full(count * k * k, 4, dtype=np.int64))
    # Other polygons (and quads at resolution 1) keep their corners, with the cut edges' points.
    for start, size in zip(starts[~is_quad].tolist(), sizes[~is_quad].tolist()):
        ring = corners[start : start + size]
        following = np.roll(ring, -1)
        polygon = np.stack([along(ring, following, step) for step in range(k)], axis=1).reshape(-1)
        fine_corners.append(polygon)
        fine_sizes.append(np.array([len(polygon)], dtype=np.int64))

    def cut(layout_edges: np.ndarray) -> np.ndarray:
        """The fine edges along the given layout edges."""
        layout_edges = np.asarray(layout_edges, dtype=np.int64).reshape(-1, 2)
        chain = np.stack([along(layout_edges[:, 0], layout_edges[:, 1], step) for step in range(k + 1)], axis=1)
        return np.stack([chain[:, :-1], chain[:, 1:]], axis=-1).reshape(-1, 2).astype(np.uint32)

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
        edges=edges,
        first_edge_point=n,
        resolution=k,
        edge_keys=keys,
    )
