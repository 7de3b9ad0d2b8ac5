"""The active anchor brought into view: a click on a row of the anchor list selects the anchor's layout vertex and
centres the 3D view on it (the overlay draws the active anchor's pair highlighted).

Only a click in the sidebar does this: the add-on's own writes of the active anchor (an anchor operator, the pair
tool) go through :func:`quietly` or come from another region, so adding anchors or hovering never moves the view.
"""

import contextlib

import bpy

import bmesh

from . import compat

_quiet = 0
"""Above 0 while the add-on itself sets the active anchor."""


@contextlib.contextmanager
def quietly():
    """Set ``active_anchor_index`` in the block without selecting or framing anything."""
    global _quiet
    _quiet += 1
    try:
        yield
    finally:
        _quiet -= 1


def from_sidebar(context) -> bool:
    """Whether ``context`` is a click in the 3D view's sidebar (where the anchor list is)."""
    area, region = getattr(context, "area", None), getattr(context, "region", None)
    return area is not None and region is not None and area.type == "VIEW_3D" and region.type == "UI"


def active_anchor_changed(settings, context) -> None:
    """``active_anchor_index``'s update: a click on a list row brings its anchor into view (:func:`show_anchor`)."""
    if _quiet or not from_sidebar(context):
        return
    show_anchor(context, settings.id_data, settings.active_anchor_index)


def show_anchor(context, layout: bpy.types.Object, index: int) -> bool:
    """Select the layout vertex of the anchor at ``index`` (the only one selected; in Edit Mode also the active
    vertex) and, when ``context`` has a 3D view, centre the view on it. False when there is no such anchor or its
    vertex is gone (then nothing changes)."""
    anchors = layout.springwrap.anchors
    if layout.type != "MESH" or not 0 <= index < len(anchors):
        return False
    vertex = anchors[index].vertex_index
    if not 0 <= vertex < len(layout.data.vertices):
        return False
    point = select_only_vertex(layout, vertex)
    space = getattr(context, "space_data", None)
    if space is not None and space.type == "VIEW_3D" and space.region_3d is not None:
        space.region_3d.view_location = point
        context.area.tag_redraw()
    return True


def select_only_vertex(layout: bpy.types.Object, vertex: int):
    """Select vertex ``vertex`` of the layout and nothing else (in Edit Mode the edit-mesh's selection, the vertex
    made active; in Object Mode the mesh's selection state); its world position (``mathutils.Vector``)."""
    mesh = layout.data
    if layout.mode == "EDIT":
        deselected = layout == bpy.context.edit_object and bpy.ops.mesh.select_all.poll()
        if deselected:  # at C speed: a Python loop over 160 000 vertices takes 0.2 s
            bpy.ops.mesh.select_all(action="DESELECT")
        editable = bmesh.from_edit_mesh(mesh)
        editable.verts.ensure_lookup_table()
        if not deselected:
            for each in editable.verts:
                each.select = False
            editable.select_flush(False)  # edges and faces of deselected vertices
        chosen = editable.verts[vertex]
        chosen.select = True
        editable.select_history.clear()
        editable.select_history.add(chosen)
        position = chosen.co.copy()
        bmesh.update_edit_mesh(mesh, loop_triangles=False, destructive=False)
    else:
        compat.deselect_all(mesh)
        mesh.vertices[vertex].select = True
        position = mesh.vertices[vertex].co.copy()
        mesh.update()
    return layout.matrix_world @ position
