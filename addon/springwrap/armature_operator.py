"""``springwrap.align_armature``: pose the layout's armature onto a target armature, skin with Blender, bake.

The paper's articulated characters: a template skinned to an armature, a target with an armature
whose bones carry the same names. The operator poses the template armature so that each bone lies
on the target's bone of the same name (``armature_align`` computes where; Blender's own
``PoseBone.matrix`` setter turns it into the pose), lets Blender's Armature modifier deform the
layout, and bakes the deformed positions into the layout's vertices. The layout is then a template
in the target's pose, its vertices space-points, ready for anchors and the wrap.

Everything is checked before anything changes; a failure after the pose was set puts the template
armature's pose back exactly, so an error leaves the scene as it was.
"""

import time

import bpy
import numpy as np

from . import armature_align
from .armature_align import SCALE_ALONG, SCALE_NONE, SCALE_UNIFORM
from .operators import import_bridge

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


class AlignmentError(ValueError):
    """Input the alignment cannot work with; the message is for the user."""


def template_armature(layout):
    """The armature object that skins ``layout``: its first enabled Armature modifier's, else an armature parent."""
    for modifier in layout.modifiers:
        if modifier.type == "ARMATURE" and modifier.object is not None and modifier.show_viewport:
            return modifier.object
    parent = layout.parent
    if parent is not None and parent.type == "ARMATURE" and layout.parent_type == "ARMATURE":
        return parent
    return None


def resolve_target_armature(context, layout, name):
    """The target armature: the one named, else the layout's setting, else a selected armature that does
    not skin the layout. Raises :class:`AlignmentError` when there is none or it is not an armature."""
    template = template_armature(layout)
    if name:
        target = bpy.data.objects.get(name)
        if target is None:
            raise AlignmentError(f"No object named '{name}'")
    else:
        target = layout.springwrap.target_armature
        if target is None:
            selected = [obj for obj in context.selected_objects if obj.type == "ARMATURE" and obj != template]
            if len(selected) > 1:
                raise AlignmentError("Several armatures are selected: pick the target armature in the panel")
            target = selected[0] if selected else None
    if target is None:
        raise AlignmentError("No target armature: pick one in the Springwrap panel (or select it)")
    if target.type != "ARMATURE":
        raise AlignmentError(f"'{target.name}' is not an armature")
    if target == template:
        raise AlignmentError(f"The target armature '{target.name}' is the layout's own armature")
    return target


def _matrix(value) -> np.ndarray:
    return np.array(value, dtype=np.float64).reshape(4, 4)


def _world_frames(armature) -> dict:
    """Each pose bone of ``armature`` (evaluated pose) as an ``armature_align.BoneFrame`` in world space."""
    world = _matrix(armature.matrix_world)
    frames = {}
    for pose_bone in armature.pose.bones:
        if pose_bone.bone.length <= 0.0:
            continue
        frame = armature_align.frame_from_matrix(_matrix(pose_bone.matrix), pose_bone.bone.length)
        frames[pose_bone.name] = armature_align.frame_in_space(frame, world)
    return frames


def _pose_snapshot(armature) -> list:
    """Every pose bone's own transform (the pose as the user set it), to put back on failure."""
    return [
        (
            pose_bone.name,
            pose_bone.rotation_mode,
            tuple(pose_bone.location),
            tuple(pose_bone.rotation_quaternion),
            tuple(pose_bone.rotation_euler),
            tuple(pose_bone.rotation_axis_angle),
            tuple(pose_bone.scale),
            pose_bone.bone.inherit_scale,
        )
        for pose_bone in armature.pose.bones
    ]


def _restore_pose(armature, snapshot) -> None:
    for name, mode, location, quaternion, euler, axis_angle, scale, inherit_scale in snapshot:
        pose_bone = armature.pose.bones[name]
        pose_bone.bone.inherit_scale = inherit_scale
        pose_bone.rotation_mode = mode
        pose_bone.location = location
        pose_bone.rotation_quaternion = quaternion
        pose_bone.rotation_euler = euler
        pose_bone.rotation_axis_angle = axis_angle
        pose_bone.scale = scale


def _clear_pose_bone(pose_bone) -> None:
    pose_bone.location = (0.0, 0.0, 0.0)
    pose_bone.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
    pose_bone.rotation_euler = (0.0, 0.0, 0.0)
    pose_bone.rotation_axis_angle = (0.0, 0.0, 1.0, 0.0)
    pose_bone.scale = (1.0, 1.0, 1.0)


class PoseResult:
    """What :func:`pose_onto` did: matched bones, bones without a partner, the worst bone mismatch (world)."""

    def __init__(self, matched, unmatched, mismatch):
        self.matched = matched
        self.unmatched = unmatched
        self.mismatch = mismatch


def pose_onto(context, template, target, match_roll, scale_mode, progress=None) -> PoseResult:
    """Pose ``template`` so that each bone lies on ``target``'s bone of the same name (world space).

    Matched bones get :func:`armature_align.desired_pose_matrix` through Blender's ``PoseBone.matrix``
    setter (with :data:`SCALE_ALONG` their Inherit Scale is set to None first), a depth level at a time (each level is evaluated before the next, since the setter reads
    the parent's evaluated pose); bones without a partner are cleared to their rest transform, so they
    follow their parent. Raises :class:`AlignmentError` when no bone matches (nothing changed then)."""
    context.view_layer.update()
    target_frames = _world_frames(target)
    names = [bone.name for bone in template.data.bones]
    matched = armature_align.matched_bones(names, target_frames.keys())
    if not matched:
        raise AlignmentError(
            f"No bone of '{template.name}' has a partner of the same name in '{target.name}' "
            f"({len(names)} and {len(target.data.bones)} bones): nothing to align"
        )
    template_world = _matrix(template.matrix_world)
    if abs(np.linalg.det(template_world[:3, :3])) < 1e-12:
        raise AlignmentError(f"Armature '{template.name}' has zero scale")
    to_template = np.linalg.inv(template_world)
    desired = {}
    for name in matched:
        bone = template.data.bones[name]
        frame = armature_align.frame_in_space(target_frames[name], to_template)
        try:
            desired[name] = armature_align.desired_pose_matrix(
                frame, _matrix(bone.matrix_local), bone.length, match_roll, scale_mode
            )
        except ValueError as error:
            raise AlignmentError(f"Bone '{name}': {error}") from error
    from mathutils import Matrix

    if scale_mode == SCALE_ALONG:
        # A child inherits its parent's stretch along the parent's axis as a shear, which a pose
        # (location, rotation, scale) cannot undo: matched bones take no scale from their parent.
        for name in matched:
            template.data.bones[name].inherit_scale = "NONE"
    levels = armature_align.depth_levels(names, [bone.parent.name if bone.parent else "" for bone in template.data.bones])
    for level_index, level in enumerate(levels):
        for name in level:
            pose_bone = template.pose.bones[name]
            if name in desired:
                pose_bone.matrix = Matrix(desired[name].tolist())
            else:
                _clear_pose_bone(pose_bone)
        context.view_layer.update()
        if progress is not None:
            progress(level_index + 1, len(levels))
    posed_frames = _world_frames(template)
    mismatch = max(armature_align.bone_mismatch(posed_frames[name], target_frames[name]) for name in matched)
    unmatched = [name for name in names if name not in desired]
    return PoseResult(matched, unmatched, mismatch)


def deformed_positions(context, layout) -> np.ndarray:
    """The layout's local vertex positions through its armature deformation only (other modifiers off for the read)."""
    switched = []
    try:
        for modifier in layout.modifiers:
            if modifier.type != "ARMATURE" and modifier.show_viewport:
                modifier.show_viewport = False
                switched.append(modifier)
        depsgraph = context.evaluated_depsgraph_get()
        depsgraph.update()
        evaluated = layout.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        try:
            if len(mesh.vertices) != len(layout.data.vertices):
                raise AlignmentError(
                    f"Layout '{layout.name}': its armature deformation changed the vertex count "
                    f"({len(layout.data.vertices)} -> {len(mesh.vertices)})"
                )
            positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", positions)
        finally:
            evaluated.to_mesh_clear()
    finally:
        for modifier in switched:
            modifier.show_viewport = True
    return positions.reshape(-1, 3)


def release_skinning(layout) -> int:
    """Remove the layout's Armature modifiers and turn an armature parent into a plain parent (world
    matrix kept), so the baked pose is not deformed a second time. Returns how many were released."""
    released = 0
    for modifier in [modifier for modifier in layout.modifiers if modifier.type == "ARMATURE" and modifier.show_viewport]:
        layout.modifiers.remove(modifier)
        released += 1
    if layout.parent is not None and layout.parent_type == "ARMATURE":
        world = layout.matrix_world.copy()
        layout.parent_type = "OBJECT"
        layout.matrix_world = world
        released += 1
    return released


class SPRINGWRAP_OT_align_armature(bpy.types.Operator):
    """Pose the layout's armature onto the target armature (bones of the same name), deform the layout with it and bake the result"""

    bl_idname = "springwrap.align_armature"
    bl_label = "Align Armature"
    bl_options = {"REGISTER", "UNDO"}

    target_armature: bpy.props.StringProperty(
        name="Target Armature",
        description="Name of the target armature (empty: the panel's Target Armature, else a selected armature)",
        default="",
    )
    match_roll: bpy.props.BoolProperty(
        name="Match Roll",
        description="Turn each bone about itself as the target's bone is turned (off: only its direction)",
        default=True,
    )
    scale_mode: bpy.props.EnumProperty(
        name="Scale",
        description="How a template bone takes the length of its target bone",
        items=SCALE_MODE_ITEMS,
        default=SCALE_ALONG,
    )
    bake: bpy.props.BoolProperty(
        name="Bake",
        description=(
            "Write the deformed shape into the layout's vertices (space-points) and remove its armature "
            "deformation; off: only pose the armature and keep the modifier live"
        ),
        default=True,
    )
    update_rest: bpy.props.BoolProperty(
        name="Update Rest Shape",
        description="Take the aligned shape as the template's rest shape, which the wrap's springs keep",
        default=True,
    )

    @classmethod
    def poll(cls, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            cls.poll_message_set("No active mesh object (the layout)")
            return False
        if template_armature(layout) is None:
            cls.poll_message_set("The layout has no armature (an Armature modifier or an armature parent)")
            return False
        return True

    def execute(self, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            self.report({"ERROR"}, "No active mesh object (the layout)")
            return {"CANCELLED"}
        template = template_armature(layout)
        if template is None:
            self.report(
                {"ERROR"},
                f"Layout '{layout.name}' has no armature: add an Armature modifier (or parent it to an armature "
                "with automatic weights) to deform it with the template's armature",
            )
            return {"CANCELLED"}
        bridge = import_bridge(self)
        if bridge is None:
            return {"CANCELLED"}
        start = time.perf_counter()
        window_manager = context.window_manager
        progress = _Progress(window_manager)
        snapshot = _pose_snapshot(template)
        posed = False
        try:
            with bridge.object_mode(layout):
                target = resolve_target_armature(context, layout, self.target_armature)
                if template.mode == "EDIT" or target.mode == "EDIT":
                    raise AlignmentError("Leave the armature's edit mode first")
                if self.bake and bridge.has_shape_keys(layout):
                    raise AlignmentError(f"Layout '{layout.name}' has shape keys; Springwrap cannot move its vertices")
                posed = True
                result = pose_onto(context, template, target, self.match_roll, self.scale_mode, progress.update)
                if self.bake:
                    positions = deformed_positions(context, layout)
                    if not np.all(np.isfinite(positions)):
                        raise AlignmentError(f"Layout '{layout.name}': the armature deformation gave non-finite positions")
                    from . import layout_state

                    before = bridge.read_layout(layout).positions
                    if bridge.read_rest(layout) is None or self.update_rest:
                        bridge.write_rest(layout, positions if self.update_rest else before)
                    bridge.write_layout(layout, positions, layout_state.space_state(len(positions)))
                    release_skinning(layout)
                    moved = float(np.max(np.linalg.norm(positions.astype(np.float64) - before, axis=1)))
        except (AlignmentError, *bridge.ERRORS) as error:
            if posed:
                _restore_pose(template, snapshot)
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
