"""The Springwrap sidebar tab of the 3D view, laid out as an artist's workflow.

The steps in the order they are taken, open by default: the layout panel itself (**Target**: the target
and the cage display), **Place** (align; its **Armature** sub-panel), **Anchors** (its **Curve
Constraints** sub-panel), **Wrap** (the big button, its main settings, the live progress) and **Check**
(the point counts, the quality read-out's heat-map and Select Problems, the last wrap). Then the point tools, each in its own sub-panel, closed by
default: **Snap**, **Project**, **Detach**, **Mirror**, **Features**.

Layouts follow Blender's own modifier panels (``properties_data_modifier``): ``use_property_split``, short
labels (the tooltips, from the properties' descriptions, carry the detail), counts on their own rows.
The lists are in ``lists``; data is read through ``blender``.
"""

import bpy

from ..blender import anchors as anchor_data
from ..blender import last_run, wrap_session
from ..blender import layout as layout_data
from . import lists

WRAP_BUTTON_SCALE = 1.6
"""Height of the Wrap button, in rows: the step the add-on exists for."""


class _SidebarPanel:
    """Where every Springwrap panel lives (the 3D view's sidebar tab) and when it shows (a mesh is active). A
    panel's id is its class name (``bl_idname`` left out, as Blender allows), which ``bl_parent_id`` names."""

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


class _ToolPanel(_SidebarPanel):
    """A tool beside the workflow's steps: a sub-panel closed by default (the steps themselves stay open)."""

    bl_options = {"DEFAULT_CLOSED"}


class _LayoutToolPanel(_ToolPanel):
    """A tool's sub-panel of the layout panel, closed by default."""

    bl_parent_id = "SPRINGWRAP_PT_layout"


def _split(layout):
    """``layout`` with property split on and no decorators (Blender's modifier panels)."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


def _count_row(layout, label: str, value, icon: str = "NONE") -> None:
    """A count on its own row: the label in the property column, the value beside it."""
    split = layout.split(factor=0.4)
    left = split.row()
    left.alignment = "RIGHT"
    left.label(text=label)
    split.label(text=str(value), icon=icon)


def _point_tool_button(layout, context, idname: str, verb: str, icon: str, settings=()):
    """A point tool's button: on the whole layout ("Snap"), or on the selected vertices in edit mode ("Snap
    Selected"). ``settings``: ``(operator property, panel setting, ...)``, the panel's settings it runs with."""
    obj = context.active_object
    editing = obj.mode == "EDIT"
    button = layout.operator(idname, text=f"{verb} Selected" if editing else verb, icon=icon)
    for name, setting, *_label in settings:
        setattr(button, name, getattr(obj.springwrap, setting))
    button.only_selected = editing
    return button


def _point_tool(layout, context, idname: str, verb: str, icon: str, settings=()):
    """A point tool's sub-panel: its settings (``(operator property, panel setting, label)``), then its button."""
    layout = _split(layout)
    for _name, setting, label in settings:
        layout.prop(context.active_object.springwrap, setting, text=label)
    _point_tool_button(layout, context, idname, verb, icon, settings)


SNAP_SETTINGS = (("mode", "snap_mode", "Mode"), ("max_distance", "max_distance", "Limit"))
"""The Snap button's properties, the panel settings they are taken from and their labels."""
PROJECT_SETTINGS = (
    ("direction", "project_direction"),
    ("orientation", "project_orientation"),
    ("both_directions", "project_both_directions"),
    ("max_distance", "max_distance"),
)
"""The Project button's properties and the panel settings they are taken from."""


class SPRINGWRAP_PT_layout(_SidebarPanel, bpy.types.Panel):
    """The layout's target and how the layout is shown over it"""

    bl_label = "Springwrap"

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.active_object.springwrap
        layout.prop(settings, "target")
        column = layout.column(heading="Show")
        column.active = settings.target is not None
        column.prop(settings, "show_cage", text="Cage")


class SPRINGWRAP_PT_align(_LayoutSubPanel, bpy.types.Panel):
    """Place the template on the target before it is attached: anchor fit and ICP"""

    bl_label = "Place"

    def draw(self, context):
        layout = self.layout
        anchor_count = len(context.active_object.springwrap.anchors)
        layout.label(text=f"Fit to {anchor_count} anchor{'' if anchor_count == 1 else 's'}, then ICP")
        row = layout.row(align=True)
        row.operator_menu_enum("springwrap.align", "method", text="Align", icon="ORIENTATION_GLOBAL")
        icp_only = row.operator("springwrap.align", text="ICP Only")
        icp_only.use_anchors = False
        icp_only.method = "RIGID"


class SPRINGWRAP_PT_armature(_ToolPanel, bpy.types.Panel):
    """Armature alignment: the target armature and the Align Armature button"""

    bl_label = "Armature"
    bl_parent_id = "SPRINGWRAP_PT_align"

    def draw(self, context):
        layout = _split(self.layout)
        layout.prop(context.active_object.springwrap, "target_armature", text="Target")
        layout.operator("springwrap.align_armature", icon="ARMATURE_DATA")


class SPRINGWRAP_PT_anchors(_LayoutSubPanel, bpy.types.Panel):
    """The active layout's anchors: list, add / remove / clear / auto, and the viewport display toggle"""

    bl_label = "Anchors"

    def draw_header(self, context):
        self.layout.prop(context.active_object.springwrap, "show_anchors", text="")

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        settings = obj.springwrap
        counts = layout.column(align=True)
        _count_row(counts, "Anchors", len(settings.anchors), icon="PINNED")
        _count_row(counts, "On Surface", anchor_data.face_anchor_count(obj), icon="SNAP_FACE")

        pairs = layout.row(align=True)  # the pair tool: pairs made and dragged in the 3D view
        pairs.operator("springwrap.pair_tool", text="Pair Tool", icon="MOUSE_LMB")
        pairs.prop(settings, "pair_live", text="Live", toggle=True)

        row = layout.row()
        row.template_list("SPRINGWRAP_UL_anchors", "", settings, "anchors", settings, "active_anchor_index", rows=4)
        column = row.column(align=True)
        add = column.operator("springwrap.anchor_add", icon="ADD", text="")
        add.vertex_index = -1
        add.use_location = False
        _symmetry_arguments(add, settings)
        column.operator("springwrap.anchor_remove", icon="REMOVE", text="").index = -1
        column.separator()
        column.operator("springwrap.anchors_update", icon="FILE_REFRESH", text="")
        column.operator("springwrap.anchors_clear", icon="X", text="")
        if len(settings.anchors):  # the active anchor's vertex numbers, whole (the list may have no room for them)
            active = settings.anchors[min(settings.active_anchor_index, len(settings.anchors) - 1)]
            text = lists.vertex_text(active.vertex_index, active.twin_vertex, len(obj.data.vertices))
            layout.label(text=f"Vertex {text}", icon="VERTEXSEL")  # the whole width: 7 digits each fit

        column = _split(layout.column())
        column.prop(settings, "anchor_spacing")
        column.prop(settings, "anchor_method")
        column.prop(settings, "anchor_keep")
        # Symmetric anchors: Add and Auto anchor each vertex's twin too, as a pair (Remove removes both).
        column.prop(settings, "anchor_symmetric")
        symmetry = column.column()
        symmetry.active = settings.anchor_symmetric
        symmetry.row(align=True).prop(settings, "anchor_symmetry_axis", text="Axis", expand=True)
        symmetry.prop(settings, "anchor_symmetry_object", text="Plane Of")
        auto = column.operator("springwrap.anchors_auto", icon="AUTO")
        auto.spacing = settings.anchor_spacing
        auto.method = settings.anchor_method
        auto.replace = not settings.anchor_keep
        auto.max_distance = settings.max_distance
        _symmetry_arguments(auto, settings)

        # Proposed pairs: from the anchors placed by hand, more where both shapes agree; accepted or rejected.
        propose = layout.row(align=True)
        propose.operator("springwrap.anchors_propose", icon="LIGHT")
        proposed = sum(1 for item in settings.anchors if item.proposed)
        if proposed:
            row = layout.row(align=True)
            row.label(text=f"{proposed} proposed")
            accept = row.operator("springwrap.anchor_accept", text="Accept", icon="CHECKMARK")
            accept.index, accept.all = -1, False
            row.operator("springwrap.anchor_accept", text="All", icon="CHECKMARK").all = True
            reject = row.operator("springwrap.anchor_reject", text="Reject", icon="CANCEL")
            reject.index, reject.all = -1, False
            row.operator("springwrap.anchor_reject", text="All", icon="CANCEL").all = True


def _symmetry_arguments(operator, settings):
    """The panel's symmetric-anchor settings given to Add or Auto Anchors."""
    operator.symmetric = settings.anchor_symmetric
    operator.symmetry_axis = settings.anchor_symmetry_axis
    symmetry_object = settings.anchor_symmetry_object
    operator.symmetry_object = symmetry_object.name if symmetry_object is not None else ""


class SPRINGWRAP_PT_curve_constraints(_ToolPanel, bpy.types.Panel):
    """The active layout's curve constraints: list, add / remove / clear / auto, and the viewport display toggle"""

    bl_label = "Curve Constraints"
    bl_parent_id = "SPRINGWRAP_PT_anchors"

    def draw_header(self, context):
        self.layout.prop(context.active_object.springwrap, "show_curve_constraints", text="")

    def draw_header_preset(self, context):
        """How many constraints the layout has, on the right of the header: seen with the sub-panel closed."""
        self.layout.label(text=str(len(context.active_object.springwrap.curve_constraints)))

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
        _split(layout.column()).prop(settings, "curve_source")
        row = layout.row(align=True)
        row.operator("springwrap.curve_constraints_auto", icon="AUTO")
        row.operator("springwrap.feature_lines_pair", icon="SHARPCURVE")


class SPRINGWRAP_PT_wrap(_LayoutSubPanel, bpy.types.Panel):
    """The wrap: the Wrap button, its schedule and vertex groups, and the live progress"""

    bl_label = "Wrap"

    def draw(self, context):
        layout = _split(self.layout)
        obj = context.active_object
        settings = obj.springwrap
        session = wrap_session.running_session(obj)
        if session is not None:
            _draw_progress(layout, session)
        else:
            row = layout.row()
            row.scale_y = WRAP_BUTTON_SCALE
            wrap = row.operator("springwrap.wrap", icon="MOD_SHRINKWRAP")
            wrap.shape_keys, wrap.schedule = settings.shape_keys, settings.wrap_schedule

        layout.prop(settings, "wrap_schedule")
        if obj.data.shape_keys is not None:  # shape keys: transferred or refused (Wrap and Mirror)
            layout.prop(settings, "shape_keys")
        row = layout.row()
        if settings.target is not None:
            row.prop_search(settings, "unreliable_group", settings.target, "vertex_groups", icon="GROUP_VERTEX")
        else:
            row.enabled = False
            row.prop(settings, "unreliable_group")
        groups = layout.column()
        groups.prop_search(settings, "stiffness_group", obj, "vertex_groups", icon="GROUP_VERTEX")
        groups.prop_search(settings, "free_group", obj, "vertex_groups", icon="GROUP_VERTEX")
        _draw_parts(layout, settings, obj)
        layout.operator("springwrap.rest_set", icon="ARMATURE_DATA")


def _draw_parts(layout, settings, obj) -> None:
    """Parts that follow the surface: Find Parts, and the groups that override its guess."""
    column = layout.column()
    column.prop(settings, "find_parts")
    for name in ("follow_group", "follow_soft_group", "surface_group"):
        column.prop_search(settings, name, obj, "vertex_groups", icon="GROUP_VERTEX")


class SPRINGWRAP_PT_over_time(_LayoutSubPanel, bpy.types.Panel):
    """Over time: Follow (the layout re-settles when the target changes) and Wrap Sequence (a frame range)"""

    bl_label = "Over Time"

    def draw_header(self, context):
        settings = context.active_object.springwrap
        self.layout.label(icon="LINKED" if settings.follow else "TIME")

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.active_object.springwrap
        row = layout.row()
        row.alert = settings.follow  # visibly on
        row.prop(settings, "follow", toggle=True, icon="LINKED" if settings.follow else "UNLINKED")
        if settings.follow:
            layout.label(text="Re-settles when the target changes", icon="INFO")
        layout.separator()
        layout.prop(settings, "sequence_source")
        collection = layout.row()
        collection.active = settings.sequence_source == "COLLECTION"
        collection.prop(settings, "sequence_collection")
        scene = context.scene
        button = layout.operator(
            "springwrap.wrap_sequence",
            text=f"Wrap Frames {scene.frame_start}-{scene.frame_end}",
            icon="RENDER_ANIMATION",
        )
        button.source = settings.sequence_source
        button.collection = settings.sequence_collection.name if settings.sequence_collection else ""
        button.schedule = settings.wrap_schedule
        layout.operator("springwrap.export_sequence", icon="EXPORT")


def _draw_progress(layout, session) -> None:
    """The live wrap's progress, on rows of their own (the status bar has the same, and Esc to cancel)."""
    column = layout.column(align=True)
    _count_row(column, "Iteration", session.total_iterations)
    _count_row(column, "Limit", session.parameters.max_iterations)
    report = session.last_report
    if report is not None:
        _count_row(column, "Last Move", f"{report.max_displacement:.2e}")
    column.label(text="Esc: cancel", icon="CANCEL")


class SPRINGWRAP_PT_check(_LayoutSubPanel, bpy.types.Panel):
    """What the layout is now: its face- and space-points, and the last wrap's result"""

    bl_label = "Check"

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        run = last_run.last(obj.name)
        counts = layout_data.read_point_counts(obj)
        column = layout.column(align=True)
        if counts is None:
            column.label(text="Counts in Object Mode", icon="INFO")
        elif run is not None and run.operation == "Fit Subdivision":  # a cage: off the surface by design
            _count_row(column, "Cage Points", sum(counts), icon="MOD_SUBSURF")
            column.label(text="Its subdivided surface is on the target")
        else:
            face_count, space_count = counts
            _count_row(column, "On Surface", face_count, icon="SNAP_FACE")  # face-points
            _count_row(column, "In Space", space_count, icon="EMPTY_AXIS")  # space-points
        _draw_readout(layout, obj)
        if run is None:
            return
        column = layout.column(align=True)
        icons = {"Wrap": "MOD_SHRINKWRAP", "Mirror": "MOD_MIRROR", "Fit Subdivision": "MOD_SUBSURF"}
        for index, (label, value) in enumerate(run.rows):
            _count_row(column, label, value, icon=icons.get(run.operation, "NONE") if index == 0 else "NONE")


def _draw_readout(layout, obj) -> None:
    """The Check section's quality read-out: the heat-map toggle and kind, Select Problems and its kind."""
    settings = obj.springwrap
    column = _split(layout.column(align=True))
    column.prop(settings, "show_heatmap", text="Show Heat-Map")
    row = column.row(align=True)
    row.active = settings.show_heatmap
    row.prop(settings, "heatmap_kind", text="Show")
    column.prop(settings, "problem_kind")
    select = column.operator("springwrap.select_problems", icon="RESTRICT_SELECT_OFF")
    select.kind = settings.problem_kind


class SPRINGWRAP_PT_fit_subdivision(_ToolPanel, bpy.types.Panel):
    """Move the layout so that its Subdivision Surface at a level lies on the target (a smooth result)"""

    bl_label = "Subdivision Fit"
    bl_parent_id = "SPRINGWRAP_PT_check"

    def draw(self, context):
        _point_tool_button(self.layout, context, "springwrap.fit_subdivision", "Fit Subdivision", "MOD_SUBSURF")
        self.layout.label(text="Level and rounds: F9")


class SPRINGWRAP_PT_snap(_LayoutToolPanel, bpy.types.Panel):
    """Snap: each vertex to the closest point of the target (it becomes a face-point)"""

    bl_label = "Snap"

    def draw(self, context):
        _point_tool(self.layout, context, "springwrap.snap", "Snap", "SNAP_ON", SNAP_SETTINGS)


class SPRINGWRAP_PT_project(_LayoutToolPanel, bpy.types.Panel):
    """Project: each vertex along a direction onto the target (a hit becomes a face-point)"""

    bl_label = "Project"

    def draw(self, context):
        settings = context.active_object.springwrap
        layout = _split(self.layout)
        layout.prop(settings, "project_direction")
        row = layout.row()
        row.active = settings.project_direction not in ("VIEW", "NORMAL")
        row.prop(settings, "project_orientation", text="Axes")
        layout.prop(settings, "project_both_directions", text="Both Ways")
        layout.prop(settings, "max_distance", text="Limit")
        _point_tool_button(layout, context, "springwrap.project", "Project", "MOD_SHRINKWRAP", PROJECT_SETTINGS)


class SPRINGWRAP_PT_detach(_LayoutToolPanel, bpy.types.Panel):
    """Detach: vertices become space-points, free in 3D (a template to place and wrap)"""

    bl_label = "Detach"

    def draw(self, context):
        _point_tool(self.layout, context, "springwrap.detach", "Detach", "UNLINKED")


class SPRINGWRAP_PT_mirror(_LayoutToolPanel, bpy.types.Panel):
    """Mirror: a surfaced half across the layout's (or an empty's) plane, then wrap the new half"""

    bl_label = "Mirror"

    def draw(self, context):
        layout = _split(self.layout)
        settings = context.active_object.springwrap
        layout.prop(settings, "mirror_object", text="Plane")
        mirror = layout.operator("springwrap.mirror", icon="MOD_MIRROR")
        mirror.shape_keys = settings.shape_keys
        mirror.mirror_object = settings.mirror_object.name if settings.mirror_object is not None else ""


class SPRINGWRAP_PT_features(_LayoutToolPanel, bpy.types.Panel):
    """Feature detection on the target: region colours and ridge / valley curves for curve constraints"""

    bl_label = "Features"

    def draw(self, context):
        obj = context.active_object
        source = obj.springwrap.target if obj.springwrap.target is not None else obj
        self.layout.label(text=f"On '{source.name}'", icon="MESH_DATA")
        self.layout.operator("springwrap.detect_features", icon="CURVE_BEZCURVE")


classes = (
    SPRINGWRAP_PT_layout,
    SPRINGWRAP_PT_align,
    SPRINGWRAP_PT_armature,
    SPRINGWRAP_PT_anchors,
    SPRINGWRAP_PT_curve_constraints,
    SPRINGWRAP_PT_wrap,
    SPRINGWRAP_PT_over_time,
    SPRINGWRAP_PT_check,
    SPRINGWRAP_PT_fit_subdivision,
    SPRINGWRAP_PT_snap,
    SPRINGWRAP_PT_project,
    SPRINGWRAP_PT_detach,
    SPRINGWRAP_PT_mirror,
    SPRINGWRAP_PT_features,
)
"""The panels in their order in the sidebar (a parent before its sub-panels)."""
