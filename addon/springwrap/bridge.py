"""The only module that moves data between ``bpy`` and the Springwrap kernel.

Reads the layout (positions, selection, state attributes, anchors) and the evaluated target into
numpy arrays, builds and caches the kernel's ``TargetMesh``, and writes positions, state and
anchors back. Bulk data moves through ``foreach_get`` / ``foreach_set``; there is no per-vertex
Python loop (except over anchors in edit mode, which are few).
"""

import collections
import contextlib
from typing import Optional

import bmesh
import bpy
import numpy as np
import springwrap_kernel

from . import anchors, compat, layout_state
from .layout_state import LayoutArrays, LayoutError, LayoutState
from .operations import Target

ERRORS = (LayoutError, springwrap_kernel.SpringwrapError)
"""Every exception an operation turns into an error report (the layout is then left untouched)."""

MAX_CACHED_TARGETS = 2
"""Number of built target meshes kept between operations."""

_target_cache: "collections.OrderedDict[tuple[str, str], Target]" = collections.OrderedDict()

_STATE_ATTRIBUTES = (
    # name, data type, foreach property, numpy dtype, components
    (layout_state.STATE_ATTRIBUTE, "INT", "value", np.int32, 1),
    (layout_state.FACE_ATTRIBUTE, "INT", "value", np.int32, 1),
    (layout_state.BARYCENTRIC_ATTRIBUTE, "FLOAT_VECTOR", "vector", np.float32, 3),
)

_ANCHOR_FIELDS = (
    # AnchorItem property, numpy dtype, components (the order of anchors.make_anchors' arguments)
    ("vertex_index", np.int32, 1),
    ("target_kind", np.int32, 1),  # enum: its item numbers are the anchor kinds
    ("triangle", np.int32, 1),
    ("barycentric", np.float32, 3),
    ("location", np.float64, 3),
)


def matrix_array(matrix) -> np.ndarray:
    """A ``mathutils.Matrix`` 4x4 as a float64 numpy array (rows are rows)."""
    return np.array(matrix, dtype=np.float64).reshape(4, 4)


def check_target(layout: bpy.types.Object) -> "bpy.types.Object":
    """The layout's target object; raises :class:`LayoutError` when it is missing or unusable."""
    target = layout.springwrap.target
    if target is None:
        raise LayoutError(f"Layout '{layout.name}' has no target: pick one in the Springwrap panel")
    if target == layout:
        raise LayoutError(f"The target of '{layout.name}' is the layout itself")
    if target.type != "MESH":
        raise LayoutError(f"Target '{target.name}' is not a mesh object")
    return target


def read_layout(layout: bpy.types.Object) -> LayoutArrays:
    """Read the layout mesh (object mode data): local positions, selection, state, transform."""
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    if vertex_count == 0:
        raise LayoutError(f"Layout '{layout.name}' has no vertices")
    positions = np.empty(vertex_count * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    selection = np.empty(vertex_count, dtype=bool)
    mesh.vertices.foreach_get("select", selection)
    return LayoutArrays(
        positions=positions.reshape(-1, 3),
        matrix_world=matrix_array(layout.matrix_world),
        selection=selection,
        state=read_state(mesh),
    )


def read_state(mesh: bpy.types.Mesh) -> LayoutState:
    """The per-vertex state from the mesh attributes; missing (or wrongly typed) ones mean space-points."""
    vertex_count = len(mesh.vertices)
    arrays = []
    for name, data_type, prop, dtype, components in _STATE_ATTRIBUTES:
        attribute = _state_attribute(mesh, name, data_type)
        if attribute is None or len(attribute.data) != vertex_count:
            return layout_state.space_state(vertex_count)
        values = np.empty(vertex_count * components, dtype=dtype)
        attribute.data.foreach_get(prop, values)
        arrays.append(values)
    return layout_state.normalized_state(*arrays)


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
    if not layout_state.is_invertible(matrix):
        raise LayoutError(f"Layout '{layout.name}' has zero scale: its normals are undefined")
    return layout_state.transform_normals(matrix, normals)


def read_target(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object) -> Target:
    """The layout's evaluated target in world space, as a kernel mesh (cached by name and content).

    Raises :class:`LayoutError` (no usable target, no faces) or a kernel error (non-finite
    coordinates...), with the target's name in the message.
    """
    target = check_target(layout)
    evaluated = target.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        vertex_count = len(mesh.vertices)
        mesh.calc_loop_triangles()
        triangle_count = len(mesh.loop_triangles)
        local_vertices = np.empty(vertex_count * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", local_vertices)
        triangles = np.empty(triangle_count * 3, dtype=np.uint32)
        mesh.loop_triangles.foreach_get("vertices", triangles)
        triangle_polygons = np.empty(triangle_count, dtype=np.int32)
        mesh.loop_triangles.foreach_get("polygon_index", triangle_polygons)
    finally:
        evaluated.to_mesh_clear()
    if vertex_count == 0 or triangle_count == 0:
        raise LayoutError(f"Target '{target.name}' has no faces")
    vertices = layout_state.as_float32_points(
        layout_state.transform_points(matrix_array(evaluated.matrix_world), local_vertices.reshape(-1, 3))
    )
    triangles = np.ascontiguousarray(triangles.reshape(-1, 3))
    key = (target.name, layout_state.content_hash(vertices, triangles))
    cached = _target_cache.get(key)
    if cached is not None:
        _target_cache.move_to_end(key)
        return cached
    try:
        kernel_mesh = springwrap_kernel.TargetMesh(vertices, triangles)
    except springwrap_kernel.SpringwrapError as error:
        raise LayoutError(f"Target '{target.name}': {error}") from error
    bounding_box_min, bounding_box_max = kernel_mesh.bounding_box()
    entry = Target(
        name=target.name,
        mesh=kernel_mesh,
        triangle_polygons=triangle_polygons,
        signature=layout_state.target_signature(triangles, vertex_count),
        reattach_tolerance=layout_state.reattach_tolerance(bounding_box_min, bounding_box_max),
    )
    _target_cache[key] = entry
    while len(_target_cache) > MAX_CACHED_TARGETS:
        _target_cache.popitem(last=False)
    return entry


def clear_target_cache() -> None:
    """Drop every cached target mesh (on unregister, and for tests)."""
    _target_cache.clear()


def cached_target_count() -> int:
    """Number of target meshes currently cached."""
    return len(_target_cache)


def write_layout(layout: bpy.types.Object, positions: np.ndarray, state: LayoutState) -> None:
    """Write local positions and the per-vertex state into the layout mesh (object mode).

    The state attributes are created when missing (or replaced when one with the same name has
    another type or domain).
    """
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    positions = np.ascontiguousarray(positions, dtype=np.float32).reshape(vertex_count, 3)
    current = np.empty(vertex_count * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", current)
    if not np.array_equal(current.view(np.uint32), positions.reshape(-1).view(np.uint32)):
        mesh.vertices.foreach_set("co", positions.reshape(-1))
    for name, data_type, _prop, _dtype, _components in _STATE_ATTRIBUTES:
        if _state_attribute(mesh, name, data_type) is None:
            existing = mesh.attributes.get(name)
            if existing is not None:
                mesh.attributes.remove(existing)
            mesh.attributes.new(name, data_type, "POINT")
    values = (state.states, state.faces, state.barycentrics)
    for (name, _data_type, prop, dtype, _components), array in zip(_STATE_ATTRIBUTES, values):
        # Look each attribute up again: adding one may move the others in memory.
        mesh.attributes[name].data.foreach_set(prop, np.ascontiguousarray(array, dtype=dtype).reshape(-1))
    mesh.update()


def has_shape_keys(layout: bpy.types.Object) -> bool:
    """Whether the layout mesh has shape keys (its positions then live in the keys, not the vertices)."""
    return layout.data.shape_keys is not None


@contextlib.contextmanager
def object_mode(layout: bpy.types.Object):
    """Run the block with the layout out of edit mode, so its mesh data is current and writable.

    In edit mode the edit-mesh is flushed to the mesh on entry and rebuilt from it on exit.
    """
    was_editing = layout.mode == "EDIT"
    if was_editing:
        bpy.ops.object.mode_set(mode="OBJECT")
    try:
        yield
    finally:
        if was_editing:
            bpy.ops.object.mode_set(mode="EDIT")


def _state_attribute(mesh: bpy.types.Mesh, name: str, data_type: str):
    """The named POINT attribute when it exists with the given type, else None."""
    attribute = mesh.attributes.get(name)
    if attribute is None or attribute.domain != "POINT" or attribute.data_type != data_type:
        return None
    return attribute


# ---------------------------------------------------------------- anchors


def read_anchors(layout: bpy.types.Object) -> anchors.Anchors:
    """The layout's anchors (``Object.springwrap.anchors``) as arrays, in list order."""
    items = layout.springwrap.anchors
    count = len(items)
    arrays = []
    for name, dtype, components in _ANCHOR_FIELDS:
        values = np.empty(count * components, dtype=dtype)
        if count:
            items.foreach_get(name, values)
        arrays.append(values)
    return anchors.make_anchors(*arrays)


def write_anchors(
    layout: bpy.types.Object, anchor_list: anchors.Anchors, active_index: int = -1, signature: Optional[str] = None
) -> None:
    """Replace the layout's anchor list; make ``active_index`` active (-1 keeps the current one, clamped).

    ``signature`` (the target's topology signature the face anchors refer to) is stored when given.
    """
    settings = layout.springwrap
    items = settings.anchors
    count = anchors.anchor_count(anchor_list)
    if len(items) != count:
        items.clear()
        for _ in range(count):
            items.add()
    if count:
        for (name, dtype, _components), array in zip(_ANCHOR_FIELDS, anchor_list):
            items.foreach_set(name, np.ascontiguousarray(array, dtype=dtype).reshape(-1))
    chosen = active_index if active_index >= 0 else settings.active_anchor_index
    settings.active_anchor_index = max(anchors.clamp_active_index(chosen, count), 0)
    if signature is not None:
        settings.anchors_signature = signature


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
            positions = np.empty(vertex_count * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", positions)
            local[valid] = positions.reshape(-1, 3)[vertex_indices[valid]]
    return layout_state.transform_points(matrix_array(layout.matrix_world), local)
