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
        local = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", local)
        triangle_array = triangle_polygons = edge_array = None
        if triangles:
            mesh.calc_loop_triangles()
            count = len(mesh.loop_triangles)
            triangle_array = np.empty(count * 3, dtype=np.uint32)
            mesh.loop_triangles.foreach_get("vertices", triangle_array)
            triangle_array = np.ascontiguousarray(triangle_array.reshape(-1, 3))
            triangle_polygons = np.empty(count, dtype=np.int32)
            mesh.loop_triangles.foreach_get("polygon_index", triangle_polygons)
        if edges:
            edge_array = np.empty(len(mesh.edges) * 2, dtype=np.int64)
            mesh.edges.foreach_get("vertices", edge_array)
            edge_array = edge_array.reshape(-1, 2)
    finally:
        evaluated.to_mesh_clear()
    local = local.reshape(-1, 3)
    matrix = transforms.matrix_array(evaluated.matrix_world)
    vertices = transforms.transform_points(matrix, local) if world else local
    return EvaluatedMesh(vertices, triangle_array, triangle_polygons, edge_array, matrix)
