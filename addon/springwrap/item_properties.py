"""The items of the per-object settings' collections: anchors (with their proposed flag and confidence) and
curve constraints with their cached target polylines (``properties.SpringwrapObjectSettings`` holds them)."""

import bpy

from . import property_kinds as props

ANCHOR_KIND_ITEMS = (
    ("SPACE", "Space", "The anchor's target is a free point in 3D", "EMPTY_AXIS", 0),
    ("FACE", "Face", "The anchor's target is a point of the target surface (triangle + barycentric)", "SNAP_FACE", 1),
)
"""Kinds of anchor targets; the item numbers are ``anchors.SPACE_ANCHOR`` and ``anchors.FACE_ANCHOR``."""


class SpringwrapAnchorItem(bpy.types.PropertyGroup):
    """An anchor: a layout vertex and the target point it is pulled to (paper section 2.4)"""

    vertex_index: props.integer("Vertex", "Index of the anchored layout vertex", 0, min=0)
    target_kind: props.choice(
        "Target Kind",
        "Whether the anchor's target is on the target surface or free in space",
        ANCHOR_KIND_ITEMS,
        "SPACE",
    )
    triangle: props.integer(
        "Triangle",
        "Triangle of the evaluated target (loop-triangle order) of a face anchor, -1 for a space anchor",
        -1,
        min=-1,
    )
    barycentric: bpy.props.FloatVectorProperty(
        name="Barycentric",
        description="Weights of the triangle's corners of a face anchor",
        size=3,
        default=(0.0, 0.0, 0.0),
    )
    location: props.point(
        "Location", "World-space target point (for a face anchor, refreshed from the target by the anchor operators)"
    )
    twin_vertex: props.integer(
        "Twin",
        "Vertex of this anchor's symmetric twin anchor (its own vertex on the symmetry plane), -1: none",
        -1,
        min=-1,
    )
    proposed: props.flag(
        "Proposed",
        "A pair proposed by Propose Anchors and not yet accepted: the wrap leaves it out until it is accepted "
        "(Accept, or a drag with the Pair tool)",
        False,
    )
    confidence: props.number(
        "Confidence",
        "How sure Propose Anchors was of this pair (0 to 1; 0 for a pair placed by hand)",
        0.0,
        min=0.0,
        max=1.0,
    )


CURVE_SOURCE_ITEMS = (
    (
        "CURVE_OBJECT",
        "Curve Object",
        "The target curve is a Blender curve object (evaluated, world space)",
        "CURVE_DATA",
        0,
    ),
    ("TARGET_EDGES", "Target Edges", "The target curve is a chain of target mesh edges", "EDGESEL", 1),
    (
        "FEATURE_LINE",
        "Feature Pair",
        "A layout feature line paired with a stretch of a target feature (ridge, valley, hole border)",
        "SHARPCURVE",
        2,
    ),
)
"""Sources of a curve constraint's target curve (``curves.CURVE_OBJECT`` / ``curves.TARGET_EDGES``)."""


def is_curve_object(_item, candidate):
    """Poll of ``curve_object``: a curve object."""
    return candidate is not None and candidate.type == "CURVE"


class SpringwrapCurvePointItem(bpy.types.PropertyGroup):
    """A world-space point of a curve constraint's cached target polyline"""

    co: bpy.props.FloatVectorProperty(name="Point", size=3, default=(0.0, 0.0, 0.0), subtype="XYZ", unit="LENGTH")


class SpringwrapCurveFractionItem(bpy.types.PropertyGroup):
    """Where along a curve constraint's target polyline one chain vertex goes"""

    value: bpy.props.FloatProperty(name="Fraction", default=0.0, min=0.0, max=1.0)


class SpringwrapCurveConstraintItem(bpy.types.PropertyGroup):
    """A curve constraint: a layout edge chain that follows a target curve (paper section 2.4)"""

    layout_vertices: props.text("Layout Chain", "Layout vertex indices of the chain, in order, separated by spaces")
    source_kind: props.choice("Source", "Where the target curve comes from", CURVE_SOURCE_ITEMS, "TARGET_EDGES")
    curve_object: props.object_pointer(
        "Curve Object",
        "Curve object of a Curve Object constraint (read evaluated, in world space, when the wrap runs)",
        poll=is_curve_object,
    )
    target_vertices: props.text(
        "Target Chain", "Target vertex indices of a Target Edges constraint, in order, separated by spaces"
    )
    points: props.items(
        "Points",
        "The target polyline in world space, as last resolved (its start at the chain's start)",
        SpringwrapCurvePointItem,
    )
    fractions: props.items(
        "Placement",
        "Where along the target polyline each chain vertex goes (fractions of its length, one per vertex, as Pair "
        "Feature Lines placed them); empty: each vertex at the fraction it has along the chain",
        SpringwrapCurveFractionItem,
    )
    confidence: props.number(
        "Confidence",
        "How sure Pair Feature Lines was of this pair (0 to 1; 0 for a constraint added otherwise)",
        0.0,
        min=0.0,
        max=1.0,
    )
