"""The layout's target object: checked, read evaluated in world space, built into the kernel's ``TargetMesh``
and cached; its edges; and the weights of one of its vertex groups on the evaluated vertices.

**The cache.** A built target is kept under its name and a hash of its evaluated content, so a target
that comes back to a content it had (an undo, a modifier switched off and on) is not built again. Reading
and hashing a large target costs time too (about 1.4 s at 5M triangles), so when
:mod:`.target_changes` says no event could have changed the object since it was last read, and a cheap
sanity key still matches (the object, its name, its evaluated mesh's vertex, polygon and loop counts, its
world matrix and a few vertex positions), the entry is reused without reading the mesh at all.
"""

import collections
from typing import NamedTuple

import bpy

import numpy as np

import springwrap_kernel

from ..core import input_policy, layout_state
from ..core.errors import LayoutError
from ..core.target import Target, frame_origin, kernel_coordinates, make_target
from . import target_changes
from .evaluated_mesh import read_evaluated_mesh

MAX_CACHED_TARGETS = 2
"""Number of built target meshes kept between operations."""

SANITY_SAMPLES = 8
"""Vertex positions of the evaluated mesh compared before a cached target is reused unread."""

_target_cache: "collections.OrderedDict[tuple[str, str], Target]" = collections.OrderedDict()


class _LastRead(NamedTuple):
    """What an object looked like when it was last read in a depsgraph, and which cache entry it gave."""

    moment: int  # target_changes.moment() before the read
    sanity: tuple  # _sanity_key() then
    content_key: tuple[str, str]  # its key in _target_cache


_last_reads: dict[tuple[int, str, str], _LastRead] = {}
"""(object key, scene name, view layer name) -> the object's last read there."""

_reads = collections.Counter()
"""How many reads took each path ("unread", "hashed", "built"), for tests and benchmarks."""


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


def read_target(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object) -> Target:
    """The layout's evaluated target in world space, as a kernel mesh (cached by name and content).

    Unread when nothing can have changed it since its last read in this depsgraph (see the module's
    docstring), else read and hashed, and built only when that content is not cached.
    Raises :class:`LayoutError` (no usable target, no faces) or a kernel error (non-finite
    coordinates...), with the target's name in the message.
    """
    target = check_target(layout)
    read_key = (target_changes.object_key(target), depsgraph.scene.name, depsgraph.view_layer.name)
    last = _last_reads.get(read_key)
    sanity = _sanity_key(target.evaluated_get(depsgraph))
    if (
        last is not None
        and last.sanity == sanity
        and last.content_key in _target_cache
        and target_changes.unchanged_since(target, last.moment)
    ):
        _target_cache.move_to_end(last.content_key)
        _reads["unread"] += 1
        return _target_cache[last.content_key]
    moment = target_changes.moment()
    entry, content_key = _read_and_build(depsgraph, target)
    _last_reads[read_key] = _LastRead(moment, sanity, content_key)
    return entry


def read_object_target(depsgraph: bpy.types.Depsgraph, obj: bpy.types.Object) -> Target:
    """Any mesh object evaluated in ``depsgraph`` as a target (a sequence's object of a frame): read, hashed and
    built or found cached as :func:`read_target` does, never reused unread. Raises :class:`LayoutError` naming it."""
    if obj.type != "MESH":
        raise LayoutError(f"'{obj.name}' is not a mesh object")
    return _read_and_build(depsgraph, obj)[0]


def _sanity_key(evaluated: bpy.types.Object) -> tuple:
    """What must not differ for a cached target to be reused unread: cheap to get, without copying the mesh."""
    mesh = evaluated.data
    vertices = mesh.vertices
    count = len(vertices)
    samples = sorted({int(index) for index in np.linspace(0, count - 1, SANITY_SAMPLES)}) if count else []
    return (
        evaluated.name,
        count,
        len(mesh.polygons),
        len(mesh.loops),
        tuple(tuple(row) for row in evaluated.matrix_world),
        tuple(tuple(vertices[index].co) for index in samples),
    )


def _read_and_build(depsgraph: bpy.types.Depsgraph, target: bpy.types.Object) -> tuple[Target, tuple[str, str]]:
    """The target read and hashed, its cached entry or a new one built; and that entry's key."""
    evaluated = read_evaluated_mesh(depsgraph, target, triangles=True)
    vertex_count, triangles = evaluated.vertices.shape[0], evaluated.triangles
    if vertex_count == 0 or triangles.shape[0] == 0:
        raise LayoutError(f"Target '{target.name}' has no faces")
    vertices = np.ascontiguousarray(evaluated.vertices, dtype=np.float64)
    key = (target.name, layout_state.content_hash(vertices, triangles))
    cached = _target_cache.get(key)
    if cached is not None:
        _target_cache.move_to_end(key)
        _reads["hashed"] += 1
        return cached, key
    try:
        finite = np.isfinite(vertices).all(axis=1)
        input_policy.check_points(
            vertices if finite.all() else vertices[finite],  # the kernel names non-finite vertices itself
            lambda row: f"Target '{target.name}': a vertex",
            fix="fix the target mesh or its modifiers and transform",
        )
        origin, polygons = frame_origin(vertices), evaluated.triangle_polygons
        in_frame = kernel_coordinates(vertices, origin)
        del evaluated, vertices  # the float64 world vertices (12 bytes a triangle) not held while the kernel builds
        entry = make_target(target.name, in_frame, triangles, polygons, origin)
    except springwrap_kernel.SpringwrapError as error:
        raise LayoutError(f"Target '{target.name}': {error}") from error
    _target_cache[key] = entry
    while len(_target_cache) > MAX_CACHED_TARGETS:
        _target_cache.popitem(last=False)
    _reads["built"] += 1
    return entry, key


def clear_target_cache() -> None:
    """Drop every cached target mesh (on unregister, and for tests)."""
    _target_cache.clear()
    _last_reads.clear()
    _reads.clear()


def target_reads() -> dict[str, int]:
    """How many target reads since :func:`clear_target_cache` were "unread" (the cached mesh reused without
    reading), "hashed" (read, and its content found cached) and "built"."""
    return {path: _reads[path] for path in ("unread", "hashed", "built")}


def cached_target_count() -> int:
    """Number of target meshes currently cached."""
    return len(_target_cache)


def read_target_edges(depsgraph: bpy.types.Depsgraph, layout: bpy.types.Object) -> tuple[np.ndarray, np.ndarray]:
    """The evaluated target's vertices in world space ((V, 3) float64) and its edges ((E, 2) int64)."""
    evaluated = read_evaluated_mesh(depsgraph, check_target(layout), edges=True)
    return evaluated.vertices, evaluated.edges


# ---------------------------------------------------------------- vertex-group weights


_WEIGHT_ATTRIBUTE = "springwrap_group_weight"

_EXISTS_ATTRIBUTE = "springwrap_group_exists"


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
