"""Springwrap's per-object settings, hung on ``bpy.types.Object.springwrap``.

All add-on state lives here (no loose Scene properties), anchors included. The per-vertex state is
not here but in mesh attributes on the layout (see ``core.layout_state``), so that it follows the mesh
through edits, undo and save/reload.
"""

from typing import NamedTuple

import bpy

from . import property_kinds as props
from .blender import compat
from .core import defaults, quality
from .core.subdivision import MAX_RESOLUTION
from .item_properties import (
    SpringwrapAnchorItem,
    SpringwrapCurveConstraintItem,
    SpringwrapCurveFractionItem,
    SpringwrapCurvePointItem,
    is_curve_object,
)

WRAP_DEFAULTS = defaults.wrap_defaults()
"""The kernel's default wrap settings: the defaults of the wrap's operator, panel and scripts. Read when the add-on
is imported (a Blender property's default is fixed when its class is defined): without its kernel the add-on
cannot be enabled, and the error says why."""


class Range(NamedTuple):
    """A property's range, decided once: hard limits (what Blender clamps a typed or scripted value to) are the
    valid range (the kernel's, for its settings), soft limits the useful one (the slider's)."""

    hard_min: float
    hard_max: float
    soft_min: float
    soft_max: float

    def keywords(self) -> dict:
        """``min``, ``max``, ``soft_min``, ``soft_max`` for a ``bpy.props`` property."""
        return {"min": self.hard_min, "max": self.hard_max, "soft_min": self.soft_min, "soft_max": self.soft_max}


INT_LIMIT = 2**31 - 1
"""The largest value of a Blender int property."""


def _kernel_range(name: str) -> Range:
    """A kernel setting's range (``defaults.wrap_ranges``) as a property's: the hard limits the kernel's (an open
    minimum is kept as the minimum: Blender cannot make it open, and the kernel refuses it), the soft ones the same
    (the tolerance's slider from 1e-5 to 0.1)."""
    kernel = defaults.wrap_ranges()[name]
    if name == "tolerance":
        return Range(kernel.low, kernel.high, 1e-5, 0.1)
    return Range(kernel.low, kernel.high, kernel.low, kernel.high)


WRAP_RANGES = {
    **{name: _kernel_range(name) for name in ("fairness", "arc_length", "thin_plate", "constraint", "folding")},
    "tolerance": _kernel_range("tolerance"),
    # The add-on's own: at least one iteration; the spring resolution up to core.subdivision.MAX_RESOLUTION.
    "max_iterations": Range(1, INT_LIMIT, 1, 20000),
    "spring_resolution": Range(1, MAX_RESOLUTION, 1, MAX_RESOLUTION),
}
"""The range of every wrap and mirror setting: one table the operators' properties are made from."""


def max_distance_property(description: str):
    """A world-space distance limit, 0 meaning unlimited: shared by the operators and the panel defaults."""
    return props.distance("Max Distance", description)


def max_iterations_property(
    description: str = "Stop the wrap after this many iterations if it has not converged by then",
):
    """The wrap's iteration limit: shared by the operators that wrap (wrap, mirror)."""
    return bpy.props.IntProperty(
        name="Max Iterations",
        description=description,
        default=defaults.MAX_ITERATIONS,
        **WRAP_RANGES["max_iterations"].keywords(),
    )


def tolerance_property(
    description: str = "Each stiffness level of the wrap ends once an iteration lowers its energy by less than this "
    "fraction: smaller runs longer and fits closer",
):
    """The wrap's convergence tolerance: shared by the operators that wrap (wrap, mirror)."""
    return bpy.props.FloatProperty(
        name="Tolerance",
        description=description,
        default=WRAP_DEFAULTS.tolerance,
        precision=7,
        **WRAP_RANGES["tolerance"].keywords(),
    )


def wrap_weight_property(name: str, label: str, description: str):
    """One of the wrap's weights (a kernel setting): the kernel's default and range."""
    return bpy.props.FloatProperty(
        name=label, description=description, default=getattr(WRAP_DEFAULTS, name), **WRAP_RANGES[name].keywords()
    )


SNAP_MODE_ITEMS = (
    ("SURFACE", "Surface", "Closest point on the target surface (exact, uses the face tree)"),
    ("VERTEX", "Vertex", "Nearest target vertex (fast, uses the vertex tree)"),
)
"""Modes of ``springwrap.snap``."""

PROJECT_DIRECTION_ITEMS = (
    ("X", "X", "Along +X"),
    ("Y", "Y", "Along +Y"),
    ("Z", "Z", "Along +Z"),
    ("-X", "-X", "Along -X"),
    ("-Y", "-Y", "Along -Y"),
    ("-Z", "-Z", "Along -Z"),
    ("VIEW", "View", "Along the 3D view's looking direction"),
    ("NORMAL", "Normal", "Along each layout vertex's normal (vertices on no face are skipped)"),
)
"""Directions of ``springwrap.project``."""

ORIENTATION_ITEMS = (
    ("GLOBAL", "Global", "Axis directions in world space"),
    ("LOCAL", "Local", "Axis directions in the layout object's space"),
)
"""Orientations of the axis directions of ``springwrap.project``."""

ANCHOR_METHOD_ITEMS = (
    ("CLOSEST", "Closest", "Each anchor's target is the closest point of the target surface"),
    ("PROJECT", "Project", "Each anchor's target is the nearer hit along the vertex normal, both ways"),
)
"""How ``springwrap.anchors_auto`` finds the anchors' targets."""

SYMMETRY_AXIS_ITEMS = tuple(
    (axis, axis, f"The plane {axis.lower()} = 0 of the layout (or of the symmetry object)") for axis in "XYZ"
)
"""The symmetric anchors' plane: perpendicular to this local axis."""


def _is_target_candidate(settings, candidate):
    """Poll of ``target``: a mesh object other than the layout that owns the settings."""
    return candidate is not None and candidate.type == "MESH" and candidate != settings.id_data


def _is_armature(_settings, candidate):
    """Poll of ``target_armature``: an armature object."""
    return candidate is not None and candidate.type == "ARMATURE"


def _is_empty(_settings, candidate):
    """Poll of ``anchor_symmetry_object``: an Empty."""
    return candidate is not None and candidate.type == "EMPTY"


def retired_solver_property():
    """The retired ``solver`` choice of the wrap's operators: hidden, kept so that scripts and presets naming it
    still run; ``'SPRINGS'`` wraps with the energy solver and says so (``defaults.RETIRED_SOLVER_WARNING``)."""
    return props.choice(
        "Solver",
        "Retired: the wrap has one solver, the energy solver ('SPRINGS' is mapped to it with a warning)",
        (
            ("ENERGY", "Energy", "The wrap's one solver"),
            (defaults.RETIRED_SOLVER, "Springs (retired)", "Wraps with the Energy solver, with a warning"),
        ),
        "ENERGY",
        options={"HIDDEN", "SKIP_SAVE"},
    )


WRAP_SCHEDULE_ITEMS = (
    (
        "AUTO",
        "Automatic",
        "Global to Local for 3 to 11 anchors, or for more that slide along the surface from where a "
        "similarity of the template puts them (a change of proportions, not a pose); Local otherwise",
    ),
    (
        "LOCAL",
        "Local",
        "One scale for the whole layout at first, then local scales; quick, and right when the "
        "layout starts near its place (many anchors, or a small change of shape)",
    ),
    (
        "GLOBAL_TO_LOCAL",
        "Global to Local",
        "Stiff, nearly affine levels first (each region stretched and sheared as one piece), "
        "then the local fit; for a few anchors on a large change of shape",
    ),
)
"""The energy wrap's stiffness schedules (``springwrap_kernel.WrapSettings(schedule=...)``)."""

SHAPE_KEYS_ITEMS = (
    (
        "TRANSFER",
        "Transfer",
        "Move the basis and carry every other shape key over onto the new shape (each key's offsets turned and "
        "scaled with the surface under them)",
    ),
    ("REFUSE", "Refuse", "Refuse a layout with shape keys and change nothing"),
)
"""What the wrap and the mirror do with a layout's shape keys (``blender.shape_keys``)."""


def shape_keys_property(description: str = "What to do with the layout's shape keys"):
    """The ``shape_keys`` option of the wrap and the mirror (and the panel's default for their buttons)."""
    return props.choice("Shape Keys", description, SHAPE_KEYS_ITEMS, "TRANSFER")


def _update_show_cage(settings, context):
    """``show_cage``'s update (``blender.cage_display``)."""
    from .blender import cage_display

    cage_display.update_show_cage(settings, context)


def _update_follow(settings, context):
    """``follow``'s update (``blender.follow``)."""
    from .blender import follow

    follow.follow_changed(settings, context)


def _update_active_anchor(settings, context):
    """``active_anchor_index``'s update (``blender.anchor_view``)."""
    from .blender import anchor_view

    anchor_view.active_anchor_changed(settings, context)


PROBLEM_KIND_ITEMS = tuple((kind, *words) for kind, words in quality.PROBLEM_KINDS.items())
"""What ``springwrap.select_problems`` selects (``core.quality.problem_mask``)."""
HEATMAP_KIND_ITEMS = tuple((kind, *words) for kind, words in quality.HEATMAP_KINDS.items())
"""What the quality heat-map shows (``ui.heatmap``)."""


SEQUENCE_SOURCE_ITEMS = (
    ("TARGET", "Target", "The layout's target as evaluated at each frame (armature, shape keys, modifiers, caches)"),
    ("COLLECTION", "Collection", "One mesh object per frame: the i-th frame's target is the collection's i-th by name"),
)
"""Where Wrap Sequence finds each frame's target."""


class SpringwrapObjectSettings(bpy.types.PropertyGroup):
    """Springwrap settings of a layout object."""

    target: props.object_pointer(
        "Target",
        "Mesh the layout is retargeted onto (its evaluated shape, modifiers included)",
        poll=_is_target_candidate,
    )
    target_signature: props.hidden_text(
        "Target Signature", "Topology signature of the target when face-points were last written"
    )
    wrap_schedule: props.choice(
        "Schedule",
        "Stiffness schedule of the panel's Wrap button",
        WRAP_SCHEDULE_ITEMS,
        WRAP_DEFAULTS.schedule,
    )
    shape_keys: shape_keys_property("What the panel's Wrap and Mirror buttons do with the layout's shape keys")
    snap_mode: props.choice("Snap Mode", "Default mode of the panel's Snap button", SNAP_MODE_ITEMS, "SURFACE")
    project_direction: props.choice(
        "Direction", "Default direction of the panel's Project button", PROJECT_DIRECTION_ITEMS, "NORMAL"
    )
    project_orientation: props.choice(
        "Orientation", "Space of the axis directions of the panel's Project button", ORIENTATION_ITEMS, "GLOBAL"
    )
    project_both_directions: props.flag("Both Directions", "Also cast each ray backwards and keep the nearer hit", True)
    max_distance: max_distance_property("Vertices farther than this from the target are left untouched (0 = unlimited)")

    anchors: props.items(
        "Anchors", "Point-to-point correspondences: a layout vertex and its target point", SpringwrapAnchorItem
    )
    active_anchor_index: props.list_position(
        "Active Anchor",
        "Index of the active anchor in the list (a click on a row selects its vertex and centres the 3D view on it)",
        update=compat.property_update(_update_active_anchor),
    )
    anchors_signature: props.hidden_text(
        "Anchors Signature", "Topology signature of the target when the face anchors were last written"
    )
    show_anchors: props.flag(
        "Show Anchors", "Draw a line from each anchored layout vertex to its target point in the 3D view", True
    )
    anchor_spacing: props.distance(
        "Spacing", "Default spacing of the panel's Auto Anchors button (0 = a tenth of the layout's size)"
    )
    anchor_method: props.choice(
        "Method", "Default method of the panel's Auto Anchors button", ANCHOR_METHOD_ITEMS, "CLOSEST"
    )
    anchor_keep: props.flag(
        "Keep Existing",
        "The panel's Auto Anchors keeps the existing anchors (those placed by hand) and spreads new ones around "
        "them; off: it replaces them",
        True,
    )
    # Symmetric anchors (operators.anchors): the panel's defaults for Add and Auto.
    anchor_symmetric: props.flag(
        "Symmetric", "Add and Auto Anchors also anchor each vertex's twin across the symmetry plane, as a pair", False
    )
    anchor_symmetry_axis: props.choice(
        "Symmetry Axis",
        "The symmetry plane is perpendicular to this local axis of the layout (or of the symmetry object)",
        SYMMETRY_AXIS_ITEMS,
        "X",
    )
    anchor_symmetry_object: props.object_pointer(
        "Symmetry Object",
        "Empty whose local plane (through its origin, perpendicular to the axis) is the symmetry plane; "
        "none: the layout's own",
        poll=_is_empty,
    )
    pair_live: props.flag(
        "Live",
        "The pair tool re-settles the layout (a wrap from where it is) after every pair edit; off: it only edits "
        "the pairs",
        False,
    )

    curve_constraints: props.items(
        "Curve Constraints", "Layout edge chains paired with target curves", SpringwrapCurveConstraintItem
    )
    active_curve_constraint_index: props.list_position(
        "Active Curve Constraint", "Index of the active curve constraint in the list"
    )
    curve_source: props.object_pointer(
        "Curve",
        "Curve object the panel's Add button pairs the selected chain with (empty: target edges)",
        poll=is_curve_object,
    )
    show_curve_constraints: props.flag(
        "Show Curve Constraints",
        "Draw dashed lines between each constrained layout chain and its target curve in the 3D view",
        True,
    )

    unreliable_group: props.text(
        "Unreliable",
        "Vertex group of the target marking noisy or untrusted data: the wrap treats points on triangles "
        "whose three corners weigh more than 0.5 as space-points (read from the evaluated target)",
    )
    stiffness_group: props.text(
        "Stiffness",
        "Vertex group of the layout: how firmly its vertices keep the template's shape in the Energy wrap "
        "(weight 0 follows the target freely, 0.5 as the others, 1 keeps the template's shape)",
    )
    free_group: props.text(
        "Free",
        "Vertex group of the layout with no pull toward the target in the Energy wrap (eye and mouth sockets, "
        "teeth): its vertices follow their neighbours by the template's shape and stay off the surface",
    )
    # Parts that follow the surface (core.parts).
    find_parts: props.flag(
        "Find Parts",
        "The wrap finds the separate pieces the target's surface does not need (eyeballs behind the lids, teeth "
        "inside the lips, lashes) and moves them with the surface around them instead of pulling them onto it",
        True,
    )
    follow_group: props.text(
        "Follow",
        "Vertex group of the layout whose vertices are parts: never pulled onto the target, each connected piece "
        "of them moved rigidly with the surface around it (an eyeball stays a sphere)",
    )
    follow_soft_group: props.text(
        "Follow Soft",
        "Vertex group of the layout whose vertices are soft parts: each follows the surface around it on its own, "
        "so the piece bends with its surface (lashes with their lid, a tongue)",
    )
    surface_group: props.text(
        "Surface",
        "Vertex group of the layout whose pieces are wrapped onto the target like the body, whatever Find Parts "
        "guesses",
    )
    # Armature alignment (operators.armature).
    target_armature: props.object_pointer(
        "Target Armature",
        "Armature of the target whose bones the layout's armature is posed onto (bones matched by name)",
        poll=_is_armature,
    )

    mirror_object: props.object_pointer(
        "Mirror Object", "Object (an empty) whose local plane the Mirror button mirrors across; none: the layout's own"
    )

    show_cage: props.flag(
        "Show Cage",
        "Draw the layout so it reads over its target: In Front and as Wire, and the Retopology overlay in "
        "Blender 4+ (Edit Mode); off puts the object's and the views' display settings back",
        False,
        update=compat.property_update(_update_show_cage),
    )
    cage_saved_display: props.hidden_text(
        "Saved Display", "The display settings Show Cage replaced (JSON), put back when it is turned off"
    )

    # The quality read-out's heat-map (ui.heatmap) and the Check panel's Select Problems.
    show_heatmap: props.flag(
        "Heat-Map",
        "Draw the quality read-out (written by Snap, Project, Wrap, Mirror) over the layout in the 3D view, with a "
        "legend",
        False,
    )
    heatmap_kind: props.choice("Show", "What the heat-map shows", HEATMAP_KIND_ITEMS, "DISTANCE")
    problem_kind: props.choice(
        "Problems", "What the panel's Select Problems button selects", PROBLEM_KIND_ITEMS, "FLIPPED"
    )

    # Over time (operators.sequence, blender.follow).
    follow: props.flag(
        "Follow",
        "Re-settle the layout by itself whenever its target changes (an edit, a sculpt stroke, a modifier, a frame "
        "change), only where the change concerns it",
        False,
        update=compat.property_update(_update_follow),
    )
    sequence_source: props.choice(
        "Source", "Where the panel's Wrap Sequence finds each frame's target", SEQUENCE_SOURCE_ITEMS, "TARGET"
    )
    sequence_collection: bpy.props.PointerProperty(
        name="Frames",
        description="Collection of one mesh object per frame (Source: Collection)",
        type=bpy.types.Collection,
    )


classes = (
    SpringwrapAnchorItem,
    SpringwrapCurvePointItem,
    SpringwrapCurveFractionItem,
    SpringwrapCurveConstraintItem,
    SpringwrapObjectSettings,
)
