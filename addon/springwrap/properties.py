"""Springwrap's per-object settings, hung on ``bpy.types.Object.springwrap``.

All add-on state lives here (no loose Scene properties). The per-vertex state is not here but in
mesh attributes on the layout (see ``layout_state``), so that it follows the mesh through edits,
undo and save/reload.
"""

import bpy

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


def _is_target_candidate(settings, candidate):
    """Poll of ``target``: a mesh object other than the layout that owns the settings."""
    return candidate is not None and candidate.type == "MESH" and candidate != settings.id_data


class SpringwrapObjectSettings(bpy.types.PropertyGroup):
    """Springwrap settings of a layout object."""

    target: bpy.props.PointerProperty(
        name="Target",
        description="Mesh the layout is retargeted onto (its evaluated shape, modifiers included)",
        type=bpy.types.Object,
        poll=_is_target_candidate,
    )
    target_signature: bpy.props.StringProperty(
        name="Target Signature",
        description="Topology signature of the target when face-points were last written",
        default="",
        options={"HIDDEN"},
    )
    snap_mode: bpy.props.EnumProperty(
        name="Snap Mode",
        description="Default mode of the panel's Snap button",
        items=SNAP_MODE_ITEMS,
        default="SURFACE",
    )
    project_direction: bpy.props.EnumProperty(
        name="Direction",
        description="Default direction of the panel's Project button",
        items=PROJECT_DIRECTION_ITEMS,
        default="NORMAL",
    )
    project_orientation: bpy.props.EnumProperty(
        name="Orientation",
        description="Space of the axis directions of the panel's Project button",
        items=ORIENTATION_ITEMS,
        default="GLOBAL",
    )
    project_both_directions: bpy.props.BoolProperty(
        name="Both Directions",
        description="Also cast each ray backwards and keep the nearer hit",
        default=True,
    )
    max_distance: bpy.props.FloatProperty(
        name="Max Distance",
        description="Vertices farther than this from the target are left untouched (0 = unlimited)",
        default=0.0,
        min=0.0,
        subtype="DISTANCE",
        unit="LENGTH",
    )


classes = (SpringwrapObjectSettings,)
