"""Springwrap operators: detach, snap and project the active layout object onto its target; set its rest shape.

Each operator reads everything, computes the complete result (``core.snapping``), and writes only
when every step succeeded; any problem is reported as an error and the layout is left exactly as
it was.
"""

import time

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import attributes
from ..blender import layout as layout_data
from ..blender import quality as quality_data
from ..blender import target as target_data
from ..blender.edit_mode import object_mode
from ..core import layout_state, quality, snapping, transforms, wrap_inputs
from ..core.errors import ERRORS, LayoutError
from ..core.transforms import matrix_array
from ..properties import ORIENTATION_ITEMS, PROJECT_DIRECTION_ITEMS, SNAP_MODE_ITEMS, max_distance_property
from .base import (
    LayoutCollectionOperator,
    LayoutOperator,
    check_inputs,
    open_layout,
    report_storage_precision,
    topology_change_report,
)


class _SnapOperator(LayoutOperator):
    """Shared run and report of detach, snap and project."""

    moves_vertices = True
    carries_shape_keys = True  # layout.write_layout carries a layout's shape keys over onto the new basis
    reads = frozenset({"positions"})
    writes_readout = True  # the quality read-out (blender.quality), measured before and written with the layout

    only_selected: props.flag(
        "Only Selected",
        "Act on the selected vertices only (face-points whose target face is gone are still resolved everywhere)",
        False,
    )

    def execute(self, context):
        layout = open_layout(self, context, self.requires_target, self.moves_vertices)
        if layout is None:
            return {"CANCELLED"}
        start = time.perf_counter()
        try:
            with object_mode(layout):
                settings = layout.springwrap
                target = None
                if settings.target is not None:
                    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
                arrays = layout_data.read_layout(layout)  # once: checked, then computed on
                extent = check_inputs(context, layout, self.reads, arrays=arrays, target=target)
                outcome = self.compute(context, layout, arrays, target)
                readout = None
                # Points alone (no faces, no edges) are snapped too; the read-out measures faces and edges.
                if target is not None and self.writes_readout and (layout.data.polygons or layout.data.edges):
                    readout = quality_data.measure_layout(layout, target, outcome.positions, state=outcome.state)
                layout_data.write_layout(layout, outcome.positions, outcome.state)
                if readout is not None:
                    quality_data.write_readout(layout, readout)
                if target is not None:
                    settings.target_signature = target.signature
                report_storage_precision(self, layout, extent, outcome.positions)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        milliseconds = (time.perf_counter() - start) * 1000.0
        self.report({"INFO"}, self.summary(outcome, milliseconds))
        if readout is not None:
            self.report({"INFO"}, quality.report_line(readout))
        topology = topology_change_report(outcome, "face-points", "space-points")
        if topology:
            self.report(*topology)
        return {"FINISHED"}

    def compute(self, context, layout, arrays, target):
        """The operation's :class:`snapping.Outcome`; raises one of ``ERRORS`` on bad input."""
        raise NotImplementedError

    def summary(self, outcome, milliseconds):
        """The report of a finished operation."""
        raise NotImplementedError


class SPRINGWRAP_OT_detach(_SnapOperator, bpy.types.Operator):
    """Detach vertices from the target: they become space-points and keep their positions"""

    bl_label = "Detach"

    requires_target = False
    moves_vertices = False
    writes_readout = False

    def compute(self, context, layout, arrays, target):
        return snapping.detach(arrays, target, layout.springwrap.target_signature, self.only_selected)

    def summary(self, outcome, milliseconds):
        return f"Detached {outcome.changed_count} vertices in {milliseconds:.1f} ms"


class SPRINGWRAP_OT_snap(_SnapOperator, bpy.types.Operator):
    """Snap vertices onto the target (closest surface point or nearest vertex); they become face-points"""

    bl_label = "Snap"

    mode: bpy.props.EnumProperty(name="Mode", items=SNAP_MODE_ITEMS, default="SURFACE")
    max_distance: max_distance_property("Vertices farther than this from the target are left untouched (0 = unlimited)")

    def compute(self, context, layout, arrays, target):
        return snapping.snap(
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


class SPRINGWRAP_OT_project(_SnapOperator, bpy.types.Operator):
    """Project vertices onto the target along a direction (ray cast); hits become face-points"""

    bl_label = "Project"

    direction: bpy.props.EnumProperty(name="Direction", items=PROJECT_DIRECTION_ITEMS, default="NORMAL")
    orientation: props.choice(
        "Orientation", "Space of the axis directions (View and Normal ignore it)", ORIENTATION_ITEMS, "GLOBAL"
    )
    both_directions: props.flag("Both Directions", "Also cast each ray backwards and keep the nearer hit", True)
    max_distance: max_distance_property("Hits farther than this along the ray are ignored (0 = unlimited)")

    def compute(self, context, layout, arrays, target):
        directions = self.world_directions(context, layout)
        return snapping.project(
            arrays,
            target,
            layout.springwrap.target_signature,
            self.only_selected,
            directions,
            self.both_directions,
            self.max_distance,
        )

    def world_directions(self, context, layout):
        """One world-space direction, or (N, 3) per-vertex directions for NORMAL."""
        if self.direction == "NORMAL":
            return layout_data.read_world_normals(layout)
        if self.direction == "VIEW":
            region_3d = _view_region(context)
            if region_3d is None:
                raise LayoutError("Project along View needs a 3D view (none in this context)")
            rotation = matrix_array(region_3d.view_rotation.to_matrix().to_4x4())
            return transforms.transform_directions(rotation, np.array([0.0, 0.0, -1.0]))[0]
        axis = transforms.axis_direction(self.direction)
        if self.orientation == "LOCAL":
            axis = transforms.transform_directions(matrix_array(layout.matrix_world), axis)[0]
            if not np.any(axis):
                raise LayoutError(f"Layout '{layout.name}' has zero scale along {self.direction}")
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

    bl_label = "Set Rest Shape"

    requires_target = False
    reads = frozenset({"positions"})

    def run(self, context, layout):
        arrays = layout_data.read_layout(layout)
        layout_state.check_finite(arrays, np.ones(arrays.positions.shape[0], dtype=bool))
        wrap_inputs.check_rest_edges(arrays.positions, layout_data.read_layout_topology(layout).edges)
        attributes.write_rest(layout, arrays.positions)
        layout.data.update()
        return [({"INFO"}, f"Rest shape of '{layout.name}' set from its {arrays.positions.shape[0]} vertices")]


classes = (SPRINGWRAP_OT_detach, SPRINGWRAP_OT_snap, SPRINGWRAP_OT_project, SPRINGWRAP_OT_rest_set)
