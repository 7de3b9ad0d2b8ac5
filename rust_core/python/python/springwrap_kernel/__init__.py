"""Springwrap's Rust kernel: target meshes, exact closest point, ray casts and face-points.

The native module ``springwrap_kernel._native`` does the work; this package re-exports it and
names the results. The array contract: positions float32 ``(N, 3)``, triangles uint32
``(M, 3)``, C-contiguous; anything else raises :class:`ArrayError` saying what was wrong.
"""

from typing import NamedTuple

import numpy as np

from . import _native
from ._native import (
    ArrayError,
    DegenerateMeshError,
    DegenerateTriangleError,
    EmptyMeshError,
    IndexOutOfRangeError,
    InternalError,
    InvalidArgumentError,
    NonFiniteError,
    SpringwrapError,
    __version__,
)

__all__ = [
    "ArrayError",
    "DegenerateMeshError",
    "DegenerateTriangleError",
    "EmptyMeshError",
    "IndexOutOfRangeError",
    "InternalError",
    "InvalidArgumentError",
    "NonFiniteError",
    "SpringwrapError",
    "SurfaceHits",
    "TargetMesh",
    "VertexHits",
    "__version__",
]


class SurfaceHits(NamedTuple):
    """Per-query surface results; ``triangles[i] == -1`` means query ``i`` found nothing."""

    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray
    distances: np.ndarray


class VertexHits(NamedTuple):
    """Per-query nearest-vertex results; ``vertices[i] == -1`` means query ``i`` found nothing."""

    vertices: np.ndarray
    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray
    distances: np.ndarray


class TargetMesh(_native.TargetMesh):
    """A triangle mesh prepared for queries: BVH over triangles, vertex tree, adjacency, normals.

    ``TargetMesh(vertices, triangles, *, reject_degenerate=False)``. Queries are batched, run on
    all cores and release the GIL.
    """

    __slots__ = ()

    def closest_points(self, points, *, max_distance=float("inf")):
        """Exact closest point on the surface (the face tree) for every query point."""
        return SurfaceHits(*super().closest_points(points, max_distance=max_distance))

    def nearest_vertices(self, points, *, max_distance=float("inf")):
        """Nearest mesh vertex (the fast vertex tree), as a face-point at that vertex."""
        return VertexHits(*super().nearest_vertices(points, max_distance=max_distance))

    def ray_cast(self, origins, directions, *, max_distance=float("inf"), both_directions=False):
        """First hit along each ray (signed distance; backwards too with ``both_directions``)."""
        return SurfaceHits(
            *super().ray_cast(
                origins, directions, max_distance=max_distance, both_directions=both_directions
            )
        )
