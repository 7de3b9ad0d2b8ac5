"""The only module that moves data between ``bpy`` and the Springwrap kernel.

Reads the layout (positions, selection, state attributes, anchors) and the evaluated target into
numpy arrays, builds and caches the kernel's ``TargetMesh``, and writes positions, state and
anchors back. Bulk data moves through ``foreach_get`` / ``foreach_set``; there is no per-vertex
Python loop (except over anchors in edit mode, which are few).
"""

import collections
import contextlib
from typing import NamedTuple, Optional

import bmesh
import bpy
import numpy as np
import springwrap_kernel

from . import anchors, compat, curves, layout_state
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


def write_layout(
    layout: bpy.types.Object, positions: np.ndarray, state: LayoutState, rest: Optional[np.ndarray] = None
) -> None:
    """Write local positions and the per-vertex state into the layout mesh (object mode).

    The state attributes are created when missing (or replaced when one with the same name has
    another type or domain). A layout without a rest shape gets one first: ``rest`` when given,
    else its positions before this write (the template as made, before Springwrap moved it).
    """
    mesh = layout.data
    vertex_count = len(mesh.vertices)
    positions = np.ascontiguousarray(positions, dtype=np.float32).reshape(vertex_count, 3)
    current = np.empty(vertex_count * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", current)
    if read_rest(layout) is None:
        write_rest(layout, current if rest is None else rest)
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


def read_rest(layout: bpy.types.Object) -> Optional[np.ndarray]:
    """The layout's stored rest shape (local (N, 3) float32), or None when it has none (object mode)."""
    attribute = _state_attribute(layout.data, layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR")
    if attribute is None:
        return None
    values = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    attribute.data.foreach_get("vector", values)
    return values.reshape(-1, 3)


def write_rest(layout: bpy.types.Object, positions: np.ndarray) -> None:
    """Store ``positions`` (local (N, 3)) as the layout's rest shape, replacing any (object mode)."""
    mesh = layout.data
    existing = mesh.attributes.get(layout_state.REST_ATTRIBUTE)
    if existing is not None and _state_attribute(mesh, layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR") is None:
        mesh.attributes.remove(existing)
    if mesh.attributes.get(layout_state.REST_ATTRIBUTE) is None:
        mesh.attributes.new(layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR", "POINT")
    values = np.ascontiguousarray(positions, dtype=np.float32).reshape(-1)
    mesh.attributes[layout_state.REST_ATTRIBUTE].data.foreach_set("vector", values)


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


# ---------------------------------------------------------------- object transform


def read_parent_matrix(layout: bpy.types.Object) -> np.ndarray:
    """The 4x4 matrix taking the object's basis (location, rotation, scale) to world space.

    ``matrix_world = parent_matrix @ matrix_basis``: the parent's world matrix times the parent
    inverse, identity for an object without a parent. Raises :class:`LayoutError` when the basis
    has zero scale (the parent part is then unknown).
    """
    basis = matrix_array(layout.matrix_basis)
    if not layout_state.is_invertible(basis):
        raise LayoutError(f"Layout '{layout.name}' has zero scale: its transform cannot be aligned")
    return matrix_array(layout.matrix_world) @ layout_state.inverse_matrix(basis)


def write_object_basis(layout: bpy.types.Object, basis: np.ndarray) -> None:
    """Set the object's location, rotation and scale from a 4x4 basis matrix (no shear)."""
    from mathutils import Matrix

    layout.matrix_basis = Matrix(np.asarray(basis, dtype=np.float64).tolist())


# ---------------------------------------------------------------- anchors


def read_anchors(layout: bpy.types.Object) -> anchors.Anchors:
    """The layout's anchors (``Object.springwrap.anchors``) as arrays, in list order."""
    items = layout.springwrap.anchors
    count = len(items)
    arrays = []
    for name, dtype, components in _ANCHOR_FIELDS:
        values = np.empty(count * components, dtype=dtype)
        if count:
            compat.foreach_get(items, name, values)
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
            compat.foreach_set(items, name, np.ascontiguousarray(array, dtype=dtype).reshape(-1))
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


# ---------------------------------------------------------------- wrap


_ABSENT = "absent"
_FOREIGN = "foreign"


class LayoutSnapshot(NamedTuple):
    """The layout's positions and state attributes as they were, to put back bit for bit (a cancelled wrap)."""

    positions: np.ndarray  # (N * 3,) float32, as read
    # attribute name -> its raw values; _ABSENT when it did not exist; _FOREIGN when an attribute of
    # that name has another type or domain (wrap frames leave it alone, see write_wrap_frame)
    attributes: dict


def take_snapshot(layout: bpy.types.Object) -> LayoutSnapshot:
    """Copy what a wrap in progress writes: positions and the state attributes (object mode)."""
    mesh = layout.data
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    attributes = {}
    for name, data_type, prop, dtype, components in _STATE_ATTRIBUTES:
        attribute = _state_attribute(mesh, name, data_type)
        if attribute is None:
            attributes[name] = _ABSENT if mesh.attributes.get(name) is None else _FOREIGN
            continue
        values = np.empty(len(attribute.data) * components, dtype=dtype)
        attribute.data.foreach_get(prop, values)
        attributes[name] = values
    return LayoutSnapshot(positions, attributes)


def restore_snapshot(layout: bpy.types.Object, snapshot: LayoutSnapshot) -> None:
    """Put back what :func:`take_snapshot` copied: positions and state attributes, bit for bit.

    An attribute that did not exist is removed again; one that existed gets its values back.
    """
    mesh = layout.data
    mesh.vertices.foreach_set("co", snapshot.positions)
    for name, data_type, prop, _dtype, _components in _STATE_ATTRIBUTES:
        saved = snapshot.attributes[name]
        if isinstance(saved, str):
            if saved == _ABSENT and mesh.attributes.get(name) is not None:
                mesh.attributes.remove(mesh.attributes[name])
            continue
        if _state_attribute(mesh, name, data_type) is None:  # only if something else replaced it meanwhile
            if mesh.attributes.get(name) is not None:
                mesh.attributes.remove(mesh.attributes[name])
            mesh.attributes.new(name, data_type, "POINT")
        mesh.attributes[name].data.foreach_set(prop, saved)
    mesh.update()


def write_wrap_frame(layout: bpy.types.Object, positions: np.ndarray, state: LayoutState) -> None:
    """An intermediate frame of a wrap: local positions and the state, without replacing attributes.

    The state attributes are created when missing, but an attribute of the same name with
    another type is left alone (only the final write replaces it, so that a cancel can restore
    everything). Creates no undo step.
    """
    mesh = layout.data
    mesh.vertices.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).reshape(-1))
    values = (state.states, state.faces, state.barycentrics)
    for (name, data_type, prop, dtype, _components), array in zip(_STATE_ATTRIBUTES, values):
        if mesh.attributes.get(name) is None:
            mesh.attributes.new(name, data_type, "POINT")
        elif _state_attribute(mesh, name, data_type) is None:
            continue
        mesh.attributes[name].data.foreach_set(prop, np.ascontiguousarray(array, dtype=dtype).reshape(-1))
    mesh.update()


def read_layout_topology(layout: bpy.types.Object):
    """The layout mesh's faces, edges and seams (object mode data), as a ``subdivision.LayoutTopology``.

    Every edge is listed (those on no face are loose curves), and the seam-marked ones as patch
    boundaries. Raises :class:`LayoutError` for a layout with neither faces nor edges.
    """
    from . import operations, subdivision

    mesh = layout.data
    face_count, edge_count = len(mesh.polygons), len(mesh.edges)
    operations.check_wrappable(layout.name, face_count, edge_count)
    loop_vertices = np.empty(len(mesh.loops), dtype=np.uint32)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    loop_starts = np.empty(face_count, dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", loop_starts)
    face_sizes = np.empty(face_count, dtype=np.uint32)
    mesh.polygons.foreach_get("loop_total", face_sizes)
    # Corners face by face: loop_start + 0 .. loop_total - 1 (loops need not be in face order).
    offsets = np.repeat(loop_starts - np.concatenate([[0], np.cumsum(face_sizes, dtype=np.int64)[:-1]]), face_sizes)
    face_corners = loop_vertices[np.arange(int(face_sizes.sum()), dtype=np.int64) + offsets]
    edges = np.empty(edge_count * 2, dtype=np.uint32)
    mesh.edges.foreach_get("vertices", edges)
    edges = edges.reshape(-1, 2)
    seam_flags = np.empty(edge_count, dtype=bool)
    mesh.edges.foreach_get("use_seam", seam_flags)
    return subdivision.LayoutTopology(
        len(mesh.vertices),
        np.ascontiguousarray(face_corners, dtype=np.uint32),
        np.ascontiguousarray(face_sizes, dtype=np.uint32),
        np.ascontiguousarray(edges),
        np.ascontiguousarray(edges[seam_flags]),
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


_WEIGHT_ATTRIBUTE = "springwrap_group_weight"
_EXISTS_ATTRIBUTE = "springwrap_group_exists"


def read_layout_group(layout: bpy.types.Object, group_name: str) -> tuple[np.ndarray, np.ndarray]:
    """((N,) float32 weights, (N,) bool membership) of the layout's vertex group ``group_name`` on its own
    (base) mesh. Raises :class:`LayoutError` when the layout has no such group."""
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
    return weights, member


def read_vertex_group_weights(context, target_object: bpy.types.Object, group_name: str) -> np.ndarray:
    """(V,) float32 weights of ``group_name`` on the *evaluated* target's vertices (0 outside the group).

    Blender has no bulk reader of vertex-group weights, so they are read through geometry nodes:
    a temporary copy of the evaluated mesh gets a node group storing the weights (the
    "Named Attribute" node reads vertex groups) as a float attribute, read with ``foreach_get``;
    the copy, its object and the node group are removed again.

    Modifiers: deforming and most generating modifiers carry vertex groups along (Subdivision
    Surface interpolates the weights, Mirror and Array copy them), so the weights are those of the
    evaluated vertices. A modifier that rebuilds the mesh (Remesh, some geometry nodes) drops the
    groups; then, when the evaluated mesh still has as many vertices as the base mesh (the stack
    only moved them), the base mesh's weights are used vertex for vertex, otherwise it is an error.
    Raises :class:`LayoutError` when the target has no such group or it cannot be followed.
    """
    if target_object.vertex_groups.get(group_name) is None:
        raise LayoutError(f"Target '{target_object.name}' has no vertex group '{group_name}'")
    depsgraph = context.evaluated_depsgraph_get()
    evaluated = target_object.evaluated_get(depsgraph)
    weights, exists = _group_weights_of(context, evaluated, depsgraph, group_name)
    if exists:
        return weights
    base_count = len(target_object.data.vertices)
    if base_count != weights.shape[0]:
        raise LayoutError(
            f"The modifiers of target '{target_object.name}' drop the vertex group '{group_name}' and change its "
            f"vertex count ({base_count} -> {weights.shape[0]}): the unreliable vertices cannot be followed"
        )
    base_weights, _exists = _group_weights_of(context, target_object.original, None, group_name)
    return base_weights


def _group_weights_of(context, source: bpy.types.Object, depsgraph, group_name: str) -> tuple[np.ndarray, bool]:
    """Weights of ``group_name`` on the mesh of ``source`` (evaluated or original), and whether it has the group."""
    mesh = bpy.data.meshes.new_from_object(source, preserve_all_data_layers=True, depsgraph=depsgraph)
    probe = tree = None
    try:
        probe = bpy.data.objects.new("springwrap weight probe", mesh)
        tree = _weight_node_group(group_name)
        modifier = probe.modifiers.new("springwrap weights", "NODES")
        modifier.node_group = tree
        context.scene.collection.objects.link(probe)
        evaluated = probe.evaluated_get(context.evaluated_depsgraph_get())
        result = evaluated.to_mesh()
        try:
            count = len(result.vertices)
            weights = np.zeros(count, dtype=np.float32)
            attribute = result.attributes.get(_WEIGHT_ATTRIBUTE)
            if attribute is not None and count:
                attribute.data.foreach_get("value", weights)
            exists = True
            flag = result.attributes.get(_EXISTS_ATTRIBUTE)
            if flag is not None and count:
                flags = np.empty(count, dtype=bool)
                flag.data.foreach_get("value", flags)
                exists = bool(flags.any())
        finally:
            evaluated.to_mesh_clear()
    finally:
        if probe is not None:
            bpy.data.objects.remove(probe)
        bpy.data.meshes.remove(mesh)
        if tree is not None:
            bpy.data.node_groups.remove(tree)
    return weights, exists


def _weight_node_group(group_name: str):
    """Geometry nodes storing the named vertex group (and whether it exists) as point attributes."""
    tree = bpy.data.node_groups.new("springwrap weights", "GeometryNodeTree")
    if hasattr(tree, "interface"):  # Blender 4.0+
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
    group_input = tree.nodes.new("NodeGroupInput")
    group_output = tree.nodes.new("NodeGroupOutput")
    named = tree.nodes.new("GeometryNodeInputNamedAttribute")
    named.data_type = "FLOAT"
    named.inputs["Name"].default_value = group_name
    geometry = group_input.outputs[0]
    stores = [(_WEIGHT_ATTRIBUTE, "FLOAT", _socket(named.outputs, "Attribute"))]
    if "Exists" in named.outputs:  # Blender 4.0+
        stores.append((_EXISTS_ATTRIBUTE, "BOOLEAN", named.outputs["Exists"]))
    for attribute_name, data_type, value in stores:
        store = tree.nodes.new("GeometryNodeStoreNamedAttribute")
        store.data_type = data_type
        store.domain = "POINT"
        store.inputs["Name"].default_value = attribute_name
        tree.links.new(geometry, store.inputs["Geometry"])
        tree.links.new(value, _socket(store.inputs, "Value"))
        geometry = store.outputs["Geometry"]
    tree.links.new(geometry, group_output.inputs[0])
    return tree


def _socket(sockets, name: str):
    """The enabled socket called ``name`` (before Blender 4.0 a node has one per data type, all so called)."""
    for socket in sockets:
        if socket.name == name and socket.enabled:
            return socket
    return sockets[name]


def make_wrap_solver(target: Target, structure, inputs, parameters):
    """A kernel ``WrapSolver`` for the prepared inputs (``operations.WrapInputs``, world space)."""
    curve_arguments = {}
    if inputs.curve_vertices is not None:
        curve_arguments = {
            "curve_vertices": inputs.curve_vertices,
            "curve_vertex_counts": inputs.curve_vertex_counts,
            "curve_points": inputs.curve_points,
            "curve_point_counts": inputs.curve_point_counts,
        }
    if getattr(inputs, "plane_vertices", None) is not None:
        curve_arguments |= {
            "plane_vertices": inputs.plane_vertices,
            "plane_point": tuple(float(value) for value in inputs.plane_point),
            "plane_normal": tuple(float(value) for value in inputs.plane_normal),
            "plane_slide": bool(inputs.plane_slide),
        }
    return springwrap_kernel.WrapSolver(
        target.mesh,
        structure,
        inputs.states,
        inputs.triangles,
        inputs.barycentrics,
        inputs.positions,
        anchor_vertices=inputs.anchor_vertices,
        anchor_triangles=inputs.anchor_triangles,
        anchor_barycentrics=inputs.anchor_barycentrics,
        anchor_positions=inputs.anchor_positions,
        unreliable_triangles=inputs.unreliable_triangles,
        rest_positions=inputs.rest_positions,
        settings=parameters.settings,
        stiffness=getattr(inputs, "stiffness", None),
        free_vertices=getattr(inputs, "free_vertices", None),
        **curve_arguments,
    )


# ---------------------------------------------------------------- curve constraints


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


def read_target_edges(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object) -> tuple[np.ndarray, np.ndarray]:
    """The evaluated target's vertices in world space ((V, 3) float64) and its edges ((E, 2) int64)."""
    target = check_target(layout)
    evaluated = target.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", positions)
        edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
        mesh.edges.foreach_get("vertices", edges)
    finally:
        evaluated.to_mesh_clear()
    world = layout_state.transform_points(matrix_array(evaluated.matrix_world), positions.reshape(-1, 3))
    return world, edges.reshape(-1, 2)


def read_curve_polyline(depsgraph: bpy.types.Depsgraph, curve_object: bpy.types.Object) -> np.ndarray:
    """(P, 3) float64 world points of an evaluated curve object, in order along its one open spline.

    Raises :class:`LayoutError` when it is not a curve object, or not one open spline of at least two points.
    """
    if curve_object is None or curve_object.type != "CURVE":
        raise LayoutError("The curve constraint's curve object is missing or not a curve")
    evaluated = curve_object.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        if mesh is None:
            raise LayoutError(f"Curve '{curve_object.name}' has no points")
        positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", positions)
        edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
        mesh.edges.foreach_get("vertices", edges)
    finally:
        evaluated.to_mesh_clear()
    positions = positions.reshape(-1, 3)
    if positions.shape[0] < 2:
        raise LayoutError(f"Curve '{curve_object.name}' has fewer than two points")
    try:
        order = curves.chain_from_edges(edges)
    except LayoutError as error:
        raise LayoutError(f"Curve '{curve_object.name}' is not one open spline: {error}") from error
    if order.size != positions.shape[0]:
        raise LayoutError(f"Curve '{curve_object.name}' has several splines: a constraint follows one open spline")
    return layout_state.transform_points(matrix_array(evaluated.matrix_world), positions[order])


def read_curve_constraints(layout: bpy.types.Object) -> list:
    """The layout's curve constraints as stored (cached polylines), as ``curves.CurveConstraint``, in list order."""
    constraints = []
    for item in layout.springwrap.curve_constraints:
        points = np.empty(len(item.points) * 3, dtype=np.float64)
        if len(item.points):
            item.points.foreach_get("co", points)
        constraints.append(
            curves.make_constraint(
                curves.parse_indices(item.layout_vertices),
                points,
                item.source_kind,
                curves.parse_indices(item.target_vertices),
                item.curve_object,
            )
        )
    return constraints


def write_curve_constraints(layout: bpy.types.Object, constraints, active_index: int = -1) -> None:
    """Replace the layout's curve constraints; make ``active_index`` active (-1 keeps the current one, clamped)."""
    settings = layout.springwrap
    items = settings.curve_constraints
    items.clear()
    for constraint in constraints:
        item = items.add()
        item.layout_vertices = curves.format_indices(constraint.layout_vertices)
        item.source_kind = constraint.source_kind
        item.curve_object = constraint.curve_object if constraint.source_kind == curves.CURVE_OBJECT else None
        item.target_vertices = curves.format_indices(constraint.target_vertices)
        for _ in range(constraint.points.shape[0]):
            item.points.add()
        if constraint.points.shape[0]:
            item.points.foreach_set("co", np.ascontiguousarray(constraint.points, dtype=np.float32).reshape(-1))
    chosen = active_index if active_index >= 0 else settings.active_curve_constraint_index
    settings.active_curve_constraint_index = max(anchors.clamp_active_index(chosen, len(items)), 0)


def resolve_curve_constraints(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object, constraints) -> list:
    """The constraints with their target polylines read again from their sources (evaluated, world space).

    A curve object's polyline is oriented (and a closed one cut) to follow the cached polyline as a
    whole (or, with no cache, the chain: ``curves.orient_to_chain``); a target edge chain is read
    at its target vertices.
    Raises :class:`LayoutError` naming the constraint whose source is gone or unusable.
    """
    constraints = list(constraints)
    if not constraints:
        return []
    target_positions = None
    resolved = []
    for number, constraint in enumerate(constraints):
        if constraint.source_kind == curves.CURVE_OBJECT:
            try:
                points = read_curve_polyline(depsgraph, constraint.curve_object)
            except LayoutError as error:
                raise LayoutError(f"Curve constraint {number}: {error}") from error
            if constraint.points.shape[0] >= 2:
                reference = constraint.points
            else:
                reference = read_world_vertex_positions(layout, constraint.layout_vertices)
            points = curves.orient_to_chain(points, reference)
        else:
            if target_positions is None:
                target_positions, _edges = read_target_edges(depsgraph, layout)
            indices = constraint.target_vertices
            bad = indices[(indices < 0) | (indices >= target_positions.shape[0])]
            if bad.size or indices.size < 2:
                raise LayoutError(
                    f"Curve constraint {number} follows target vertices the target no longer has "
                    f"(it has {target_positions.shape[0]}): remove it and pair the chain again"
                )
            points = target_positions[indices]
        resolved.append(constraint._replace(points=points))
    return resolved


def leave_edit_mode(layout: bpy.types.Object) -> bool:
    """Switch the layout to object mode when it is in edit mode (flushing the edit-mesh); whether it was."""
    if layout.mode != "EDIT":
        return False
    bpy.ops.object.mode_set(mode="OBJECT")
    return True


def enter_edit_mode() -> None:
    """Switch the active object back into edit mode (after :func:`leave_edit_mode`)."""
    bpy.ops.object.mode_set(mode="EDIT")


# ---------------------------------------------------------------- feature detection

FEATURE_COLLECTION = "Springwrap Features"
"""Collection holding the feature curve objects of ``springwrap.detect_features``."""
FEATURE_COLOR_ATTRIBUTE = "springwrap_curvature"
"""Point colour attribute of the regions (flat / convex / concave / saddle)."""
FEATURE_SOURCE_PROPERTY = "springwrap_feature_source"
"""Custom property of a feature curve object: the name of the mesh object it was detected on."""
FEATURE_KIND_PROPERTY = "springwrap_feature"
"""Custom property of a feature curve object: ``RIDGE`` or ``VALLEY``."""


class FeatureMesh(NamedTuple):
    """A mesh object's evaluated geometry in world space, as the kernel takes it."""

    vertices: np.ndarray  # (V, 3) float32 world positions of the evaluated mesh
    triangles: np.ndarray  # (T, 3) uint32 loop triangles
    base_vertex_count: int  # vertices of the object's own mesh (colours go there)


def read_feature_mesh(depsgraph: bpy.types.Depsgraph, obj: bpy.types.Object) -> FeatureMesh:
    """The evaluated mesh of ``obj`` in world space; raises :class:`LayoutError` when it has no faces."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        local = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", local)
        triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.uint32)
        mesh.loop_triangles.foreach_get("vertices", triangles)
    finally:
        evaluated.to_mesh_clear()
    if local.size == 0 or triangles.size == 0:
        raise LayoutError(f"'{obj.name}' has no faces: there is no surface to detect features on")
    world = layout_state.transform_points(matrix_array(evaluated.matrix_world), local.reshape(-1, 3))
    return FeatureMesh(
        vertices=layout_state.as_float32_points(world),
        triangles=np.ascontiguousarray(triangles.reshape(-1, 3)),
        base_vertex_count=len(obj.data.vertices),
    )


def detect_features(feature_mesh: FeatureMesh, scale: float, **settings):
    """``springwrap_kernel.TargetMesh.detect_features`` on the mesh (raises one of :data:`ERRORS`)."""
    mesh = springwrap_kernel.TargetMesh(feature_mesh.vertices, feature_mesh.triangles)
    return mesh.detect_features(scale, **settings)


def write_feature_colors(obj: bpy.types.Object, colors: np.ndarray) -> None:
    """Store (V, 4) RGBA colours as the point colour attribute ``springwrap_curvature`` of ``obj``'s
    mesh (replacing one of another type) and make it the active and render colour (object mode)."""
    mesh = obj.data
    existing = mesh.attributes.get(FEATURE_COLOR_ATTRIBUTE)
    if existing is not None and (existing.domain != "POINT" or existing.data_type != "FLOAT_COLOR"):
        mesh.attributes.remove(existing)
        existing = None
    if existing is None:
        mesh.attributes.new(FEATURE_COLOR_ATTRIBUTE, "FLOAT_COLOR", "POINT")
    values = np.ascontiguousarray(colors, dtype=np.float32).reshape(-1)
    mesh.attributes[FEATURE_COLOR_ATTRIBUTE].data.foreach_set("color", values)
    compat.set_active_color(mesh, FEATURE_COLOR_ATTRIBUTE)
    mesh.update()


def remove_feature_curves(source_name: str) -> int:
    """Remove the feature curve objects detected on the object called ``source_name`` (and their
    curve data when nothing else uses it); how many were removed."""
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        return 0
    doomed = [obj for obj in collection.objects if obj.get(FEATURE_SOURCE_PROPERTY) == source_name]
    for obj in doomed:
        data = obj.data
        bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            bpy.data.curves.remove(data)
    return len(doomed)


def write_feature_curves(context, source: bpy.types.Object, curves) -> list:
    """One poly-curve object per feature curve (world space, identity transform), in the collection
    ``Springwrap Features`` (made and linked to the scene when missing), named by kind; each an open
    spline, a closed curve ending on its first point again, so that it can be a curve constraint's
    target. Replaces the curves detected on ``source`` before. Returns the new objects."""
    remove_feature_curves(source.name)
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        collection = bpy.data.collections.new(FEATURE_COLLECTION)
    if collection not in context.scene.collection.children_recursive:
        context.scene.collection.children.link(collection)
    created = []
    counts = collections.Counter()
    for curve in curves:
        counts[curve.kind] += 1
        name = f"{source.name} {curve.kind.title()} {counts[curve.kind]}"
        points = np.asarray(curve.points, dtype=np.float32)
        if curve.closed:
            points = np.concatenate([points, points[:1]])
        data = bpy.data.curves.new(name, "CURVE")
        data.dimensions = "3D"
        spline = data.splines.new("POLY")
        spline.points.add(points.shape[0] - 1)
        homogeneous = np.concatenate([points, np.ones((points.shape[0], 1), dtype=np.float32)], axis=1)
        spline.points.foreach_set("co", np.ascontiguousarray(homogeneous).reshape(-1))
        obj = bpy.data.objects.new(name, data)
        obj[FEATURE_SOURCE_PROPERTY] = source.name
        obj[FEATURE_KIND_PROPERTY] = curve.kind
        collection.objects.link(obj)
        created.append(obj)
    return created


# ---------------------------------------------------------------- mirroring

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
    existing = mesh.attributes.get(_MIRROR_SOURCE_ATTRIBUTE)
    if existing is not None:
        mesh.attributes.remove(existing)
    mesh.attributes.new(_MIRROR_SOURCE_ATTRIBUTE, "INT", "POINT")
    mesh.attributes[_MIRROR_SOURCE_ATTRIBUTE].data.foreach_set("value", np.arange(count, dtype=np.int32))
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
    attribute = mesh.attributes[_MIRROR_SOURCE_ATTRIBUTE]
    source = np.empty(len(mesh.vertices), dtype=np.int32)
    attribute.data.foreach_get("value", source)
    mesh.attributes.remove(mesh.attributes[_MIRROR_SOURCE_ATTRIBUTE])
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
    loop_faces[np.arange(int(totals.sum()), dtype=np.int64) + offsets] = np.repeat(np.arange(len(mesh.polygons)), totals)
    vertex_flags[loop_vertices[face_flags[loop_faces]]] = True
    edge_vertices = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", edge_vertices)
    edge_flags = vertex_flags[edge_vertices.reshape(-1, 2)].all(axis=1)
    mesh.polygons.foreach_set("select", face_flags)
    mesh.edges.foreach_set("select", edge_flags)
    mesh.vertices.foreach_set("select", vertex_flags)
    mesh.update()
