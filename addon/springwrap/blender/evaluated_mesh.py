"""The one reader of an object's evaluated mesh (modifiers applied): vertices, and on request its loop
triangles and edges, in world space or the object's own.

Every operation that needs a target's surface, a target's edges, a curve object's polyline, the
feature detection's mesh or the armature-deformed layout reads it here, once, with
``foreach_get``, and frees the temporary mesh at once.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import transforms
from . import compat


class EvaluatedMesh(NamedTuple):
    """An object's evaluated geometry as arrays."""

    vertices: np.ndarray  # (V, 3): float64 world positions, or float32 local ones (world=False)
    triangles: np.ndarray | None  # (T, 3) uint32 loop triangles, when asked for
    triangle_polygons: np.ndarray | None  # (T,) int32 the polygon of each loop triangle, with the triangles
    edges: np.ndarray | None  # (E, 2) int64 vertex pairs, when asked for
    matrix_world: np.ndarray  # (4, 4) float64 the evaluated object's transform


def read_evaluated_mesh(
    depsgraph: bpy.types.Depsgraph,
    obj: bpy.types.Object,
    triangles: bool = False,
    edges: bool = False,
    world: bool = True,
) -> EvaluatedMesh | None:
    """``obj`` evaluated in ``depsgraph``; None when it gives no mesh (a curve without points).

    ``world``: vertices transformed by the evaluated object's ``matrix_world`` (float64); else its
    local float32 coordinates.
    """
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        if mesh is None:
            return None
        local = _positions(mesh)
        triangle_array = triangle_polygons = edge_array = None
        if triangles:
            triangle_array, triangle_polygons = _loop_triangles(mesh, local)
        if edges:
            edge_array = np.empty(len(mesh.edges) * 2, dtype=np.int64)
            mesh.edges.foreach_get("vertices", edge_array)
            edge_array = edge_array.reshape(-1, 2)
    finally:
        evaluated.to_mesh_clear()
    matrix = transforms.matrix_array(evaluated.matrix_world)
    vertices = transforms.transform_points(matrix, local) if world else local
    return EvaluatedMesh(vertices, triangle_array, triangle_polygons, edge_array, matrix)


def _positions(mesh) -> np.ndarray:
    """(V, 3) float32 local vertex positions (the position attribute read whole when there is one)."""
    local = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    attribute = mesh.attributes.get("position")
    if attribute is not None and attribute.data_type == "FLOAT_VECTOR" and attribute.domain == "POINT":
        attribute.data.foreach_get("vector", local)
    else:
        mesh.vertices.foreach_get("co", local)
    return local.reshape(-1, 3)


def _loop_triangles(mesh, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((T, 3) uint32 vertices, (T,) int32 polygon) of the mesh's loop triangles.

    Read element by element these cost about 1 µs a triangle. A mesh of triangles only (a scan's) needs no loop
    triangles at all: they are its polygons' corners, in order (one read of the corners, which the triangles then
    share; Blender builds none). For a mesh of triangles and quads they are rebuilt from the corner and polygon
    arrays (read whole) as Blender makes them: a quad (0 1 2 3) gives (0 1 2) (0 2 3), or (0 1 3) (1 2 3) when it
    folds over its first diagonal (Blender's ``is_quad_flip_v3_first_third_fast``). A mesh with larger polygons
    is read element by element."""
    polygon_count = len(mesh.polygons)
    if polygon_count and len(mesh.loops) == 3 * polygon_count:  # every polygon has at least three corners
        corners, _sizes = compat.read_face_corners(mesh)
        return corners.reshape(-1, 3), np.arange(polygon_count, dtype=np.int32)
    mesh.calc_loop_triangles()
    count = len(mesh.loop_triangles)
    polygons = np.empty(count, dtype=np.int32)
    corners = mesh.attributes.get(".corner_vert")
    if hasattr(mesh, "loop_triangle_polygons") and corners is not None and count:
        mesh.loop_triangle_polygons.foreach_get("value", polygons)
        corner_vertices = np.empty(len(mesh.loops), dtype=np.int32)
        corners.data.foreach_get("value", corner_vertices)
        rebuilt = _triangles_of_quads(corner_vertices, polygons, len(mesh.polygons), positions)
        if rebuilt is not None:
            return rebuilt, polygons
    triangles = np.empty(count * 3, dtype=np.uint32)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    mesh.loop_triangles.foreach_get("polygon_index", polygons)
    return np.ascontiguousarray(triangles.reshape(-1, 3)), polygons


def _triangles_of_quads(corner_vertices, polygons, polygon_count: int, positions) -> np.ndarray | None:
    """(T, 3) uint32 loop triangles of a mesh whose polygons are triangles and quads (None otherwise), from
    each corner's vertex and each triangle's polygon."""
    per_polygon = np.bincount(polygons, minlength=polygon_count)
    sizes = per_polygon + 2
    if sizes.max() > 4 or sizes.min() < 3 or int(sizes.sum()) != corner_vertices.size:
        return None
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))[polygons]
    within = np.arange(polygons.size) - np.concatenate(([0], np.cumsum(per_polygon)[:-1]))[polygons]
    triangles = corner_vertices[np.stack([starts, starts + within + 1, starts + within + 2], axis=1)]
    quad = sizes[polygons] == 4
    first = starts[quad]
    quads = corner_vertices[first[:, None] + np.arange(4)]
    a, b, c, d = (positions[quads[:, corner]] for corner in range(4))
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), np.cross(d - a, c - a)) > 0.0
    flipped = np.where((within[quad] == 0)[:, None], quads[:, [0, 1, 3]], quads[:, [1, 2, 3]])
    triangles[np.flatnonzero(quad)[flip]] = flipped[flip]
    return np.ascontiguousarray(triangles, dtype=np.uint32)
