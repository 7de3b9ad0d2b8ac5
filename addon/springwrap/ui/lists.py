"""The lists of the sidebar's sub-panels: the layout's anchors and its curve constraints."""

import bpy

from mathutils import Vector


class SPRINGWRAP_UL_anchors(bpy.types.UIList):
    """The layout's anchors: the vertex index (its icon: the target is on the surface or in space), its symmetric
    twin's vertex (a mirror icon and its index, or "mid" on the plane), and how far the vertex is from its target point"""

    bl_idname = "SPRINGWRAP_UL_anchors"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        obj = data.id_data
        vertices = obj.data.vertices if obj.type == "MESH" else ()
        missing = not 0 <= item.vertex_index < len(vertices)
        split = layout.split(factor=0.4, align=True)
        split.alert = missing
        kind_icon = "SNAP_FACE" if item.target_kind == "FACE" else "EMPTY_AXIS"
        split.label(text=str(item.vertex_index), icon="ERROR" if missing else kind_icon)
        if item.twin_vertex >= 0:  # a pair is written mutual (blender.anchors.write_anchors)
            mid = item.twin_vertex == item.vertex_index
            split.label(text="mid" if mid else str(item.twin_vertex), icon="MOD_MIRROR")
        if missing:
            split.label(text="missing")
            return
        # Object-mode data (in edit mode, as of the last switch): one vertex per visible row, read as drawn.
        world = obj.matrix_world @ vertices[item.vertex_index].co
        distance = (Vector(item.location) - world).length
        split.label(text=_length_text(context, distance))


def _length_text(context, value: float) -> str:
    """A distance in the scene's units, three significant digits ("0.0312 m", "3.12 cm", "1.2 ft")."""
    units = context.scene.unit_settings if context.scene is not None else None
    if units is None or units.system == "NONE":
        return f"{value:.3g}"
    return bpy.utils.units.to_string(
        units.system, "LENGTH", value * units.scale_length, precision=3, split_unit=units.use_separate
    )


class SPRINGWRAP_UL_curve_constraints(bpy.types.UIList):
    """The layout's curve constraints: the chain's end vertices and the target curve's source"""

    bl_idname = "SPRINGWRAP_UL_curve_constraints"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        vertices = item.layout_vertices.split()
        chain = f"{vertices[0]}..{vertices[-1]} ({len(vertices)})" if vertices else "(empty)"
        row = layout.row(align=True)
        row.label(text=chain, icon="EDGESEL")
        if item.source_kind == "CURVE_OBJECT":
            name = item.curve_object.name if item.curve_object is not None else "(missing curve)"
            row.alert = item.curve_object is None
            row.label(text=name, icon="CURVE_DATA")
        else:
            row.label(text=f"{len(item.points)} target vertices", icon="MESH_DATA")


classes = (SPRINGWRAP_UL_anchors, SPRINGWRAP_UL_curve_constraints)
