"""The Springwrap sidebar panel of the 3D view, and its Align, Armature, Anchors, Curve Constraints, Wrap and
Features sub-panels (their lists are in ``lists``)."""

import bpy

from ..blender import anchors as anchor_data
from ..blender import layout as layout_data


class _SidebarPanel:
    """Where every Springwrap panel lives (the 3D view's sidebar tab) and when it shows (a mesh is active)."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Springwrap"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH"


class _LayoutSubPanel(_SidebarPanel):
    """A sub-panel of the layout panel."""

    bl_parent_id = "SPRINGWRAP_PT_layout"


class SPRINGWRAP_PT_layout(_SidebarPanel, bpy.types.Panel):
    """Target picker and the detach / snap / project buttons for the active layout"""

    bl_label = "Springwrap"
    bl_idname = "SPRINGWRAP_PT_layout"

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
    counts = layout_data.read_point_counts(obj)
    if counts is None:
        layout.label(text="Point counts shown in Object Mode", icon="INFO")
    else:
        face_count, space_count = counts
        layout.label(text=f"{face_count} face-points, {space_count} space-points", icon="INFO")


class SPRINGWRAP_PT_anchors(_LayoutSubPanel, bpy.types.Panel):
    """The active layout's anchors: list, add / remove / clear / auto, and the viewport display toggle"""

    bl_label = "Anchors"
    bl_idname = "SPRINGWRAP_PT_anchors"

    def draw_header(self, context):
        self.layout.prop(context.active_object.springwrap, "show_anchors", text="")

    def draw(self, context):
        layout = self.layout
        settings = context.active_object.springwrap
        layout.label(text=_anchor_counts_text(context.active_object), icon="PINNED")

        row = layout.row()
        row.template_list("SPRINGWRAP_UL_anchors", "", settings, "anchors", settings, "active_anchor_index", rows=4)
        column = row.column(align=True)
        add = column.operator("springwrap.anchor_add", icon="ADD", text="")
        add.vertex_index = -1
        add.use_location = False
        column.operator("springwrap.anchor_remove", icon="REMOVE", text="").index = -1
        column.separator()
        column.operator("springwrap.anchors_update", icon="FILE_REFRESH", text="")
        column.operator("springwrap.anchors_clear", icon="X", text="")

        box = layout.box()
        box.use_property_split = True
        box.use_property_decorate = False
        box.prop(settings, "anchor_spacing")
        box.prop(settings, "anchor_method")
        auto = box.operator("springwrap.anchors_auto", icon="AUTO")
        auto.spacing = settings.anchor_spacing
        auto.method = settings.anchor_method
        auto.max_distance = settings.max_distance


class SPRINGWRAP_PT_curve_constraints(_LayoutSubPanel, bpy.types.Panel):
    """The active layout's curve constraints: list, add / remove / clear / auto, and the viewport display toggle"""

    bl_label = "Curve Constraints"
    bl_idname = "SPRINGWRAP_PT_curve_constraints"

    def draw_header(self, context):
        self.layout.prop(context.active_object.springwrap, "show_curve_constraints", text="")

    def draw(self, context):
        layout = self.layout
        settings = context.active_object.springwrap
        row = layout.row()
        row.template_list(
            "SPRINGWRAP_UL_curve_constraints",
            "",
            settings,
            "curve_constraints",
            settings,
            "active_curve_constraint_index",
            rows=3,
        )
        column = row.column(align=True)
        add = column.operator("springwrap.curve_constraint_add", icon="ADD", text="")
        add.curve_object = settings.curve_source.name if settings.curve_source is not None else ""
        column.operator("springwrap.curve_constraint_remove", icon="REMOVE", text="").index = -1
        column.separator()
        column.operator("springwrap.curve_constraints_clear", icon="X", text="")
        layout.prop(settings, "curve_source")
        layout.label(text="Add: selected edge chain (Edit Mode)", icon="INFO")
        layout.operator("springwrap.curve_constraints_auto", icon="AUTO")


class SPRINGWRAP_PT_align(_LayoutSubPanel, bpy.types.Panel):
    """Alignment of the template before it is attached: anchor fit and ICP"""

    bl_label = "Align"
    bl_idname = "SPRINGWRAP_PT_align"

    def draw(self, context):
        layout = self.layout
        anchor_count = len(context.active_object.springwrap.anchors)
        layout.label(text=f"Fit to {anchor_count} anchors, then ICP", icon="INFO")
        row = layout.row(align=True)
        row.operator_menu_enum("springwrap.align", "method", text="Align", icon="ORIENTATION_GLOBAL")
        icp_only = row.operator("springwrap.align", text="ICP Only")
        icp_only.use_anchors = False
        icp_only.method = "RIGID"


class SPRINGWRAP_PT_wrap(_LayoutSubPanel, bpy.types.Panel):
    """The wrap: the target's unreliable vertex group and the Wrap button"""

    bl_label = "Wrap"
    bl_idname = "SPRINGWRAP_PT_wrap"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.active_object.springwrap
        row = layout.row()
        if settings.target is not None:
            row.prop_search(settings, "unreliable_group", settings.target, "vertex_groups", icon="GROUP_VERTEX")
        else:
            row.enabled = False
            row.prop(settings, "unreliable_group")
        layout.prop(settings, "wrap_solver")
        groups = layout.column()
        groups.active = settings.wrap_solver == "ENERGY"
        groups.prop_search(settings, "stiffness_group", context.active_object, "vertex_groups", icon="GROUP_VERTEX")
        groups.prop_search(settings, "free_group", context.active_object, "vertex_groups", icon="GROUP_VERTEX")
        layout.label(text="Whole layout; Esc or right-click cancels", icon="INFO")
        layout.operator("springwrap.wrap", icon="MOD_SHRINKWRAP").solver = settings.wrap_solver
        layout.operator("springwrap.rest_set", icon="ARMATURE_DATA")
        box = layout.box()
        box.prop(settings, "mirror_object")
        mirror = box.operator("springwrap.mirror", icon="MOD_MIRROR")
        mirror.solver = settings.wrap_solver
        mirror.mirror_object = settings.mirror_object.name if settings.mirror_object is not None else ""


class SPRINGWRAP_PT_armature(_LayoutSubPanel, bpy.types.Panel):
    """Armature alignment: the target armature and the Align Armature button"""

    bl_label = "Armature"
    bl_idname = "SPRINGWRAP_PT_armature"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.active_object.springwrap, "target_armature")
        layout.operator("springwrap.align_armature", icon="ARMATURE_DATA")


class SPRINGWRAP_PT_features(_LayoutSubPanel, bpy.types.Panel):
    """Feature detection on the target: region colours and ridge / valley curves for curve constraints"""

    bl_label = "Features"
    bl_idname = "SPRINGWRAP_PT_features"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        obj = context.active_object
        source = obj.springwrap.target if obj.springwrap.target is not None else obj
        self.layout.label(text=f"On '{source.name}'", icon="MESH_DATA")
        self.layout.operator("springwrap.detect_features", icon="CURVE_BEZCURVE")


def _anchor_counts_text(obj):
    """ "K anchors (F on the surface)", the kinds read at once (the list may be long)."""
    return f"{len(obj.springwrap.anchors)} anchors ({anchor_data.face_anchor_count(obj)} on the surface)"


classes = (
    SPRINGWRAP_PT_layout,
    SPRINGWRAP_PT_align,
    SPRINGWRAP_PT_armature,
    SPRINGWRAP_PT_anchors,
    SPRINGWRAP_PT_curve_constraints,
    SPRINGWRAP_PT_wrap,
    SPRINGWRAP_PT_features,
)
