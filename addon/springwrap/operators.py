"""Springwrap operators: detach, snap and project the active layout object onto its target.

Each operator reads everything, computes the complete result (``operations``), and writes only
when every step succeeded; any problem is reported as an error and the layout is left exactly as
it was.
"""

import contextlib
import time

import bpy
import numpy as np

from .properties import ORIENTATION_ITEMS, PROJECT_DIRECTION_ITEMS, SNAP_MODE_ITEMS, max_distance_property


def layout_problem(context, require_target=True):
    """Why the operators cannot run on the active object, or None when they can."""
    layout = context.active_object
    if layout is None or layout.type != "MESH":
        return "No active mesh object (the layout)"
    target = layout.springwrap.target
    if target is None:
        return "No target set (Springwrap panel in the sidebar)" if require_target else None
    if target == layout:
        return "The target is the layout itself"
    if target.type != "MESH":
        return f"Target '{target.name}' is not a mesh"
    return None


def import_bridge(operator):
    """The ``bridge`` module (importing it imports the kernel), or None after an ERROR report that the
    kernel is missing."""
    try:
        from . import bridge
    except ImportError as error:
        operator.report({"ERROR"}, f"The Springwrap kernel is not available: {error}")
        return None
    return bridge


def checked_bridge(operator, context, require_target=True):
    """What a layout operator's ``execute`` starts with: :func:`layout_problem`, then the kernel; the
    ``bridge`` module, or None after an ERROR report saying why not."""
    problem = layout_problem(context, require_target)
    if problem is not None:
        operator.report({"ERROR"}, problem)
        return None
    return import_bridge(operator)


def poll_layout(cls, context, require_target=True) -> bool:
    """A layout operator's ``poll``: whether it can run, with the reason set when not."""
    problem = layout_problem(context, require_target)
    if problem is not None:
        cls.poll_message_set(problem)
        return False
    return True


class _LayoutOperator:
    """Shared poll, run and report of the Springwrap operators."""

    requires_target = True
    moves_vertices = True

    only_selected: bpy.props.BoolProperty(
        name="Only Selected",
        description="Act on the selected vertices only (face-points whose target face is gone are still resolved everywhere)",
        default=False,
    )

    @classmethod
    def poll(cls, context):
        return poll_layout(cls, context, cls.requires_target)

    def execute(self, context):
        bridge = checked_bridge(self, context, self.requires_target)
        if bridge is None:
            return {"CANCELLED"}
        from . import operations
        layout = context.active_object
        if self.moves_vertices and bridge.has_shape_keys(layout):
            self.report({"ERROR"}, f"Layout '{layout.name}' has shape keys; Springwrap cannot move its vertices")
            return {"CANCELLED"}
        start = time.perf_counter()
        try:
            with bridge.object_mode(layout):
                settings = layout.springwrap
                arrays = bridge.read_layout(layout)
                target = None
                if settings.target is not None:
                    target = bridge.read_target(context.evaluated_depsgraph_get(), layout)
                outcome = self.compute(context, bridge, operations, layout, arrays, target)
                bridge.write_layout(layout, outcome.positions, outcome.state)
                if target is not None:
                    settings.target_signature = target.signature
        except bridge.ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        milliseconds = (time.perf_counter() - start) * 1000.0
        self.report({"INFO"}, self.summary(outcome, milliseconds))
        detached, reattached = outcome.topology_detached_count, outcome.topology_reattached_count
        if detached or reattached:
            self.report(
                {"WARNING"} if detached else {"INFO"},
                f"Target topology changed: {detached} face-points lost their target face and became "
                f"space-points, {reattached} re-attached",
            )
        return {"FINISHED"}

    def compute(self, context, bridge, operations, layout, arrays, target):
        """The operation's :class:`operations.Outcome`; raises one of ``bridge.ERRORS`` on bad input."""
        raise NotImplementedError

    def summary(self, outcome, milliseconds):
        """The report of a finished operation."""
        raise NotImplementedError


class LayoutCollectionOperator:
    """Shared poll, guard and report of the operators that edit what the layout keeps besides its
    positions: its lists (anchors, curve constraints) and its rest shape.

    A subclass names the list (``collection``) and what to say when it is empty, and implements
    :meth:`run`: compute the complete new list, write it through the bridge, and return the
    reports. Everything is checked before anything is written; any problem is reported as an
    error and the list is left exactly as it was.
    """

    collection = ""
    """Name of the collection property on ``object.springwrap``."""
    empty_message = ""
    """The poll message when the collection is needed but empty."""
    requires_target = True
    requires_items = False
    reads_layout_mesh = True  # leaves edit mode for the duration, so the mesh data is current

    @classmethod
    def problem(cls, context):
        """Why the operator cannot run on the active object, or None when it can."""
        problem = layout_problem(context, cls.requires_target)
        if problem is not None:
            return problem
        if cls.requires_items and not len(getattr(context.active_object.springwrap, cls.collection)):
            return cls.empty_message
        return None

    @classmethod
    def poll(cls, context):
        problem = cls.problem(context)
        if problem is not None:
            cls.poll_message_set(problem)
            return False
        return True

    def execute(self, context):
        problem = self.problem(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return {"CANCELLED"}
        bridge = import_bridge(self)
        if bridge is None:
            return {"CANCELLED"}
        layout = context.active_object
        try:
            mode = bridge.object_mode(layout) if self.reads_layout_mesh else contextlib.nullcontext()
            with mode:
                reports = self.run(context, bridge, layout)
        except bridge.ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        for level, message in reports:
            self.report(level, message)
        return {"FINISHED"}

    def run(self, context, bridge, layout):
        """Compute and write the new list; return ``[(report level set, message), ...]``.

        Raises one of ``bridge.ERRORS`` on bad input, before writing anything."""
        raise NotImplementedError


class SPRINGWRAP_OT_detach(_LayoutOperator, bpy.types.Operator):
    """Detach vertices from the target: they become space-points and keep their positions"""

    bl_idname = "springwrap.detach"
    bl_label = "Detach"
    bl_options = {"REGISTER", "UNDO"}

    requires_target = False
    moves_vertices = False

    def compute(self, context, bridge, operations, layout, arrays, target):
        return operations.detach(arrays, target, layout.springwrap.target_signature, self.only_selected)

    def summary(self, outcome, milliseconds):
        return f"Detached {outcome.changed_count} vertices in {milliseconds:.1f} ms"


class SPRINGWRAP_OT_snap(_LayoutOperator, bpy.types.Operator):
    """Snap vertices onto the target (closest surface point or nearest vertex); they become face-points"""

    bl_idname = "springwrap.snap"
    bl_label = "Snap"
    bl_options = {"REGISTER", "UNDO"}

    mode: bpy.props.EnumProperty(name="Mode", items=SNAP_MODE_ITEMS, default="SURFACE")
    max_distance: max_distance_property("Vertices farther than this from the target are left untouched (0 = unlimited)")

    def compute(self, context, bridge, operations, layout, arrays, target):
        return operations.snap(
            arrays, target, layout.springwrap.target_signature, self.only_selected, self.mode, self.max_distance
        )

    def summary(self, outcome, milliseconds):
        text = (
            f"Snapped {outcome.changed_count} vertices ({self.mode}), "
            f"max distance {outcome.moved_distance:.4g} in {milliseconds:.1f} ms"
        )
        if outcome.missed_count:
            text += f"; {outcome.missed_count} beyond max distance left untouched"
        return text


class SPRINGWRAP_OT_project(_LayoutOperator, bpy.types.Operator):
    """Project vertices onto the target along a direction (ray cast); hits become face-points"""

    bl_idname = "springwrap.project"
    bl_label = "Project"
    bl_options = {"REGISTER", "UNDO"}

    direction: bpy.props.EnumProperty(name="Direction", items=PROJECT_DIRECTION_ITEMS, default="NORMAL")
    orientation: bpy.props.EnumProperty(
        name="Orientation",
        description="Space of the axis directions (View and Normal ignore it)",
        items=ORIENTATION_ITEMS,
        default="GLOBAL",
    )
    both_directions: bpy.props.BoolProperty(
        name="Both Directions",
        description="Also cast each ray backwards and keep the nearer hit",
        default=True,
    )
    max_distance: max_distance_property("Hits farther than this along the ray are ignored (0 = unlimited)")

    def compute(self, context, bridge, operations, layout, arrays, target):
        directions = self.world_directions(context, bridge, layout)
        return operations.project(
            arrays,
            target,
            layout.springwrap.target_signature,
            self.only_selected,
            directions,
            self.both_directions,
            self.max_distance,
        )

    def world_directions(self, context, bridge, layout):
        """One world-space direction, or (N, 3) per-vertex directions for NORMAL."""
        import numpy as np

        from . import layout_state

        if self.direction == "NORMAL":
            return bridge.read_world_normals(layout)
        if self.direction == "VIEW":
            region_3d = _view_region(context)
            if region_3d is None:
                raise layout_state.LayoutError("Project along View needs a 3D view (none in this context)")
            rotation = bridge.matrix_array(region_3d.view_rotation.to_matrix().to_4x4())
            return layout_state.transform_directions(rotation, np.array([0.0, 0.0, -1.0]))[0]
        axis = layout_state.axis_direction(self.direction)
        if self.orientation == "LOCAL":
            axis = layout_state.transform_directions(bridge.matrix_array(layout.matrix_world), axis)[0]
            if not np.any(axis):
                raise layout_state.LayoutError(f"Layout '{layout.name}' has zero scale along {self.direction}")
        return axis

    def summary(self, outcome, milliseconds):
        label = self.direction if self.direction in ("VIEW", "NORMAL") else f"{self.direction} {self.orientation}"
        text = (
            f"Projected {outcome.changed_count} vertices ({label}), "
            f"max distance {outcome.moved_distance:.4g} in {milliseconds:.1f} ms"
        )
        if outcome.missed_count:
            text += f"; {outcome.missed_count} missed the target and were left untouched"
        if outcome.skipped_count:
            text += f"; {outcome.skipped_count} on no face (no normal) skipped"
        return text


def _view_region(context):
    """The 3D view's region data: from the region itself, or the view of the sidebar's area."""
    region_3d = getattr(context, "region_data", None)
    if isinstance(region_3d, bpy.types.RegionView3D):
        return region_3d
    space = getattr(context, "space_data", None)
    if space is not None and space.type == "VIEW_3D":
        return space.region_3d
    return None


class SPRINGWRAP_OT_rest_set(LayoutCollectionOperator, bpy.types.Operator):
    """Take the layout's current shape as the template's rest shape: the shape the wrap's springs keep"""

    bl_idname = "springwrap.rest_set"
    bl_label = "Set Rest Shape"
    bl_options = {"REGISTER", "UNDO"}

    requires_target = False

    def run(self, context, bridge, layout):
        from . import operations

        arrays = bridge.read_layout(layout)
        operations.check_finite(arrays, np.ones(arrays.positions.shape[0], dtype=bool))
        operations.check_rest_edges(arrays.positions, bridge.read_layout_topology(layout).edges)
        bridge.write_rest(layout, arrays.positions)
        layout.data.update()
        return [({"INFO"}, f"Rest shape of '{layout.name}' set from its {arrays.positions.shape[0]} vertices")]


classes = (SPRINGWRAP_OT_detach, SPRINGWRAP_OT_snap, SPRINGWRAP_OT_project, SPRINGWRAP_OT_rest_set)
