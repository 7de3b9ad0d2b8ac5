"""The quality read-out on the layout object: measured (``core.quality``) from its positions, rest shape and
faces against its target, written as three attributes, and read back (the heat-map, Select Problems).

- ``springwrap_distance`` (POINT, FLOAT): distance to the target surface, world units;
- ``springwrap_stretch`` (POINT, FLOAT): mean edge length now / at rest, 1 = unchanged;
- ``springwrap_flipped`` (FACE, BOOLEAN): the face is turned over against its rest shape (a fold).

Snap, project, the wrap (its one finish, ``WrapSession.finish``: the operator, the live wrap, the mirror and
the scripts) and the mirror write them as part of their own write, so one undo step holds both. Object mode
data only.
"""

import bpy

import bmesh
import numpy as np

from ..core import quality, transforms
from ..core.quality import Readout
from ..core.target import Target
from ..core.transforms import matrix_array
from . import attributes
from . import layout as layout_data


def measure_layout(
    layout: bpy.types.Object,
    target: Target,
    local_positions: np.ndarray | None = None,
    rest: np.ndarray | None = None,
    topology=None,
    state=None,
) -> Readout:
    """The read-out of ``layout`` at ``local_positions`` ((N, 3), default: as stored) on ``target``.

    ``rest`` (local (N, 3)): the rest shape to measure the stretch against; default the stored one, else the
    positions stored now (what the layout's first write keeps as its rest shape). ``topology``: the layout's
    ``LayoutTopology`` when the caller has it. ``state``: the face-points at those positions (default: the
    stored ones when the positions are), where the distances' searches start. Writes nothing.
    """
    mesh = layout.data
    stored = None if local_positions is not None else attributes.read_positions(mesh).reshape(-1, 3)
    # As they will be stored (float32): the read-out describes the layout the artist gets.
    local_positions = stored if local_positions is None else np.asarray(local_positions, np.float32).reshape(-1, 3)
    if rest is None:
        rest = attributes.read_rest(layout)
        if rest is None:
            rest = attributes.read_positions(mesh).reshape(-1, 3) if stored is None else stored
    if topology is None:
        topology = layout_data.read_layout_topology(layout, seams=False)
    if state is None and local_positions is stored:
        state = attributes.read_state(mesh)  # the stored face-points, where the stored positions are
    return quality.measure_placed(
        local_positions, rest, matrix_array(layout.matrix_world), topology, target.mesh, state
    )


def write_readout(layout: bpy.types.Object, readout: Readout) -> None:
    """Write the read-out's three attributes (created, or replaced when one of those names has another type)."""
    mesh = layout.data
    attributes.write_point_attribute(mesh, quality.DISTANCE_ATTRIBUTE, "FLOAT", readout.distances)
    attributes.write_point_attribute(mesh, quality.STRETCH_ATTRIBUTE, "FLOAT", readout.stretch)
    attributes.write_attribute(mesh, quality.FLIPPED_ATTRIBUTE, "BOOLEAN", "FACE", readout.flipped)
    mesh.update()


def update_layout(layout: bpy.types.Object, target: Target) -> Readout:
    """Measure the layout as it is now and write the attributes (the command line's last step)."""
    readout = measure_layout(layout, target)
    write_readout(layout, readout)
    return readout


_object_mode_readouts: dict = {}
"""Mesh pointer -> the read-out last read in object mode: Blender 3.x's bmesh has no boolean layers, so in edit
mode the flips come from here."""


def read_readout(layout: bpy.types.Object) -> Readout | None:
    """The read-out stored on the layout, or None when one of its attributes is missing or does not fit the mesh
    (another type, or the mesh's vertex or face count changed since). The diagonal is the layout's now.

    In edit mode (the heat-map while the artist fixes what Select Problems selected) the values are read from
    the edit-mesh's layers."""
    mesh = layout.data
    if mesh.is_editmode:
        return _read_edit_readout(layout)
    distances = attributes.read_point_attribute(mesh, quality.DISTANCE_ATTRIBUTE, "FLOAT")
    stretch = attributes.read_point_attribute(mesh, quality.STRETCH_ATTRIBUTE, "FLOAT")
    flipped = attributes.read_attribute(mesh, quality.FLIPPED_ATTRIBUTE, "BOOLEAN", "FACE")
    if distances is None or stretch is None or flipped is None:
        return None
    if distances.size != len(mesh.vertices) or flipped.size != len(mesh.polygons):
        return None
    world = transforms.transform_points(matrix_array(layout.matrix_world), attributes.read_positions(mesh))
    readout = Readout(
        distances=distances.astype(np.float64),
        stretch=stretch.astype(np.float64),
        flipped=flipped.astype(bool),
        diagonal=quality.bounding_diagonal(world),
    )
    _object_mode_readouts[mesh.as_pointer()] = readout
    return readout


def _read_edit_readout(layout: bpy.types.Object) -> Readout | None:
    """:func:`read_readout` from the edit-mesh (one Python loop over its elements: the heat-map reads it once
    per change)."""
    editable = bmesh.from_edit_mesh(layout.data)
    distance_layer = editable.verts.layers.float.get(quality.DISTANCE_ATTRIBUTE)
    stretch_layer = editable.verts.layers.float.get(quality.STRETCH_ATTRIBUTE)
    if distance_layer is None or stretch_layer is None:
        return None
    bool_layers = getattr(editable.faces.layers, "bool", None)  # Blender 4.0+
    flipped_layer = None if bool_layers is None else bool_layers.get(quality.FLIPPED_ATTRIBUTE)
    if flipped_layer is not None:
        flipped = np.array([face[flipped_layer] for face in editable.faces], dtype=bool)
    else:
        remembered = _object_mode_readouts.get(layout.data.as_pointer())
        if remembered is None or remembered.flipped.size != len(editable.faces):
            return None
        flipped = remembered.flipped
    local = np.array([vertex.co for vertex in editable.verts], dtype=np.float64).reshape(-1, 3)
    world = transforms.transform_points(matrix_array(layout.matrix_world), local)
    return Readout(
        distances=np.array([vertex[distance_layer] for vertex in editable.verts], dtype=np.float64),
        stretch=np.array([vertex[stretch_layer] for vertex in editable.verts], dtype=np.float64),
        flipped=flipped,
        diagonal=quality.bounding_diagonal(world),
    )


MISSING_READOUT = (
    "Layout '{name}' has no quality read-out: Snap, Project, Wrap or Mirror (with a target) writes it "
    "(attributes springwrap_distance, springwrap_stretch, springwrap_flipped)"
)
"""The refusal when the read-out is needed and missing."""


def hidden(layout: bpy.types.Object, domain: str) -> np.ndarray:
    """(N,) bool: which vertices (``'POINT'``) or faces (``'FACE'``) are hidden (object mode data)."""
    elements = layout.data.vertices if domain == "POINT" else layout.data.polygons
    flags = np.empty(len(elements), dtype=bool)
    elements.foreach_get("hide", flags)
    return flags


def select_vertices(layout: bpy.types.Object, mask: np.ndarray) -> None:
    """Select exactly the vertices in ``mask`` ((N,) bool, hidden ones left out), the edges between two of them and
    the faces all of whose corners are selected (as Blender's vertex select mode flushes); object mode."""
    mesh = layout.data
    vertex_flags = np.asarray(mask, dtype=bool).reshape(-1) & ~hidden(layout, "POINT")
    edge_vertices = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edge_vertices)
    loop_vertices = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    starts = np.empty(len(mesh.polygons), dtype=np.int64)
    totals = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    loop_faces = np.full(len(mesh.loops), -1, dtype=np.int64)
    for offset in range(int(totals.max()) if totals.size else 0):  # corner by corner: a few passes
        has = totals > offset
        loop_faces[starts[has] + offset] = np.flatnonzero(has)
    used = loop_faces >= 0
    selected_corners = np.bincount(
        loop_faces[used], weights=vertex_flags[loop_vertices[used]], minlength=len(mesh.polygons)
    )
    mesh.vertices.foreach_set("select", vertex_flags)
    mesh.edges.foreach_set("select", vertex_flags[edge_vertices.reshape(-1, 2)].all(axis=1))
    mesh.polygons.foreach_set("select", (selected_corners == totals) & ~hidden(layout, "FACE"))
    mesh.update()


def read_triangles(layout: bpy.types.Object) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The layout's faces as triangles for the heat-map: ((3T, 3) float32 world corner positions, (3T,) their
    vertices, (3T,) their faces), or None when there is nothing to draw.

    Each face is cut as a fan from its first corner (read from the mesh data's loops, never from Blender's
    loop triangles, which a draw callback must not make Blender compute). Faces are the mesh data's (as in
    object mode); in edit mode the positions are the edit-mesh's (they follow the artist's edits), and nothing
    is drawn once its vertex count differs from the mesh data's.
    """
    mesh = layout.data
    face_count = len(mesh.polygons)
    if not face_count:
        return None
    loop_vertices = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    starts = np.empty(face_count, dtype=np.int64)
    totals = np.empty(face_count, dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    fans = np.maximum(totals - 2, 0)
    triangle_faces = np.repeat(np.arange(face_count), fans)
    step = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans)  # 0 .. fans - 1 in each face
    first = starts[triangle_faces]
    corner_loops = np.stack([first, first + step + 1, first + step + 2], axis=1).reshape(-1)
    corner_vertices = loop_vertices[corner_loops]
    if mesh.is_editmode:
        editable = bmesh.from_edit_mesh(mesh)
        if len(editable.verts) != len(mesh.vertices):
            return None
        local = np.array([vertex.co for vertex in editable.verts], dtype=np.float64).reshape(-1, 3)
    else:
        local = attributes.read_positions(mesh).reshape(-1, 3)
    world = transforms.transform_points(matrix_array(layout.matrix_world), local)
    return world[corner_vertices].astype(np.float32), corner_vertices, np.repeat(triangle_faces, 3)


def forget_readouts() -> None:
    """Drop the remembered object-mode read-outs (the add-on is unregistered)."""
    _object_mode_readouts.clear()
