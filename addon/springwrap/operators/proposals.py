"""Proposed pairs: propose further anchors from those placed by hand, accept or reject them.

Each operator reads everything, computes the complete new anchor list (``core.proposals``) and writes it only
when every step succeeded (one undo step); any problem is reported and the anchors are left as they were.
"""

import bpy

from .. import property_kinds as props
from ..blender import anchors as anchor_data
from ..blender import attributes
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..core import anchors, proposals
from .anchors import _AnchorOperator, _list_outcome


class SPRINGWRAP_OT_anchors_propose(_AnchorOperator, bpy.types.Operator):
    """Propose further pairs where both shapes agree (tips and pits), from the hand anchors and the current fit"""

    bl_label = "Propose Anchors"

    reads = frozenset({"positions", "anchors"})

    max_count: props.integer(
        "Most Pairs",
        "Propose at most this many pairs (the most confident)",
        proposals.DEFAULTS["max_count"],
        min=1,
        max=10_000,
    )
    min_confidence: props.number(
        "Least Confidence",
        "Propose only pairs at least this sure (0 to 1: how well the two points agree and how clearly they are each "
        "other's best)",
        proposals.DEFAULTS["min_confidence"],
        min=0.0,
        max=1.0,
    )
    search_radius: props.number(
        "Search Radius",
        "How far from where the current fit puts a layout point its partner is looked for, as a fraction of the "
        "target's size (raise it after a rough Align, lower it after a close one)",
        proposals.DEFAULTS["search_radius"],
        min=0.001,
        max=0.5,
    )
    feature_scale: props.number(
        "Feature Scale",
        "The size of the features compared, as a fraction of each model's size: larger finds broad features (a "
        "knee, a chin) that hold a sliding region in place, smaller finds narrow tips and pits",
        proposals.DEFAULTS["feature_scale"],
        min=0.002,
        max=0.1,
    )
    accept: props.flag(
        "Accept", "Store the pairs accepted at once (soft pairs the wrap uses); off: as proposed pairs", False
    )

    def compute(self, context, layout):
        arrays = layout_data.read_layout(layout)
        topology = layout_data.read_layout_topology(layout)
        rest = attributes.read_rest(layout)
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        outcome = proposals.propose(
            arrays,
            arrays.positions if rest is None else rest,
            topology.face_corners,
            topology.face_sizes,
            anchor_data.read_anchors(layout),
            target,
            layout.springwrap.anchors_signature,
            self.max_count,
            self.min_confidence,
            self.search_radius,
            self.feature_scale,
            self.accept,
        )
        return outcome, target.signature

    def summary(self, anchors, outcome, milliseconds):
        how = "accepted" if self.accept else "proposed"
        text = f"{outcome.added_count} pairs {how} in {milliseconds:.0f} ms"
        if outcome.added_count:
            confidences = outcome.anchors.confidences[-outcome.added_count :]
            text += f" (confidence {float(confidences.min()):.2f} to {float(confidences.max()):.2f})"
        if outcome.replaced_count:
            text += f"; replaced {outcome.replaced_count} earlier proposals"
        return text


class _ProposalEdit(_AnchorOperator):
    """Accept or reject a proposed pair (the active one by default) or all of them."""

    requires_items = True
    reads_layout_mesh = False
    reads = frozenset()

    index: props.integer("Index", "Position of the pair in the anchor list; -1: the active anchor", -1, min=-1)
    all: props.flag("All", "Every proposed pair", False)

    def chosen_index(self, layout):
        if self.all:
            return -1
        return self.index if self.index >= 0 else layout.springwrap.active_anchor_index


class SPRINGWRAP_OT_anchor_accept(_ProposalEdit, bpy.types.Operator):
    """Accept a proposed pair (the active one, or all): the wrap uses it, as a soft pair that steers its stiff levels"""

    bl_label = "Accept Proposed Pair"

    def compute(self, context, layout):
        accepted, self._count = proposals.accept(anchor_data.read_anchors(layout), self.chosen_index(layout))
        return _list_outcome(anchors, accepted, -1), None

    def summary(self, anchors, outcome, milliseconds):
        return f"Accepted {self._count} proposed pairs"


class SPRINGWRAP_OT_anchor_reject(_ProposalEdit, bpy.types.Operator):
    """Reject a proposed pair (the active one, or all): it is removed"""

    bl_label = "Reject Proposed Pair"

    def compute(self, context, layout):
        kept, self._count = proposals.reject(anchor_data.read_anchors(layout), self.chosen_index(layout))
        count = anchors.anchor_count(kept)
        active = anchors.clamp_active_index(layout.springwrap.active_anchor_index, count)
        return _list_outcome(anchors, kept, active), None

    def summary(self, anchors, outcome, milliseconds):
        return f"Rejected {self._count} proposed pairs; {anchors.anchor_count(outcome.anchors)} anchors left"


classes = (SPRINGWRAP_OT_anchors_propose, SPRINGWRAP_OT_anchor_accept, SPRINGWRAP_OT_anchor_reject)
