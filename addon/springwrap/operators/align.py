"""``springwrap.align``: bring the layout into place before it is attached (paper section 2.2).

A transform is fitted to the anchors (rigid, similarity or affine, least squares) and optionally
refined by ICP against the target; it is applied to the layout object's transform or baked into
its vertices. The template then floats free of the target: every face-point becomes a
space-point, to be attached by projection, snap or the wrap.
"""

import time

import bpy

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..blender.edit_mode import object_mode
from ..core import alignment, anchors, proposals
from ..core.errors import ERRORS
from ..properties import max_distance_property
from .base import READS_LAYOUT, LayoutOperator, check_inputs, open_layout, operator_values

METHOD_ITEMS = (
    ("RIGID", "Rigid", "Rotation and translation (needs 3 anchors not on one line)"),
    ("SIMILARITY", "Similarity", "Rotation, translation and uniform scale (needs 3 anchors not on one line)"),
    (
        "AFFINE",
        "Affine",
        "Any linear map and translation: also stretches and shears (needs 4 anchors not in one plane)",
    ),
)
APPLY_ITEMS = (
    ("OBJECT", "Object Transform", "Change the layout object's location, rotation and scale; the mesh stays as it is"),
    ("BAKE", "Bake into Vertices", "Move the layout's vertices; the object's transform stays as it is"),
)


class SPRINGWRAP_OT_align(LayoutOperator, bpy.types.Operator):
    """Align the layout to its target: fit a transform to the anchors, then refine it by ICP"""

    bl_label = "Align"
    carries_shape_keys = True  # a baked alignment carries the layout's shape keys over (layout.write_layout)

    method: props.choice(
        "Method",
        "Transform fitted to the anchors (least squares); ICP refines rigid fits rigidly, the others by similarity steps",
        METHOD_ITEMS,
        "SIMILARITY",
    )
    use_anchors: props.flag(
        "Fit Anchors", "Fit the transform to the anchors; off: ICP alone, from the current placement", True
    )
    use_icp: props.flag("ICP", "Refine by iterative closest points against the target (point-to-plane, trimmed)", True)
    icp_iterations: props.integer("ICP Iterations", "Most ICP iterations to run", 50, min=1, max=10_000)
    trim_fraction: props.number(
        "Trim",
        "Fraction of the farthest pairs ICP ignores each iteration (outliers, parts the target lacks)",
        0.1,
        min=0.0,
        max=0.95,
        subtype="FACTOR",
    )
    max_distance: max_distance_property("ICP ignores layout vertices farther than this from the target (0 = unlimited)")
    anchor_weight: props.number(
        "Anchor Weight",
        "How firmly ICP keeps the anchors where the fit put them: all anchors together weigh this "
        "much against the whole surface (0: ICP follows the surface alone)",
        0.3,
        min=0.0,
        soft_max=10.0,
    )
    only_selected: props.flag(
        "Only Selected",
        "ICP uses the selected layout vertices only (the transform still moves the whole layout)",
        False,
    )
    apply: props.choice("Apply", "Where the alignment goes", APPLY_ITEMS, "OBJECT")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "method")
        layout.prop(self, "use_anchors")
        layout.prop(self, "use_icp")
        column = layout.column()
        column.active = self.use_icp
        for name in ("icp_iterations", "trim_fraction", "max_distance", "anchor_weight", "only_selected"):
            column.prop(self, name)
        layout.prop(self, "apply")

    def execute(self, context):
        layout = open_layout(
            self,
            context,
            moves_vertices=self.apply == "BAKE",
        )
        if layout is None:
            return {"CANCELLED"}
        parameters = operator_values(self, alignment.AlignParameters)
        start = time.perf_counter()
        try:
            with object_mode(layout):
                check_inputs(context, layout, READS_LAYOUT if self.use_anchors else frozenset({"positions"}))
                arrays = layout_data.read_layout(layout)
                target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
                anchor_list = anchors.no_anchors()
                if self.use_anchors:
                    anchor_list, _resolution = anchors.resolve(
                        proposals.used_by_wrap(anchor_data.read_anchors(layout)),
                        target,
                        layout.springwrap.anchors_signature,
                    )
                outcome = alignment.align(arrays, anchor_list, target, parameters)
                detached = alignment.detached_count(arrays)
                if self.apply == "OBJECT":
                    basis = alignment.object_basis(
                        outcome.matrix, arrays.matrix_world, layout_data.read_parent_matrix(layout)
                    )
                    layout_data.write_layout(layout, arrays.positions, alignment.floating_state(arrays))
                    layout_data.write_object_basis(layout, basis)
                else:
                    positions = alignment.baked_positions(arrays, outcome.matrix)
                    layout_data.write_layout(layout, positions, alignment.floating_state(arrays))
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        milliseconds = (time.perf_counter() - start) * 1000.0
        self.report({"INFO"}, alignment.summary(layout.name, parameters, outcome, detached, self.apply, milliseconds))
        if outcome.icp is not None and not outcome.icp.converged:
            self.report(
                {"WARNING"},
                f"ICP did not converge in {outcome.icp.iterations} iterations: run Align again (anchors off) "
                "or raise ICP Iterations",
            )
        return {"FINISHED"}


classes = (SPRINGWRAP_OT_align,)
