"""``springwrap.align_armature``: pose the layout's armature onto a target armature, skin with Blender, bake.

The paper's articulated characters: a template skinned to an armature, a target with an armature
whose bones carry the same names. The operator poses the template armature so that each bone lies
on the target's bone of the same name (``core.armature`` computes where, ``blender.armature`` sets it through Blender's own
``PoseBone.matrix`` setter), lets Blender's Armature modifier deform the
layout, and bakes the deformed positions into the layout's vertices. The layout is then a template
in the target's pose, its vertices space-points, ready for anchors and the wrap.

Everything is checked before anything changes; a failure after the pose was set puts the template
armature's pose back exactly, so an error leaves the scene as it was.
"""

import time

import bpy

import numpy as np

from .. import property_kinds as props
from ..blender import armature as armature_data
from ..blender import attributes
from ..blender import layout as layout_data
from ..blender.edit_mode import object_mode
from ..core import layout_state
from ..core.armature import SCALE_ALONG, SCALE_NONE, SCALE_UNIFORM
from ..core.errors import ERRORS, LayoutError
from .base import SpringwrapOperator, check_inputs

SCALE_MODE_ITEMS = (
    (
        SCALE_ALONG,
        "Along Bones",
        "Stretch each bone along its length so that its tail meets the target's (matched bones then inherit no scale)",
    ),
    (SCALE_UNIFORM, "Uniform", "Scale each bone uniformly by the ratio of the lengths (thicker when longer)"),
    (SCALE_NONE, "None", "Match heads and directions only (a longer target bone leaves a gap at the joint)"),
)
"""Values of ``scale_mode``: how a template bone takes the length of its target bone."""


class SPRINGWRAP_OT_align_armature(SpringwrapOperator, bpy.types.Operator):
    """Pose the layout's armature onto the target armature (bones of the same name), deform the layout with it and bake the result"""

    bl_label = "Align Armature"

    target_armature: props.text(
        "Target Armature", "Name of the target armature (empty: the panel's Target Armature, else a selected armature)"
    )
    match_roll: props.flag(
        "Match Roll", "Turn each bone about itself as the target's bone is turned (off: only its direction)", True
    )
    scale_mode: props.choice(
        "Scale", "How a template bone takes the length of its target bone", SCALE_MODE_ITEMS, SCALE_ALONG
    )
    bake: props.flag(
        "Bake",
        "Write the deformed shape into the layout's vertices (space-points) and remove its armature "
        "deformation; off: only pose the armature and keep the modifier live",
        True,
    )
    update_rest: props.flag(
        "Update Rest Shape", "Take the aligned shape as the template's rest shape, which the wrap's springs keep", True
    )

    @classmethod
    def poll(cls, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            cls.poll_message_set("No active mesh object (the layout)")
            return False
        if armature_data.template_armature(layout) is None:
            cls.poll_message_set("The layout has no armature (an Armature modifier or an armature parent)")
            return False
        return True

    def execute(self, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            self.report({"ERROR"}, "No active mesh object (the layout)")
            return {"CANCELLED"}
        template = armature_data.template_armature(layout)
        if template is None:
            self.report(
                {"ERROR"},
                f"Layout '{layout.name}' has no armature: add an Armature modifier (or parent it to an armature "
                "with automatic weights) to deform it with the template's armature",
            )
            return {"CANCELLED"}
        start = time.perf_counter()
        window_manager = context.window_manager
        progress = _Progress(window_manager)
        snapshot = armature_data.pose_snapshot(template)
        posed = False
        try:
            with object_mode(layout):
                target = armature_data.resolve_target_armature(context, layout, self.target_armature)
                if template.mode == "EDIT" or target.mode == "EDIT":
                    raise LayoutError("Leave the armature's edit mode first")
                if self.bake:
                    layout_data.refuse_shape_keys(layout)
                check_inputs(context, layout, frozenset({"positions"}), with_target=False)
                posed = True
                result = armature_data.pose_onto(
                    context, template, target, self.match_roll, self.scale_mode, progress.update
                )
                if self.bake:
                    positions = armature_data.deformed_positions(context, layout)
                    if not np.all(np.isfinite(positions)):
                        raise LayoutError(f"Layout '{layout.name}': the armature deformation gave non-finite positions")
                    before = layout_data.read_layout(layout).positions
                    if attributes.read_rest(layout) is None or self.update_rest:
                        attributes.write_rest(layout, positions if self.update_rest else before)
                    layout_data.write_layout(layout, positions, layout_state.space_state(len(positions)))
                    armature_data.release_skinning(layout)
                    moved = float(np.max(np.linalg.norm(positions.astype(np.float64) - before, axis=1)))
        except ERRORS as error:
            if posed:
                armature_data.restore_pose(template, snapshot)
                context.view_layer.update()
            progress.end()
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        progress.end()
        milliseconds = (time.perf_counter() - start) * 1000.0
        text = (
            f"Aligned {len(result.matched)} bones of '{template.name}' onto '{target.name}' "
            f"({len(result.unmatched)} without a partner follow their parent), largest bone mismatch "
            f"{result.mismatch:.4g}"
        )
        if self.bake:
            text += f"; baked {len(positions)} vertices (space-points, moved up to {moved:.4g})"
        else:
            text += "; the Armature modifier stays live (the layout's vertices are unchanged)"
        self.report({"INFO"}, f"{text} in {milliseconds:.0f} ms")
        return {"FINISHED"}


class _Progress:
    """The window manager's progress indicator, when there is a window to show it in."""

    def __init__(self, window_manager):
        self.window_manager = window_manager if bpy.context.window is not None else None
        self.started = False

    def update(self, done, total):
        if self.window_manager is None:
            return
        if not self.started:
            self.window_manager.progress_begin(0, total)
            self.started = True
        self.window_manager.progress_update(done)

    def end(self):
        if self.started:
            self.window_manager.progress_end()
            self.started = False


classes = (SPRINGWRAP_OT_align_armature,)
