"""Differences between the Blender versions the add-on supports (3.4 and later)."""

from collections.abc import Callable

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


_SELECTION_ATTRIBUTES = (("vertices", ".select_vert"), ("edges", ".select_edge"), ("polygons", ".select_poly"))
"""Where a mesh keeps the selection of each domain since Blender 3.5 (no attribute: nothing selected)."""


def deselect_all(mesh: "bpy.types.Mesh") -> None:
    """Deselect every vertex, edge and face of a mesh (object mode data).

    Since Blender 3.5 the selection is in boolean attributes: written as attributes at once (setting
    ``select`` through the vertices costs seconds on 100 000 of them); before, in the items' flags.
    """
    for domain, name in _SELECTION_ATTRIBUTES:
        attribute = mesh.attributes.get(name)
        if attribute is not None:
            attribute.data.foreach_set("value", np.zeros(len(attribute.data), dtype=bool))
        elif bpy.app.version < (3, 5, 0):
            items = getattr(mesh, domain)
            items.foreach_set("select", np.zeros(len(items), dtype=bool))


def pointer_poll(poll: Callable) -> Callable | None:
    """The ``poll`` to give a ``PointerProperty``: ``poll`` itself, or None in the PyPI bpy 4.2 module.

    The bpy 4.2 module (seen with 4.2.23) crashes when the process exits once a class with a
    PointerProperty poll callback was registered (``bpy_class_free`` runs after Python is
    finalized), even after unregistering it. The module has no user interface, and a poll only
    filters the UI's object picker (Python assignment never calls it), so nothing is lost there.
    """
    if not bpy.app.binary_path and bpy.app.version[:2] == (4, 2):
        return None
    return poll


def property_update(update: Callable) -> Callable | None:
    """The ``update`` to give a property: ``update`` itself, or None in the PyPI bpy 4.2 module.

    The same crash as :func:`pointer_poll`'s: the bpy 4.2 module (4.2.23) crashes when the process
    exits once a property with a Python ``update`` callback was registered. The module has no user
    interface (nothing toggles the property from a button), so a script that sets it there calls
    the update itself (``blender.cage_display.update_show_cage``).
    """
    if not bpy.app.binary_path and bpy.app.version[:2] == (4, 2):
        return None
    return update


# Before Blender 4.2 (seen in 3.4), foreach_get / foreach_set silently skip enum properties: set
# leaves the items unchanged and get reads zeros. Those versions go item by item.
_ENUM_FOREACH_WORKS = bpy.app.version >= (4, 2, 0)


def _is_enum(collection, name: str) -> bool:
    return len(collection) > 0 and collection[0].bl_rna.properties[name].type == "ENUM"


def foreach_get(collection, name: str, values: np.ndarray) -> None:
    """``collection.foreach_get(name, values)``, enum properties read as their item numbers."""
    if _ENUM_FOREACH_WORKS or not _is_enum(collection, name):
        collection.foreach_get(name, values)
        return
    numbers = {item.identifier: item.value for item in collection[0].bl_rna.properties[name].enum_items}
    values[:] = [numbers[getattr(item, name)] for item in collection]


def foreach_set(collection, name: str, values: np.ndarray) -> None:
    """``collection.foreach_set(name, values)``, enum properties set from their item numbers."""
    if _ENUM_FOREACH_WORKS or not _is_enum(collection, name):
        collection.foreach_set(name, values)
        return
    identifiers = {item.value: item.identifier for item in collection[0].bl_rna.properties[name].enum_items}
    for item, value in zip(collection, values.tolist()):
        setattr(item, name, identifiers[int(value)])


def set_active_color(mesh: "bpy.types.Mesh", name: str) -> None:
    """Make the colour attribute ``name`` the mesh's active and render colour (what the viewport's
    Attribute colour shows). Blender 3.5+ names them (``active_color_name``, ``default_color_name``);
    3.4 only has the ``active_color`` pointer and ``render_color_index``."""
    colors = mesh.color_attributes
    if hasattr(colors, "active_color_name"):
        colors.active_color_name = name
        colors.default_color_name = name
        return
    colors.active_color = colors[name]
    if hasattr(colors, "render_color_index"):
        colors.render_color_index = colors.find(name)


_CREASE_ATTRIBUTES = {"POINT": "crease_vert", "EDGE": "crease_edge"}


def read_creases(mesh: "bpy.types.Mesh", domain: str) -> np.ndarray | None:
    """(N,) float32 vertex (``domain='POINT'``) or edge (``'EDGE'``) creases, None when the mesh has none.

    Blender 4.0 keeps them in the FLOAT attributes ``crease_vert`` / ``crease_edge``; before, vertex
    creases were a layer of ``Mesh.vertex_creases`` and edge creases the edges' ``crease``.
    """
    items = mesh.vertices if domain == "POINT" else mesh.edges
    values = np.zeros(len(items), dtype=np.float32)
    attribute = mesh.attributes.get(_CREASE_ATTRIBUTES[domain])
    if attribute is not None and attribute.data_type == "FLOAT" and len(attribute.data) == len(items):
        attribute.data.foreach_get("value", values)
        return values
    if bpy.app.version >= (4, 0, 0):
        return None
    if domain == "EDGE" and len(items):
        items.foreach_get("crease", values)
        return values
    layers = getattr(mesh, "vertex_creases", None)
    if domain == "POINT" and layers is not None and len(layers) and len(layers[0].data) == len(items):
        layers[0].data.foreach_get("value", values)
        return values
    return None


def read_corner_normals(mesh: "bpy.types.Mesh") -> np.ndarray:
    """(C, 3) float32 normals of the mesh's face corners (custom split normals included), local space.

    Blender 4.1 computes them on demand (``Mesh.corner_normals``); before, ``calc_normals_split`` filled
    the loops' ``normal``.
    """
    normals = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    if hasattr(mesh, "corner_normals"):
        mesh.corner_normals.foreach_get("vector", normals)
    else:
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", normals)
    return normals.reshape(-1, 3)


def read_corner_vertices(mesh: "bpy.types.Mesh") -> np.ndarray:
    """(L,) uint32 vertex of each face corner: the ``.corner_vert`` attribute where Blender has it (4.0+: one
    copy, ~50 times faster than the loops' ``vertex_index`` on a large mesh), else the loops."""
    values = np.empty(len(mesh.loops), dtype=np.int32)
    attribute = mesh.attributes.get(".corner_vert")
    if attribute is not None and attribute.domain == "CORNER" and attribute.data_type == "INT":
        attribute.data.foreach_get("value", values)
    else:
        mesh.loops.foreach_get("vertex_index", values)
    return values.view(np.uint32)  # the same numbers (an int32 buffer is Blender's fast path), no copy


def read_face_corners(mesh: "bpy.types.Mesh") -> tuple[np.ndarray, np.ndarray]:
    """((sum of sizes,) uint32 corners face by face, (F,) uint32 corner count of each face). Blender 4.0+ stores
    faces as offsets into corners kept in face order, so the corners are ``.corner_vert`` as it is and the sizes
    the offsets' steps (one read); older versions may hold corners in any order: ``loop_start`` and
    ``loop_total`` place them."""
    face_count = len(mesh.polygons)
    loop_vertices = read_corner_vertices(mesh)
    # Into uint32 (the property's own type): one copy of Blender's face offsets; an int32 buffer takes Blender's
    # per-face path, about a thousand times slower (28 ms against 0.1 ms for a million faces).
    loop_starts = np.empty(face_count, dtype=np.uint32)
    mesh.polygons.foreach_get("loop_start", loop_starts)
    if bpy.app.version >= (4, 0, 0):
        return loop_vertices, np.diff(loop_starts, append=np.uint32(loop_vertices.size))
    sizes = np.empty(face_count, dtype=np.uint32)
    mesh.polygons.foreach_get("loop_total", sizes)
    starts = loop_starts.astype(np.int64)
    # Corners face by face: loop_start + 0 .. loop_total - 1.
    offsets = np.repeat(starts - np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)[:-1]]), sizes)
    return loop_vertices[np.arange(int(sizes.sum()), dtype=np.int64) + offsets], sizes
