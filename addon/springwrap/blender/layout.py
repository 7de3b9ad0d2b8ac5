"""The layout object's own data as arrays: positions, selection and state, normals, topology, vertex groups,
its object transform. With shape keys the positions are the reference key's, and writing them carries the
other keys over (``blender.shape_keys``); the operators that cannot do that refuse a layout with shape keys.

Object mode data unless a function says otherwise (:func:`read_world_vertex_positions` also reads the
edit-mesh). Bulk data moves through ``foreach_get`` / ``foreach_set``.
"""

from typing import NamedTuple

import bpy

import bmesh
import numpy as np
from mathutils import Matrix

import springwrap_kernel

from ..core import input_policy, layout_state, subdivision, transforms, wrap_inputs
from ..core.errors import LayoutError
from ..core.layout_state import LayoutArrays, LayoutState
from ..core.transforms import matrix_array
from . import attributes, compat, last_run, shape_keys

SHAPE_KEYS_CONSEQUENCE = (
    "Fit Subdivision and Align Armature evaluate the layout through a Blender modifier, which would mix the keys "
    "in: apply or remove them first (Wrap, Mirror, Snap, Project and Align carry shape keys over)"
)
"""What the refusal of a layout with shape keys says by default."""


def refuse_shape_keys(layout: bpy.types.Object, consequence: str = SHAPE_KEYS_CONSEQUENCE) -> None:
    """Raise :class:`LayoutError` when the layout mesh has shape keys (an operation that cannot carry them over:
    its positions live in the keys, so what it wrote would not show, or it evaluates the keys' mix)."""
    shape_keys.refuse(layout, "REFUSE", consequence)


def read_positions(layout: bpy.types.Object) -> np.ndarray:
    """(N * 3,) float32 local positions: the reference key's when the layout has shape keys, else the vertices'."""
    basis = shape_keys.read_basis(layout.data)
    return attributes.read_positions(layout.data) if basis is None else basis


def read_layout(layout: bpy.types.Object) -> LayoutArrays:
    """Read the layout mesh (object mode data): local positions, selection, state, transform."""
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    if vertex_count == 0:
        raise LayoutError(f"Layout '{layout.name}' has no vertices")
    selection = np.empty(vertex_count, dtype=bool)
    mesh.vertices.foreach_get("select", selection)
    return LayoutArrays(
        positions=read_positions(layout).reshape(-1, 3),
        matrix_world=matrix_array(layout.matrix_world),
        selection=selection,
        state=attributes.read_state(mesh),
    )


def read_point_counts(layout: bpy.types.Object) -> tuple[int, int] | None:
    """(face-points, space-points) from the state attribute; None when they cannot be read from it (edit mode,
    which holds the mesh data back, or an attribute of another type or length)."""
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    if mesh.attributes.get(layout_state.STATE_ATTRIBUTE) is None:
        return None if layout.mode == "EDIT" else (0, vertex_count)
    states = attributes.read_point_attribute(mesh, layout_state.STATE_ATTRIBUTE, "INT")
    if states is None or states.size != vertex_count:
        return None
    return layout_state.point_counts(states)


def read_world_normals(layout: bpy.types.Object) -> np.ndarray:
    """(N, 3) float64 unit vertex normals of the layout in world space; zero for vertices on no face.

    Blender gives loose vertices (curve chains) a made-up normal; those are zeroed so that a
    NORMAL projection skips them instead of casting a meaningless ray.
    """
    mesh = layout.data
    normals = compat.read_vertex_normals(mesh).astype(np.float64)
    corner_vertices = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corner_vertices)
    on_face = np.zeros(len(mesh.vertices), dtype=bool)
    on_face[corner_vertices] = True
    normals[~on_face] = 0.0
    matrix = matrix_array(layout.matrix_world)
    if not transforms.is_invertible(matrix):
        raise LayoutError(f"Layout '{layout.name}' has zero scale: its normals are undefined")
    return transforms.transform_normals(matrix, normals)


class MeshNow(NamedTuple):
    """What a caller knows the layout mesh holds now (a wrap: what it read, or its last frame), so that
    :func:`write_layout` reads none of it back."""

    positions: np.ndarray  # (N, 3) float32 local positions, as read_positions reads them
    has_rest: bool  # whether a rest shape is stored
    topology: object  # subdivision.LayoutTopology
    shape_keys: object  # blender.shape_keys.ShapeKeys as stored now, None without keys


def write_layout(
    layout: bpy.types.Object,
    positions: np.ndarray,
    state: LayoutState,
    rest: np.ndarray | None = None,
    now: MeshNow | None = None,
) -> None:
    """Write local positions and the per-vertex state into the layout mesh (object mode).

    The state attributes are created when missing (or replaced when one with the same name has
    another type or domain). A layout without a rest shape gets one first: ``rest`` when given,
    else its positions before this write (the template as made, before Springwrap moved it). With shape keys
    the positions become the reference key's too and every other key is carried over onto them
    (``shape_keys.carried``, computed before anything is written). The layout's last wrap, mirror or fit is
    forgotten (``last_run``): the operation that writes says what it did. ``now``: what the mesh holds now, known
    to the caller (:class:`MeshNow`): then nothing of it is read back.
    """
    last_run.forget(layout.name)
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    positions = np.ascontiguousarray(positions, dtype=np.float32).reshape(vertex_count, 3)
    current = read_positions(layout) if now is None else np.ascontiguousarray(now.positions, dtype=np.float32)
    unmoved = np.array_equal(current.reshape(-1).view(np.uint32), positions.reshape(-1).view(np.uint32))
    keys = None
    if shape_keys.has_shape_keys(layout) and not unmoved:
        if now is not None:
            keys = shape_keys.carried(layout, positions, now.topology, now.shape_keys)
        else:
            topology = read_layout_topology(layout) if len(mesh.polygons) or len(mesh.edges) else None
            keys = shape_keys.carried(layout, positions, topology)
    if not (attributes.read_rest(layout) is not None if now is None else now.has_rest):
        attributes.write_rest(layout, current.reshape(-1, 3) if rest is None else rest)
    if keys is not None:
        shape_keys.write(layout, *keys)
    elif not unmoved:
        mesh.vertices.foreach_set("co", positions.reshape(-1))
    attributes.write_state(mesh, state)
    mesh.update()


def read_vertex_selection(layout: bpy.types.Object) -> tuple[np.ndarray, int]:
    """(N,) bool vertex selection and the active vertex (last of the selection history, -1 for none).

    Reads the mesh data (object mode): leaving edit mode writes the selection history into it.
    """
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    selection = np.empty(vertex_count, dtype=bool)
    mesh.vertices.foreach_get("select", selection)
    active_vertex = -1
    if selection.any():
        editable = bmesh.new()
        try:
            editable.from_mesh(mesh)
            active = editable.select_history.active
            if isinstance(active, bmesh.types.BMVert):
                active_vertex = active.index
        finally:
            editable.free()
    return selection, active_vertex


def read_world_vertex_positions(layout: bpy.types.Object, vertex_indices: np.ndarray) -> np.ndarray:
    """(K, 3) float64 world positions of the given layout vertices; NaN rows for indices out of range.

    In edit mode the positions come from the edit-mesh (so they follow edits as they happen),
    one anchor at a time; otherwise all vertex positions are read at once.
    """
    mesh = layout.data
    vertex_indices = np.asarray(vertex_indices, dtype=np.int64).reshape(-1)
    local = np.full((vertex_indices.shape[0], 3), np.nan, dtype=np.float64)
    if mesh.is_editmode:
        editable = bmesh.from_edit_mesh(mesh)
        editable.verts.ensure_lookup_table()
        vertex_count = len(editable.verts)
        for row, index in enumerate(vertex_indices.tolist()):
            if 0 <= index < vertex_count:
                local[row] = editable.verts[index].co
    else:
        vertex_count = len(mesh.vertices)
        valid = (vertex_indices >= 0) & (vertex_indices < vertex_count)
        if valid.any():
            local[valid] = read_positions(layout).reshape(-1, 3)[vertex_indices[valid]]
    return transforms.transform_points(matrix_array(layout.matrix_world), local)


# ---------------------------------------------------------------- topology


def read_layout_topology(layout: bpy.types.Object, seams: bool = True):
    """The layout mesh's faces, edges and seams (object mode data), as a ``subdivision.LayoutTopology``.

    Every edge is listed (those on no face are loose curves), and the seam-marked ones as patch
    boundaries (``seams=False``: none read, for a reader that does not use them). Raises
    :class:`LayoutError` for a layout with neither faces nor edges.
    """
    mesh = layout.data
    face_count, edge_count = len(mesh.polygons), len(mesh.edges)
    wrap_inputs.check_wrappable(layout.name, face_count, edge_count)
    face_corners, face_sizes = compat.read_face_corners(mesh)
    edges = np.empty(edge_count * 2, dtype=np.uint32)
    mesh.edges.foreach_get("vertices", edges)
    edges = edges.reshape(-1, 2)
    seam_edges = np.zeros((0, 2), dtype=np.uint32)
    if seams:
        seam_flags = np.zeros(edge_count, dtype=bool)
        mesh.edges.foreach_get("use_seam", seam_flags)
        seam_edges = np.ascontiguousarray(edges[seam_flags])
    return subdivision.LayoutTopology(
        len(mesh.vertices),
        np.ascontiguousarray(face_corners, dtype=np.uint32),
        np.ascontiguousarray(face_sizes, dtype=np.uint32),
        np.ascontiguousarray(edges),
        seam_edges,
    )


def make_layout_structure(topology):
    """A kernel ``LayoutStructure`` of a ``subdivision.LayoutTopology``."""
    return springwrap_kernel.LayoutStructure(
        int(topology.vertex_count),
        np.ascontiguousarray(topology.face_corners, dtype=np.uint32),
        np.ascontiguousarray(topology.face_sizes, dtype=np.uint32),
        edges=np.ascontiguousarray(topology.edges, dtype=np.uint32).reshape(-1, 2),
        seams=np.ascontiguousarray(topology.seams, dtype=np.uint32).reshape(-1, 2),
    )


def read_layout_structure(layout: bpy.types.Object):
    """The layout mesh's faces, edges and seams as a kernel ``LayoutStructure`` (object mode data)."""
    return make_layout_structure(read_layout_topology(layout))


def read_layout_curves(layout: bpy.types.Object) -> list:
    """The layout's curves as the kernel finds them: (kind, vertices in order, closed) per curve (object mode)."""
    return [
        (kind, np.asarray(vertices, dtype=np.int64), bool(closed))
        for kind, vertices, closed in read_layout_structure(layout).curves()
    ]


def read_selected_edges(layout: bpy.types.Object) -> np.ndarray:
    """(E, 2) int64 vertex pairs of the layout's selected edges (object mode data)."""
    mesh = layout.data
    edge_count = len(mesh.edges)
    selected = np.empty(edge_count, dtype=bool)
    mesh.edges.foreach_get("select", selected)
    edges = np.empty(edge_count * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    return edges.reshape(-1, 2)[selected]


def read_layout_group(layout: bpy.types.Object, group_name: str) -> tuple[np.ndarray, np.ndarray]:
    """((N,) float32 weights, (N,) bool membership) of the layout's vertex group ``group_name`` on its own
    (base) mesh. Raises :class:`LayoutError` naming the group when the layout has no such group or a weight in
    it is not a finite number (the add-on's input policy: ``core.input_policy.setting_problem``)."""
    group = layout.vertex_groups.get(group_name)
    if group is None:
        raise LayoutError(f"Layout '{layout.name}' has no vertex group '{group_name}'")
    mesh = layout.data
    weights = np.zeros(len(mesh.vertices), dtype=np.float32)
    member = np.zeros(len(mesh.vertices), dtype=bool)
    index = group.index
    for vertex in mesh.vertices:
        for element in vertex.groups:
            if element.group == index:
                weights[vertex.index] = element.weight
                member[vertex.index] = True
    bad = np.flatnonzero(~np.isfinite(weights))
    if bad.size:
        problem = input_policy.setting_problem(f"vertex {int(bad[0])}'s weight", weights[bad[0]])
        raise LayoutError(
            f"Layout '{layout.name}': vertex group '{group_name}': {problem} ({bad.size} such): set those weights "
            "(Weight Paint, or Vertex Group › Assign)"
        )
    return weights, member


# ---------------------------------------------------------------- object transform


def read_parent_matrix(layout: bpy.types.Object) -> np.ndarray:
    """The 4x4 matrix taking the object's basis (location, rotation, scale) to world space.

    ``matrix_world = parent_matrix @ matrix_basis``: the parent's world matrix times the parent
    inverse, identity for an object without a parent. Raises :class:`LayoutError` when the basis
    has zero scale (the parent part is then unknown).
    """
    basis = matrix_array(layout.matrix_basis)
    if not transforms.is_invertible(basis):
        raise LayoutError(f"Layout '{layout.name}' has zero scale: its transform cannot be aligned")
    return matrix_array(layout.matrix_world) @ transforms.inverse_matrix(basis)


def write_object_basis(layout: bpy.types.Object, basis: np.ndarray) -> None:
    """Set the object's location, rotation and scale from a 4x4 basis matrix (no shear)."""
    layout.matrix_basis = Matrix(np.asarray(basis, dtype=np.float64).tolist())
