"""What one wrap reads from Blender, read once (:class:`WrapReads`): the layout's arrays, topology and rest shape, its
anchors and curve constraints as stored, and its evaluated target. An operator reads it, checks it (``operators.base.check_inputs``
given its members) and hands it to ``blender.wrap_session.WrapSession``, which reads none of these again.

Object mode data: read inside ``edit_mode.object_mode(layout)``.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import wrap_inputs
from ..core.errors import LayoutError
from ..core.layout_state import LayoutArrays
from ..core.target import Target
from . import anchors as anchor_data
from . import attributes
from . import curves as curve_data
from . import layout as layout_data
from . import target as target_data


class WrapReads(NamedTuple):
    """The layout and its target as one wrap reads them."""

    arrays: LayoutArrays  # local positions, selection, state, transform
    topology: object  # subdivision.LayoutTopology: faces, edges and seams
    anchors: object  # core.anchors.Anchors as stored on the layout (unresolved)
    curves: list  # the layout's curve constraints as stored (their cached polylines)
    target: Target  # the evaluated target in world space
    rest: np.ndarray | None  # the stored rest shape (local (N, 3) float32), None when the layout has none


def read(context, layout: bpy.types.Object, target: Target | None = None) -> WrapReads:
    """Read everything a wrap of ``layout`` needs once; ``target``: the target already read (a sequence's frame
    object), else the layout's target is read. Raises one of ``core.errors.ERRORS`` naming what cannot be read."""
    if target is None:
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    return WrapReads(
        arrays=layout_data.read_layout(layout),
        topology=layout_data.read_layout_topology(layout),
        anchors=anchor_data.read_anchors(layout),
        curves=curve_data.read_curve_constraints(layout),
        target=target,
        rest=attributes.read_rest(layout),
    )


def read_vertex_groups(inputs, layout: bpy.types.Object, parameters):
    """``inputs`` (``core.wrap_inputs.WrapInputs``) with the Stiffness and Free groups (``parameters``' own, else the
    layout's settings) read in; unchanged without them."""
    settings = layout.springwrap
    stiffness_group = getattr(parameters, "stiffness_group", "") or settings.stiffness_group
    free_group = getattr(parameters, "free_group", "") or settings.free_group
    if not stiffness_group and not free_group:
        return inputs
    if int(parameters.spring_resolution) > 1:
        raise LayoutError("The Stiffness and Free groups need Spring Resolution 1")
    if stiffness_group:
        weights, member = layout_data.read_layout_group(layout, stiffness_group)
        inputs = inputs._replace(stiffness=wrap_inputs.group_stiffness(weights, member))
    if free_group:
        weights, member = layout_data.read_layout_group(layout, free_group)
        inputs = inputs._replace(free_vertices=np.ascontiguousarray(member & (weights > 0.0)))
    return inputs


def unreliable_triangles(context, settings, target: Target) -> np.ndarray | None:
    """The target's triangles in the layout's Unreliable group (``settings.unreliable_group`` on
    ``settings.target``), as ``core.wrap_inputs.unreliable_triangles`` marks them; None without the group.
    Raises ``LayoutError`` when the group's weights do not match ``target``'s vertices."""
    if not settings.unreliable_group:
        return None
    weights = target_data.read_vertex_group_weights(context, settings.target, settings.unreliable_group)
    if weights.shape[0] != target.mesh.vertex_count:
        raise LayoutError(
            f"Vertex group '{settings.unreliable_group}' has {weights.shape[0]} weights for a target of "
            f"{target.mesh.vertex_count} vertices"
        )
    return wrap_inputs.unreliable_triangles(target.mesh.triangles(), weights)
