"""The mirror's changes to the layout mesh: the mirrored half's topology added with bmesh, the mesh backed up
and restored, faces selected. ``core.mirroring`` decides everything first.
"""

import bpy

import bmesh
import numpy as np

from . import attributes

_MIRROR_SOURCE_ATTRIBUTE = "springwrap_mirror_source"
"""Temporary INT point attribute: each vertex's original index, carried to its copy by bmesh."""


def mirror_mesh_topology(
    layout: bpy.types.Object, duplicate_faces: np.ndarray, duplicate_edges: np.ndarray, seam: np.ndarray
) -> np.ndarray:
    """Add the mirrored half's topology to the layout mesh (object mode); (M,) the source of each vertex.

    The faces and loose edges flagged are copied with every attribute the mesh has (UV maps,
    vertex groups, seams, the Springwrap state), the copies' winding is reversed, and the copies of
    ``seam`` vertices are welded back onto their originals, so the seam is shared. The layout's own
    vertices keep their indices (anchors stay valid); the copies follow them. Positions are not
    changed here: the caller writes the reflected ones.
    """
    mesh = layout.data
    count = len(mesh.vertices)
    attributes.remove_attribute(mesh, _MIRROR_SOURCE_ATTRIBUTE)
    attributes.write_point_attribute(mesh, _MIRROR_SOURCE_ATTRIBUTE, "INT", np.arange(count, dtype=np.int32))
    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        bm.faces.ensure_lookup_table()
        bm.edges.ensure_lookup_table()
        bm.verts.ensure_lookup_table()
        geometry = [bm.faces[index] for index in np.flatnonzero(duplicate_faces).tolist()]
        geometry += [bm.edges[index] for index in np.flatnonzero(duplicate_edges).tolist()]
        seam_vertices = [bm.verts[index] for index in np.flatnonzero(seam).tolist()]
        duplicated = bmesh.ops.duplicate(bm, geom=geometry)
        vertex_map = duplicated["vert_map"]
        new_faces = [element for element in duplicated["geom"] if isinstance(element, bmesh.types.BMFace)]
        bmesh.ops.reverse_faces(bm, faces=new_faces)
        targets = {}
        for original in seam_vertices:
            copy = vertex_map.get(original)
            if copy is not None and copy is not original:
                targets[copy] = original
        if targets:
            bmesh.ops.weld_verts(bm, targetmap=targets)
        bm.to_mesh(mesh)
    finally:
        bm.free()
    source = attributes.read_point_attribute(mesh, _MIRROR_SOURCE_ATTRIBUTE, "INT")
    attributes.remove_attribute(mesh, _MIRROR_SOURCE_ATTRIBUTE)
    mesh.update()
    return source.astype(np.int64)


def backup_mesh(layout: bpy.types.Object) -> bpy.types.Mesh:
    """A copy of the layout's mesh datablock (every attribute), to put back with :func:`restore_mesh`."""
    return layout.data.copy()


def restore_mesh(layout: bpy.types.Object, backup: bpy.types.Mesh) -> None:
    """Put the geometry and attributes of ``backup`` back into the layout's own mesh (object mode)."""
    bm = bmesh.new()
    try:
        bm.from_mesh(backup)
        bm.to_mesh(layout.data)
    finally:
        bm.free()
    layout.data.update()


def select_faces(layout: bpy.types.Object, faces: np.ndarray) -> None:
    """Select exactly ``faces`` (indices) of the layout mesh and their vertices and edges (object mode)."""
    mesh = layout.data
    face_flags = np.zeros(len(mesh.polygons), dtype=bool)
    face_flags[np.asarray(faces, dtype=np.int64)] = True
    vertex_flags = np.zeros(len(mesh.vertices), dtype=bool)
    loop_vertices = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    loop_faces = np.empty(len(mesh.loops), dtype=np.int64)
    starts = np.empty(len(mesh.polygons), dtype=np.int64)
    totals = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    # Loops face by face: loop_start + 0 .. loop_total - 1 (loops need not be in face order).
    offsets = np.repeat(starts - np.concatenate([[0], np.cumsum(totals)[:-1]]), totals)
    loop_faces[np.arange(int(totals.sum()), dtype=np.int64) + offsets] = np.repeat(
        np.arange(len(mesh.polygons)), totals
    )
    vertex_flags[loop_vertices[face_flags[loop_faces]]] = True
    edge_vertices = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", edge_vertices)
    edge_flags = vertex_flags[edge_vertices.reshape(-1, 2)].all(axis=1)
    mesh.polygons.foreach_set("select", face_flags)
    mesh.edges.foreach_set("select", edge_flags)
    mesh.vertices.foreach_set("select", vertex_flags)
    mesh.update()
