"""Differences between the Blender versions the add-on supports (3.4 and later)."""

import bpy
import numpy as np


def read_vertex_normals(mesh: "bpy.types.Mesh") -> np.ndarray:
    """(N, 3) float32 vertex normals of a mesh in its local space.

    Blender 3.5 moved vertex normals to ``Mesh.vertex_normals``; before, they were on the vertices.
    """
    normals = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if hasattr(mesh, "vertex_normals"):
        mesh.vertex_normals.foreach_get("vector", normals)
    else:
        mesh.vertices.foreach_get("normal", normals)
    return normals.reshape(-1, 3)
