"""The mirror's changes to the layout mesh: the mirrored half's topology added with bmesh (each new element a copy
of its original, with all its data), custom normals reflected, the mesh backed up and restored, faces selected.
``core.mirroring`` decides everything first.
"""

from typing import NamedTuple

import bpy

import bmesh
import numpy as np

from ..core import mirroring
from ..core.transforms import matrix_array
from . import attributes, compat

_SOURCE_ATTRIBUTE = "springwrap_mirror_source"
"""Prefix of the temporary INT attributes (one per domain) that carry each element's original index through
bmesh to its copy."""
_CUSTOM_NORMAL_ATTRIBUTE = "custom_normal"
"""Where Blender 5.0 keeps custom split normals (INT16_2D corner values, relative to each corner's own edges)."""
_DOMAINS = ("POINT", "EDGE", "FACE", "CORNER")
_BMESH_UNSAFE_TYPES = frozenset({"FLOAT4X4"})
"""Attribute types bmesh cannot copy from one element to another (Blender 5.0.1 crashes on a 4x4 matrix
attribute of points or corners): they are lifted out of the mesh around the bmesh edit and put back."""


class MirroredMesh(NamedTuple):
    """What :func:`mirror_mesh_topology` made: the original of each vertex and of each face corner."""

    vertex_source: np.ndarray  # (M,) int64: a vertex's own index for the layout's vertices, its original's for a copy
    corner_source: np.ndarray  # (C,) int64: the same for face corners


def mirror_mesh_topology(
    layout: bpy.types.Object, duplicate_faces: np.ndarray, duplicate_edges: np.ndarray, seam: np.ndarray
) -> MirroredMesh:
    """Add the mirrored half's topology to the layout mesh (object mode); where each vertex and corner comes from.

    The vertices of the faces and loose edges flagged, except the ``seam`` vertices (shared by both
    halves), are copied; so are those edges (an edge between two seam vertices is shared) and faces,
    the faces with their winding reversed. Every copy takes all the data of its original, bit for bit
    (``copy_from``: UV maps and other corner data corner by corner, vertex groups, creases, seams,
    sharp edges, materials, selection and hiding, every attribute), except that a vertex group weight
    goes to the group of the mirrored name where the layout has one (``Arm.L`` -> ``Arm.R``, as Blender's
    Mirror modifier does). Nothing is merged or interpolated, so the original mesh is unchanged: its
    vertices, edges and faces keep their indices (anchors stay valid) and the copies follow them, vertices
    in the order of their originals. Positions are not changed here: the caller writes the reflected ones.
    """
    mesh = layout.data
    seam = np.asarray(seam, dtype=bool)
    lifted = attributes.lift_attributes(mesh, _BMESH_UNSAFE_TYPES)
    for domain in _DOMAINS:
        attributes.write_attribute(
            mesh,
            f"{_SOURCE_ATTRIBUTE}_{domain.lower()}",
            "INT",
            domain,
            np.arange(attributes.domain_size(mesh, domain), dtype=np.int32),
        )
    group_partners = mirrored_group_indices([group.name for group in layout.vertex_groups])
    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        bm.verts.ensure_lookup_table()
        bm.edges.ensure_lookup_table()
        bm.faces.ensure_lookup_table()
        faces = [bm.faces[index] for index in np.flatnonzero(duplicate_faces).tolist()]
        edges = {edge.index: edge for face in faces for edge in face.edges}
        edges.update((index, bm.edges[index]) for index in np.flatnonzero(duplicate_edges).tolist())
        copied = sorted(
            {vertex.index for edge in edges.values() for vertex in edge.verts} - set(np.flatnonzero(seam).tolist())
        )
        copies = _copy_vertices(bm, copied, group_partners)
        for index in sorted(edges):
            edge = edges[index]
            ends = [copies.get(vertex, vertex) for vertex in edge.verts]
            if ends[0] is not edge.verts[0] or ends[1] is not edge.verts[1]:
                _copy_flags(bm.edges.new(ends, edge), edge)
        for face in faces:
            loops = list(reversed(face.loops))
            copy = bm.faces.new([copies.get(loop.vert, loop.vert) for loop in loops], face)
            _copy_flags(copy, face)
            for new_loop, loop in zip(copy.loops, loops):
                new_loop.copy_from(loop)
        bm.to_mesh(mesh)
    finally:
        bm.free()
        sources = {}
        for domain in _DOMAINS:
            name = f"{_SOURCE_ATTRIBUTE}_{domain.lower()}"
            sources[domain] = attributes.read_attribute(mesh, name, "INT", domain)
            attributes.remove_attribute(mesh, name)
        attributes.put_back_attributes(mesh, lifted, sources)
    mesh.update()
    return MirroredMesh(sources["POINT"].astype(np.int64), sources["CORNER"].astype(np.int64))


def read_custom_normals(layout: bpy.types.Object) -> np.ndarray | None:
    """(C, 3) corner normals of a layout with custom split normals (local space), None without them."""
    mesh = layout.data
    return compat.read_corner_normals(mesh) if mesh.has_custom_normals else None


def mirror_custom_normals(
    layout: bpy.types.Object, normals: np.ndarray, corner_source: np.ndarray, plane: mirroring.Plane
) -> None:
    """Give the copies' corners the reflection of their original's custom normal, as Blender's Mirror modifier
    does (a copied value would be meaningless: it is stored relative to its corner's own edges); the original
    corners are set to the normals they had (``normals``, read before the mirror)."""
    mesh = layout.data
    corner_source = np.asarray(corner_source, dtype=np.int64)
    is_copy = np.arange(corner_source.shape[0]) >= normals.shape[0]
    result = np.asarray(normals, dtype=np.float64)[corner_source]
    result[is_copy] = mirroring.reflect_local_normals(result[is_copy], matrix_array(layout.matrix_world), plane)
    sharp = np.empty(len(mesh.edges), dtype=bool)
    mesh.edges.foreach_get("use_edge_sharp", sharp)
    stored = attributes.read_attribute(mesh, _CUSTOM_NORMAL_ATTRIBUTE, "INT16_2D", "CORNER")
    mesh.normals_split_custom_set(result.tolist())
    # Blender marks edges sharp where the normals of a fan differ (the seam's two sides): the user's marks stay.
    mesh.edges.foreach_set("use_edge_sharp", sharp)
    if stored is not None:  # Blender 5.0 shows the stored normals: the original corners keep theirs bit for bit
        encoded = attributes.read_attribute(mesh, _CUSTOM_NORMAL_ATTRIBUTE, "INT16_2D", "CORNER").reshape(-1, 2)
        encoded[~is_copy] = stored.reshape(-1, 2)[~is_copy]
        attributes.write_attribute(mesh, _CUSTOM_NORMAL_ATTRIBUTE, "INT16_2D", "CORNER", encoded)
    mesh.update()


def _copy_vertices(bm, indices: list, group_partners: dict) -> dict:
    """Copy the vertices ``indices`` of ``bm`` with all their data (original -> copy), each weight of a group with
    a partner in ``group_partners`` moved to the partner."""
    deform = bm.verts.layers.deform.active
    copies = {}
    for original in [bm.verts[index] for index in indices]:
        copy = bm.verts.new(original.co, original)
        _copy_flags(copy, original)
        if deform is not None and group_partners:
            copy[deform].clear()
            for group, weight in original[deform].items():
                copy[deform][group_partners.get(group, group)] = weight
        copies[original] = copy
    return copies


def _copy_flags(copy, original) -> None:
    """Selection and hiding, which an element made from an example does not take. Only set, never cleared: a new
    element has neither, and clearing a face's would clear its vertices' too, the seam's among them."""
    if original.select:
        copy.select = True
    if original.hide:
        copy.hide = True


def mirrored_group_indices(names: list[str]) -> dict[int, int]:
    """Vertex group index -> the index of the group with the mirrored name (``bpy.utils.flip_name``: ``.L`` /
    ``.R``, ``_L`` / ``_R``, ``Left`` / ``Right``...), for the groups whose partner exists."""
    index_of = {name: index for index, name in enumerate(names)}
    partners = {}
    for index, name in enumerate(names):
        partner = index_of.get(bpy.utils.flip_name(name))
        if partner is not None and partner != index:
            partners[index] = partner
    return partners


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
