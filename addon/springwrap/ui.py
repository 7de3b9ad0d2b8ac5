"""The Springwrap sidebar panel of the 3D view."""

import bpy


class SPRINGWRAP_PT_layout(bpy.types.Panel):
    """Target picker and the detach / snap / project buttons for the active layout"""

    bl_label = "Springwrap"
    bl_idname = "SPRINGWRAP_PT_layout"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Springwrap"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        obj = context.active_object
        settings = obj.springwrap
        in_edit_mode = obj.mode == "EDIT"

        layout.prop(settings, "target")
        _draw_point_counts(layout, obj)

        column = layout.column(align=True)
        column.label(text="Selected Vertices" if in_edit_mode else "All Vertices", icon="VERTEXSEL")

        box = layout.box()
        box.prop(settings, "snap_mode")
        box.prop(settings, "max_distance")
        snap = box.operator("springwrap.snap", icon="SNAP_ON")
        snap.mode = settings.snap_mode
        snap.max_distance = settings.max_distance
        snap.only_selected = in_edit_mode

        box = layout.box()
        box.prop(settings, "project_direction")
        row = box.row()
        row.active = settings.project_direction not in ("VIEW", "NORMAL")
        row.prop(settings, "project_orientation")
        box.prop(settings, "project_both_directions")
        project = box.operator("springwrap.project", icon="MOD_SHRINKWRAP")
        project.direction = settings.project_direction
        project.orientation = settings.project_orientation
        project.both_directions = settings.project_both_directions
        project.max_distance = settings.max_distance
        project.only_selected = in_edit_mode

        detach = layout.operator("springwrap.detach", icon="UNLINKED")
        detach.only_selected = in_edit_mode


def _draw_point_counts(layout, obj):
    """Face-point / space-point counts, read from the state attribute (not available in edit mode)."""
    import numpy as np

    from . import layout_state

    mesh = obj.data
    attribute = mesh.attributes.get(layout_state.STATE_ATTRIBUTE)
    vertex_count = len(mesh.vertices)
    if attribute is None:
        counts = None if obj.mode == "EDIT" else (0, vertex_count)
    elif attribute.domain != "POINT" or attribute.data_type != "INT" or len(attribute.data) != vertex_count:
        counts = None
    else:
        states = np.empty(vertex_count, dtype=np.int32)
        attribute.data.foreach_get("value", states)
        counts = layout_state.point_counts(states)
    if counts is None:
        layout.label(text="Point counts shown in Object Mode", icon="INFO")
    else:
        face_count, space_count = counts
        layout.label(text=f"{face_count} face-points, {space_count} space-points", icon="INFO")


classes = (SPRINGWRAP_PT_layout,)
