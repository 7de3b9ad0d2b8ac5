"""Springwrap curve-constraint operators: add, pair automatically, remove and clear.

A curve constraint pairs a layout edge chain with a target curve (paper section 2.4): a Blender
curve object or a chain of target mesh edges. Each operator reads everything, computes the
complete new constraint list (``curves``), and writes it only when every step succeeded; any
problem is reported as an error and the constraints are left exactly as they were.
"""

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import curves as curve_data
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..core import anchors, curves, edge_paths, input_policy
from ..core.errors import LayoutError
from .base import LayoutCollectionOperator, RemovesItems, RemovesOneItem


class _CurveOperator(LayoutCollectionOperator):
    """Shared run and report of the curve-constraint operators."""

    collection = "curve_constraints"
    active_index = "active_curve_constraint_index"
    empty_message = "The layout has no curve constraints"

    def run(self, context, layout):
        constraints, active_index = self.compute(context, layout)
        curve_data.write_curve_constraints(layout, constraints, active_index)
        return [({"INFO"}, self.summary(constraints))]

    def compute(self, context, layout):
        """``(complete new list of curves.CurveConstraint, active index)``; raises one of ``ERRORS``."""
        raise NotImplementedError

    def summary(self, constraints):
        """The report of a finished operation."""
        raise NotImplementedError


class SPRINGWRAP_OT_curve_constraint_add(_CurveOperator, bpy.types.Operator):
    """Pair the selected layout edge chain with a target curve: a curve object, or the target edges between its ends' anchors"""

    bl_label = "Add Curve Constraint"

    curve_object: props.text(
        "Curve Object",
        "Name of the curve object the chain follows; empty: the chain of target edges along the layout chain's "
        "course between the target vertices nearest to its end anchors (or to its end vertices where they have "
        "none)",
    )

    def compute(self, context, layout):
        depsgraph = context.evaluated_depsgraph_get()
        chain = edge_paths.chain_from_edges(layout_data.read_selected_edges(layout))
        existing = curve_data.read_curve_constraints(layout)
        anchor_list = anchor_data.read_anchors(layout)
        vertex_count = len(layout.data.vertices)
        anchored = anchors.anchored_mask(anchor_list, vertex_count)
        curves.check_free(chain, existing, anchored)
        chain_positions = layout_data.read_world_vertex_positions(layout, chain)
        if self.curve_object:
            curve_object = bpy.data.objects.get(self.curve_object)
            if curve_object is None or curve_object.type != "CURVE":
                raise LayoutError(f"There is no curve object called '{self.curve_object}'")
            points = curve_data.read_curve_polyline(depsgraph, curve_object, near=chain_positions)
            input_policy.check_points(
                points, lambda row: f"Curve '{curve_object.name}': point {row}", self.extent, "fix the curve"
            )
            points = curves.orient_to_chain(points, chain_positions)
            new = curves.make_constraint(chain, points, curves.CURVE_OBJECT, (), curve_object)
        else:
            location_of = {
                int(vertex): location
                for vertex, location in zip(anchor_list.vertex_indices.tolist(), anchor_list.locations)
            }
            start = location_of.get(int(chain[0]), chain_positions[0])
            end = location_of.get(int(chain[-1]), chain_positions[-1])
            target_positions, target_edges = target_data.read_target_edges(depsgraph, layout)
            new = curves.target_edge_constraint(chain, chain_positions, start, end, target_positions, target_edges)
        self._new = new
        return existing + [new], len(existing)

    def summary(self, constraints):
        new = self._new
        source = (
            f"curve '{new.curve_object.name}'"
            if new.source_kind == "CURVE_OBJECT"
            else f"a chain of {new.target_vertices.size - 1} target edges"
        )
        return (
            f"Paired a chain of {new.layout_vertices.size} layout vertices ({int(new.layout_vertices[0])} to "
            f"{int(new.layout_vertices[-1])}) with {source}; {len(constraints)} curve constraints"
        )


class SPRINGWRAP_OT_curve_constraints_auto(_CurveOperator, bpy.types.Operator):
    """Pair every layout curve (border, seam, loose chain) whose two ends are anchored with the target edges along it between the anchors"""

    bl_label = "Auto Curve Constraints"

    def run(self, context, layout):
        constraints, active_index = self.compute(context, layout)
        curve_data.write_curve_constraints(layout, constraints, active_index)
        level, text = curves.auto_pairs_report(self._curve_count, self._outcome)
        return [({level}, text)]

    def compute(self, context, layout):
        existing = curve_data.read_curve_constraints(layout)
        anchor_list = anchor_data.read_anchors(layout)
        target_positions, target_edges = target_data.read_target_edges(context.evaluated_depsgraph_get(), layout)
        layout_curves = layout_data.read_layout_curves(layout)
        self._curve_count = len(layout_curves)
        outcome = curves.auto_pairs(
            layout_curves,
            anchor_list.vertex_indices,
            anchor_list.locations,
            existing,
            target_positions,
            target_edges,
            layout_data.read_world_vertex_positions(layout, np.arange(len(layout.data.vertices))),
        )
        self._outcome = outcome
        return existing + outcome.constraints, -1


class SPRINGWRAP_OT_curve_constraint_remove(RemovesOneItem, _CurveOperator, bpy.types.Operator):
    """Remove a curve constraint (the active one by default)"""

    bl_label = "Remove Curve Constraint"

    def remove(self, layout, index):
        existing = curve_data.read_curve_constraints(layout)
        if not 0 <= index < len(existing):
            raise LayoutError(f"There is no curve constraint {index}: the layout has {len(existing)}")
        remaining = existing[:index] + existing[index + 1 :]
        return remaining, max(min(index, len(remaining) - 1), 0)

    def summary(self, constraints):
        return f"Removed a curve constraint; {len(constraints)} left"


class SPRINGWRAP_OT_curve_constraints_clear(RemovesItems, _CurveOperator, bpy.types.Operator):
    """Remove every curve constraint of the layout"""

    bl_label = "Clear Curve Constraints"

    def compute(self, context, layout):
        self._count = len(layout.springwrap.curve_constraints)
        return [], 0

    def summary(self, constraints):
        return f"Removed {self._count} curve constraints"


classes = (
    SPRINGWRAP_OT_curve_constraint_add,
    SPRINGWRAP_OT_curve_constraints_auto,
    SPRINGWRAP_OT_curve_constraint_remove,
    SPRINGWRAP_OT_curve_constraints_clear,
)
