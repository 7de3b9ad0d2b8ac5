"""Springwrap anchor operators: add, spread, update, remove and clear the active layout's anchors.

An anchor pairs a layout vertex with a target point (paper section 2.4). Each operator reads
everything, computes the complete new anchor list (``anchors``), and writes it only when every
step succeeded; any problem is reported as an error and the anchors are left exactly as they were.
"""

import time

import bpy

import numpy as np

from ..blender import anchors as anchor_data
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..core import anchor_twins, anchors, input_policy, symmetry, transforms
from ..core.errors import LayoutError
from ..properties import ANCHOR_METHOD_ITEMS, SYMMETRY_AXIS_ITEMS, max_distance_property
from .base import LayoutCollectionOperator


def symmetric_property():
    """``symmetric`` of Add and Auto Anchors."""
    return bpy.props.BoolProperty(
        name="Symmetric",
        description="Also anchor each vertex's twin across the symmetry plane (by topology, else by position) to the "
        "closest target point of the reflected target point; the two are a pair",
        default=False,
    )


def symmetry_axis_property():
    """``symmetry_axis`` of Add and Auto Anchors."""
    return bpy.props.EnumProperty(
        name="Symmetry Axis",
        description="The symmetry plane is perpendicular to this local axis of the layout (or of the symmetry object)",
        items=SYMMETRY_AXIS_ITEMS,
        default="X",
    )


def symmetry_object_property():
    """``symmetry_object`` of Add and Auto Anchors."""
    return bpy.props.StringProperty(
        name="Symmetry Object",
        description="Name of an Empty whose local plane (through its origin) is the symmetry plane; empty: the layout's",
        default="",
    )


class _AnchorOperator(LayoutCollectionOperator):
    """Shared run and report of the anchor operators."""

    collection = "anchors"
    empty_message = "The layout has no anchors"

    def run(self, context, layout):
        start = time.perf_counter()
        outcome, signature = self.compute(context, layout)
        anchor_data.write_anchors(layout, outcome.anchors, outcome.active_index, signature)
        milliseconds = (time.perf_counter() - start) * 1000.0
        reports = [({"INFO"}, self.summary(anchors, outcome, milliseconds))]
        reports += self.twin_reports()
        detached, reattached = outcome.topology_detached_count, outcome.topology_reattached_count
        if detached or reattached:
            reports.append(
                (
                    {"WARNING"} if detached else {"INFO"},
                    f"Target topology changed: {detached} face anchors lost their target face and became "
                    f"space anchors, {reattached} re-attached",
                )
            )
        return reports

    def compute(self, context, layout):
        """``(anchors.AnchorOutcome, signature or None)``; raises one of ``ERRORS`` on bad input."""
        raise NotImplementedError

    def twin_reports(self):
        """What the symmetric half did, when the operation was symmetric (``self._twins``)."""
        report = getattr(self, "_twins", None)
        if report is None:
            return []
        lone = []
        if report.no_vertex_count:
            lone.append(f"{report.no_vertex_count} with no twin vertex (asymmetric layout there)")
        if report.no_target_count:
            lone.append(f"{report.no_target_count} with no target point near the reflection")
        if not lone:
            return []
        return [
            ({"WARNING"}, f"Symmetric anchors across the plane of '{self._plane_owner}': left alone " + ", ".join(lone))
        ]

    def read_twins(self, layout):
        """The layout's vertex twins across the chosen symmetry plane, and the plane (object mode data)."""
        arrays = layout_data.read_layout(layout)
        topology = layout_data.read_layout_topology(layout)
        plane, self._plane_owner = anchor_data.read_symmetry_plane(
            layout, self.symmetry_axis, self.symmetry_object, self.extent
        )
        world = transforms.world_positions(arrays)
        return symmetry.vertex_twins(world, topology.face_corners, topology.face_sizes, topology.edges, plane), plane

    def summary(self, anchors, outcome, milliseconds):
        """The report of a finished operation."""
        raise NotImplementedError


class SPRINGWRAP_OT_anchor_add(_AnchorOperator, bpy.types.Operator):
    """Anchor a layout vertex to the target point closest to the 3D cursor (or to a given location)"""

    bl_idname = "springwrap.anchor_add"
    bl_label = "Add Anchor"
    bl_options = {"REGISTER", "UNDO"}

    @property
    def reads(self):
        """A symmetric add reads the layout's vertices too (for the twins)."""
        return frozenset({"anchors", "positions"} if self.symmetric else {"anchors"})

    vertex_index: bpy.props.IntProperty(
        name="Vertex Index",
        description="Layout vertex to anchor; -1 for the active selected vertex (or the only selected one)",
        default=-1,
        soft_min=-1,
    )
    location: bpy.props.FloatVectorProperty(
        name="Location",
        description="World-space point whose closest target point becomes the anchor's target",
        size=3,
        default=(0.0, 0.0, 0.0),
        subtype="XYZ",
        unit="LENGTH",
    )
    use_location: bpy.props.BoolProperty(
        name="Use Location",
        description="Use Location instead of the 3D cursor",
        default=False,
    )
    on_surface: bpy.props.BoolProperty(
        name="On Surface",
        description="The target is the closest point of the target surface; off: the location itself (a space anchor)",
        default=True,
    )
    symmetric: symmetric_property()
    symmetry_axis: symmetry_axis_property()
    symmetry_object: symmetry_object_property()

    def compute(self, context, layout):
        selection, active_vertex = layout_data.read_vertex_selection(layout)
        if not selection.size:
            raise LayoutError(f"Layout '{layout.name}' has no vertices")
        if self.vertex_index == -1:
            self._vertex = anchors.pick_vertex(selection, active_vertex)
        else:
            self._vertex = anchors.check_vertex_index(self.vertex_index, selection.size)
        source = self.location if self.use_location else context.scene.cursor.location
        self._source = input_policy.check_location(
            tuple(source), "The anchor location" if self.use_location else "The 3D cursor", self.extent
        )
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        arguments = (
            selection.size,
            anchor_data.read_anchors(layout),
            target,
            layout.springwrap.anchors_signature,
            self._vertex,
            self._source,
            self.on_surface,
        )
        self._twins = None
        if not self.symmetric:
            return anchors.add(*arguments), target.signature
        twins, plane = self.read_twins(layout)
        outcome, self._twins = anchor_twins.add(*arguments, twins, plane)
        return outcome, target.signature

    def summary(self, anchors, outcome, milliseconds):
        own = outcome.active_index
        location = outcome.anchors.locations[own]
        where = "the target surface" if outcome.anchors.kinds[own] == anchors.FACE_ANCHOR else "a point in space"
        distance = float(np.linalg.norm(location - self._source))
        source = "location" if self.use_location else "3D cursor"
        text = (
            f"Anchored vertex {self._vertex} to {where} at ({location[0]:.4g}, {location[1]:.4g}, "
            f"{location[2]:.4g}), {distance:.4g} from the {source}"
        )
        if outcome.replaced_count and self._twins is not None:
            text += f"; replaced {outcome.replaced_count} previous anchor(s) on the pair's vertices"
        elif outcome.replaced_count:
            text += "; replaced its previous anchor"
        twins = self._twins
        if twins is not None and twins.twin_vertex >= 0:
            text += f"; its twin: vertex {twins.twin_vertex} ({twins.how})"
        elif twins is not None and twins.on_plane_count:
            text += "; it is on the symmetry plane: its own twin"
        return text


class SPRINGWRAP_OT_anchors_auto(_AnchorOperator, bpy.types.Operator):
    """Spread anchors evenly over the layout (no two closer than the spacing), targets by closest point or projection"""

    bl_idname = "springwrap.anchors_auto"
    bl_label = "Auto Anchors"
    bl_options = {"REGISTER", "UNDO"}

    reads = frozenset({"positions", "anchors"})

    spacing: bpy.props.FloatProperty(
        name="Spacing",
        description="Smallest distance between two anchored layout vertices (0 = a tenth of the layout's size)",
        default=0.0,
        min=0.0,
        subtype="DISTANCE",
        unit="LENGTH",
    )
    method: bpy.props.EnumProperty(name="Method", items=ANCHOR_METHOD_ITEMS, default="CLOSEST")
    replace: bpy.props.BoolProperty(
        name="Replace",
        description="Remove the existing anchors first; off: keep them and anchor other vertices only",
        default=True,
    )
    max_distance: max_distance_property(
        "Vertices whose target point is farther than this get no anchor (0 = unlimited)"
    )
    symmetric: symmetric_property()
    symmetry_axis: symmetry_axis_property()
    symmetry_object: symmetry_object_property()

    def compute(self, context, layout):
        arrays = layout_data.read_layout(layout)
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        normals = layout_data.read_world_normals(layout) if self.method == "PROJECT" else None
        arguments = (
            arrays,
            normals,
            anchor_data.read_anchors(layout),
            target,
            layout.springwrap.anchors_signature,
            self.spacing,
            self.method,
            self.replace,
            self.max_distance,
        )
        self._twins = None
        if not self.symmetric:
            return anchors.auto(*arguments), target.signature
        twins, plane = self.read_twins(layout)
        outcome, self._twins, self._side = anchor_twins.auto(*arguments, twins, plane)
        return outcome, target.signature

    def summary(self, anchors, outcome, milliseconds):
        text = (
            f"Added {outcome.added_count} anchors (spacing {outcome.spacing:.4g}, {self.method}) "
            f"in {milliseconds:.1f} ms"
        )
        if self.replace and outcome.replaced_count:
            text += f"; replaced {outcome.replaced_count} existing anchors"
        elif not self.replace:
            text += f"; kept {anchors.anchor_count(outcome.anchors) - outcome.added_count} existing anchors"
        if outcome.missed_count:
            text += f"; {outcome.missed_count} vertices missed the target (no anchor)"
        if outcome.skipped_count:
            text += f"; {outcome.skipped_count} on no face (no normal) skipped"
        if self._twins is not None:
            side = "+" if self._side > 0 else "-"
            text += (
                f"; symmetric across '{self._plane_owner}' ({self.symmetry_axis}): spread on the {side} side, "
                f"{self._twins.paired_count} pairs, {self._twins.on_plane_count} on the plane"
            )
        return text


class SPRINGWRAP_OT_anchors_update(_AnchorOperator, bpy.types.Operator):
    """Follow the target: refresh the anchors' target points and re-find those whose target face changed"""

    bl_idname = "springwrap.anchors_update"
    bl_label = "Update Anchors"
    bl_options = {"REGISTER", "UNDO"}

    requires_items = True
    reads_layout_mesh = False
    reads = frozenset({"anchors"})

    def compute(self, context, layout):
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        outcome = anchors.update(anchor_data.read_anchors(layout), target, layout.springwrap.anchors_signature)
        return outcome, target.signature

    def summary(self, anchors, outcome, milliseconds):
        face_count, space_count = anchors.kind_counts(outcome.anchors)
        return f"Updated {face_count + space_count} anchors ({face_count} on the surface, {space_count} in space)"


class SPRINGWRAP_OT_anchor_remove(_AnchorOperator, bpy.types.Operator):
    """Remove an anchor (the active one by default)"""

    bl_idname = "springwrap.anchor_remove"
    bl_label = "Remove Anchor"
    bl_options = {"REGISTER", "UNDO"}

    requires_target = False
    requires_items = True
    reads_layout_mesh = False
    reads = frozenset()  # the way out of a broken anchor: nothing is checked

    index: bpy.props.IntProperty(
        name="Index",
        description="Position of the anchor in the list; -1 for the active anchor",
        default=-1,
        soft_min=-1,
    )
    with_twin: bpy.props.BoolProperty(
        name="With Twin",
        description="Remove the anchor's symmetric twin too; off: only this one (its twin stays, unpaired)",
        default=True,
    )

    def compute(self, context, layout):
        existing = anchor_data.read_anchors(layout)
        index = layout.springwrap.active_anchor_index if self.index == -1 else self.index
        self._vertex = int(existing.vertex_indices[index]) if 0 <= index < anchors.anchor_count(existing) else -1
        remaining = anchors.remove(existing, index, self.with_twin)
        count = anchors.anchor_count(remaining)
        self._removed = anchors.anchor_count(existing) - count
        active = anchors.clamp_active_index(min(index, count - 1), count)
        return _list_outcome(anchors, remaining, active), None

    def summary(self, anchors, outcome, milliseconds):
        both = " and its twin" if self._removed == 2 else ""
        return (
            f"Removed the anchor of vertex {self._vertex}{both}; {anchors.anchor_count(outcome.anchors)} anchors left"
        )


class SPRINGWRAP_OT_anchors_clear(_AnchorOperator, bpy.types.Operator):
    """Remove every anchor of the layout"""

    bl_idname = "springwrap.anchors_clear"
    bl_label = "Clear Anchors"
    bl_options = {"REGISTER", "UNDO"}

    requires_target = False
    requires_items = True
    reads_layout_mesh = False
    reads = frozenset()  # the way out of a broken anchor: nothing is checked

    def compute(self, context, layout):
        self._count = len(layout.springwrap.anchors)
        return _list_outcome(anchors, anchors.no_anchors(), 0), None

    def summary(self, anchors, outcome, milliseconds):
        return f"Removed {self._count} anchors"


def _list_outcome(anchors, anchor_list, active_index):
    """An :class:`anchors.AnchorOutcome` that only replaces the list (no query, no target)."""
    return anchors.AnchorOutcome(anchor_list, active_index, 0, 0, 0, 0, 0.0, 0, 0)


classes = (
    SPRINGWRAP_OT_anchor_add,
    SPRINGWRAP_OT_anchors_auto,
    SPRINGWRAP_OT_anchors_update,
    SPRINGWRAP_OT_anchor_remove,
    SPRINGWRAP_OT_anchors_clear,
)
