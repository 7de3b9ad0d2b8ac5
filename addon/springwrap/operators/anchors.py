"""Springwrap anchor operators: add, spread, update, remove and clear the active layout's anchors.

An anchor pairs a layout vertex with a target point (paper section 2.4). Each operator reads
everything, computes the complete new anchor list (``anchors``), and writes it only when every
step succeeded; any problem is reported as an error and the anchors are left exactly as they were.
"""

import time

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..core import anchor_twins, anchors, input_policy
from ..core.errors import LayoutError
from ..properties import ANCHOR_METHOD_ITEMS, SYMMETRY_AXIS_ITEMS, max_distance_property
from .base import LayoutCollectionOperator, RemovesItems, RemovesOneItem, topology_change_report


def symmetric_property():
    """``symmetric`` of Add and Auto Anchors."""
    return props.flag(
        "Symmetric",
        "Also anchor each vertex's twin across the symmetry plane (by topology, else by position) to the closest "
        "target point of the reflected target point; the two are a pair",
        False,
    )


def symmetry_axis_property():
    """``symmetry_axis`` of Add and Auto Anchors."""
    return props.choice(
        "Symmetry Axis",
        "The symmetry plane is perpendicular to this local axis of the layout (or of the symmetry object)",
        SYMMETRY_AXIS_ITEMS,
        "X",
    )


def symmetry_object_property():
    """``symmetry_object`` of Add and Auto Anchors."""
    return props.text(
        "Symmetry Object",
        "Name of an Empty whose local plane (through its origin) is the symmetry plane; empty: the layout's",
    )


ANCHOR_ADD_HOW = (
    "Enter Edit Mode and select the layout vertex to anchor (the 3D cursor on its target point), or use the Pair tool"
)
"""What **+** says outside Edit Mode when the selection picks no vertex."""


class _AnchorOperator(LayoutCollectionOperator):
    """Shared run and report of the anchor operators."""

    collection = "anchors"
    active_index = "active_anchor_index"
    empty_message = "The layout has no anchors"

    def run(self, context, layout):
        start = time.perf_counter()
        outcome, signature = self.compute(context, layout)
        anchor_data.write_anchors(layout, outcome.anchors, outcome.active_index, signature)
        milliseconds = (time.perf_counter() - start) * 1000.0
        topology = topology_change_report(outcome, "face anchors", "space anchors")
        reports = [({"INFO"}, self.summary(anchors, outcome, milliseconds)), *self.twin_reports()]
        return reports + ([topology] if topology else [])

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

    def maybe_symmetric(self, layout, plain, symmetric, *arguments):
        """``plain(*arguments)`` (``core.anchors``), or with ``symmetric`` on the same through ``symmetric``
        (``core.anchor_twins``) with the layout's twins; what the twins did is kept for the report."""
        self._twins = self._side = None
        if not self.symmetric:
            return plain(*arguments)
        outcome, self._twins, *side = symmetric(*self.read_twins(layout), *arguments)
        self._side = side[0] if side else None
        return outcome

    def read_twins(self, layout):
        """The layout's vertex twins across the chosen symmetry plane, and the plane (object mode data)."""
        twins, plane, self._plane_owner = anchor_data.read_vertex_twins(
            layout, self.symmetry_axis, self.symmetry_object, self.extent
        )
        return twins, plane

    def summary(self, anchors, outcome, milliseconds):
        """The report of a finished operation."""
        raise NotImplementedError


class SPRINGWRAP_OT_anchor_add(_AnchorOperator, bpy.types.Operator):
    """Anchor a layout vertex to the target point closest to the 3D cursor (or to a given location)"""

    bl_label = "Add Anchor"

    @property
    def reads(self):
        """A symmetric add reads the layout's vertices too (for the twins)."""
        return frozenset({"anchors", "positions"} if self.symmetric else {"anchors"})

    vertex_index: props.integer(
        "Vertex Index",
        "Layout vertex to anchor; -1 for the active selected vertex (or the only selected one)",
        -1,
        soft_min=-1,
    )
    location: props.point("Location", "World-space point whose closest target point becomes the anchor's target")
    use_location: props.flag("Use Location", "Use Location instead of the 3D cursor", False)
    on_surface: props.flag(
        "On Surface",
        "The target is the closest point of the target surface; off: the location itself (a space anchor)",
        True,
    )
    symmetric: symmetric_property()
    symmetry_axis: symmetry_axis_property()
    symmetry_object: symmetry_object_property()

    def compute(self, context, layout):
        selection, active_vertex = layout_data.read_vertex_selection(layout)
        if not selection.size:
            raise LayoutError(f"Layout '{layout.name}' has no vertices")
        if self.vertex_index == -1:
            self._vertex = self.pick_vertex(layout, selection, active_vertex)
        else:
            self._vertex = anchors.check_vertex_index(self.vertex_index, selection.size)
        source = self.location if self.use_location else context.scene.cursor.location
        self._source = input_policy.check_location(
            tuple(source), "The anchor location" if self.use_location else "The 3D cursor", self.extent
        )
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        existing = (selection.size, anchor_data.read_anchors(layout), target, layout.springwrap.anchors_signature)
        anchor = (self._vertex, self._source, self.on_surface)
        return self.maybe_symmetric(layout, anchors.add, anchor_twins.add, *existing, *anchor), target.signature

    def execute(self, context):
        obj = context.active_object
        self._editing = obj is not None and obj.mode == "EDIT"  # the operation runs out of edit mode
        return super().execute(context)

    def pick_vertex(self, layout, selection, active_vertex):
        """The vertex to anchor when none is given: the active (or only) selected one. Outside Edit Mode a
        selection that picks none is no hint of a mistake (every vertex may be selected there): say how to pick."""
        try:
            return anchors.pick_vertex(selection, active_vertex)
        except LayoutError:
            if self._editing:
                raise
            raise LayoutError(ANCHOR_ADD_HOW) from None

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

    bl_label = "Auto Anchors"

    reads = frozenset({"positions", "anchors"})

    spacing: props.distance(
        "Spacing", "Smallest distance between two anchored layout vertices (0 = a tenth of the layout's size)"
    )
    method: bpy.props.EnumProperty(name="Method", items=ANCHOR_METHOD_ITEMS, default="CLOSEST")
    replace: props.flag(
        "Replace",
        "Remove the existing anchors first; off (the default): keep them (anchors placed by hand) and anchor other "
        "vertices around them",
        False,
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
        existing = (arrays, normals, anchor_data.read_anchors(layout), target, layout.springwrap.anchors_signature)
        spread = (self.spacing, self.method, self.replace, self.max_distance)
        return self.maybe_symmetric(layout, anchors.auto, anchor_twins.auto, *existing, *spread), target.signature

    def summary(self, anchors, outcome, milliseconds):
        added = f"{outcome.added_count} anchors (spacing {outcome.spacing:.4g}, {self.method}) in {milliseconds:.1f} ms"
        kept = anchors.anchor_count(outcome.anchors) - outcome.added_count
        if kept:
            text = f"Kept {kept} existing anchors and added {added}"
        elif outcome.replaced_count:
            text = f"Replaced the {outcome.replaced_count} existing anchors with {added}"
        else:
            text = f"Added {added}"
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

    bl_label = "Update Anchors"

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


class SPRINGWRAP_OT_anchor_remove(RemovesOneItem, _AnchorOperator, bpy.types.Operator):
    """Remove an anchor (the active one by default)"""

    bl_label = "Remove Anchor"

    with_twin: props.flag(
        "With Twin", "Remove the anchor's symmetric twin too; off: only this one (its twin stays, unpaired)", True
    )

    def remove(self, layout, index):
        existing = anchor_data.read_anchors(layout)
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


class SPRINGWRAP_OT_anchors_clear(RemovesItems, _AnchorOperator, bpy.types.Operator):
    """Remove every anchor of the layout"""

    bl_label = "Clear Anchors"

    def compute(self, context, layout):
        self._count = len(layout.springwrap.anchors)
        return _list_outcome(anchors, anchors.no_anchors(), 0), None

    def summary(self, anchors, outcome, milliseconds):
        return f"Removed {self._count} anchors"


def _list_outcome(anchors, anchor_list, active_index):
    """An :class:`anchors.AnchorOutcome` that only replaces the list (no query, no target)."""
    return anchors.AnchorOutcome(anchor_list, active_index)


classes = (
    SPRINGWRAP_OT_anchor_add,
    SPRINGWRAP_OT_anchors_auto,
    SPRINGWRAP_OT_anchors_update,
    SPRINGWRAP_OT_anchor_remove,
    SPRINGWRAP_OT_anchors_clear,
)
