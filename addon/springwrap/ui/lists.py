"""The lists of the sidebar's sub-panels: the layout's anchors and its curve constraints."""

import bpy


class SPRINGWRAP_UL_anchors(bpy.types.UIList):
    """The layout's anchors: vertex index, target kind and target location"""

    bl_idname = "SPRINGWRAP_UL_anchors"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        vertex_count = len(data.id_data.data.vertices) if data.id_data.type == "MESH" else 0
        missing = not 0 <= item.vertex_index < vertex_count
        row = layout.row(align=True)
        row.alert = missing
        vertex_text = f"Vertex {item.vertex_index}" + (" (missing)" if missing else "")
        row.label(text=vertex_text, icon="ERROR" if missing else "VERTEXSEL")
        x, y, z = item.location
        kind_icon = "SNAP_FACE" if item.target_kind == "FACE" else "EMPTY_AXIS"
        row.label(text=f"{item.target_kind.title()} ({x:.3g}, {y:.3g}, {z:.3g})", icon=kind_icon)


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
