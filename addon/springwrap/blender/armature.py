"""``springwrap.align_armature``'s Blender side: the template armature that skins the layout, the target
armature, the pose set bone by bone through Blender's ``PoseBone.matrix`` setter (``core.armature``
computes where each bone goes), the layout read through its armature deformation, the skinning released.

A failure after the pose was set is undone with :func:`restore_pose` by the operator.
"""

import bpy

import numpy as np
from mathutils import Matrix

from ..core import armature as armature_maths
from ..core.armature import SCALE_ALONG
from ..core.errors import LayoutError
from ..core.transforms import matrix_array
from .evaluated_mesh import read_evaluated_mesh


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
    not skin the layout. Raises :class:`LayoutError` when there is none or it is not an armature."""
    template = template_armature(layout)
    if name:
        target = bpy.data.objects.get(name)
        if target is None:
            raise LayoutError(f"No object named '{name}'")
    else:
        target = layout.springwrap.target_armature
        if target is None:
            selected = [obj for obj in context.selected_objects if obj.type == "ARMATURE" and obj != template]
            if len(selected) > 1:
                raise LayoutError("Several armatures are selected: pick the target armature in the panel")
            target = selected[0] if selected else None
    if target is None:
        raise LayoutError("No target armature: pick one in the Springwrap panel (or select it)")
    if target.type != "ARMATURE":
        raise LayoutError(f"'{target.name}' is not an armature")
    if target == template:
        raise LayoutError(f"The target armature '{target.name}' is the layout's own armature")
    return target


def _world_frames(armature) -> dict:
    """Each pose bone of ``armature`` (evaluated pose) as an ``armature_maths.BoneFrame`` in world space."""
    world = matrix_array(armature.matrix_world)
    frames = {}
    for pose_bone in armature.pose.bones:
        if pose_bone.bone.length <= 0.0:
            continue
        frame = armature_maths.frame_from_matrix(matrix_array(pose_bone.matrix), pose_bone.bone.length)
        frames[pose_bone.name] = armature_maths.frame_in_space(frame, world)
    return frames


POSE_CHANNELS = ("rotation_mode", "location", "rotation_quaternion", "rotation_euler", "rotation_axis_angle", "scale")
"""A pose bone's own transform: what the user set, kept by :func:`pose_snapshot`."""


def pose_snapshot(armature) -> list:
    """Every pose bone's own transform (the pose as the user set it) and its bone's scale inheritance, to put back
    on failure: ``(name, inherit_scale, {channel: value})`` per pose bone."""
    return [
        (
            pose_bone.name,
            pose_bone.bone.inherit_scale,
            {channel: _copied(getattr(pose_bone, channel)) for channel in POSE_CHANNELS},
        )
        for pose_bone in armature.pose.bones
    ]


def _copied(value):
    """A channel's value detached from Blender's data (a vector or quaternion as a tuple, a mode as it is)."""
    return value if isinstance(value, str) else tuple(value)


def restore_pose(armature, snapshot) -> None:
    """Put back the pose :func:`pose_snapshot` kept."""
    for name, inherit_scale, channels in snapshot:
        pose_bone = armature.pose.bones[name]
        pose_bone.bone.inherit_scale = inherit_scale
        for channel, value in channels.items():
            setattr(pose_bone, channel, value)


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

    Matched bones get :func:`armature_maths.desired_pose_matrix` through Blender's ``PoseBone.matrix``
    setter (with :data:`SCALE_ALONG` their Inherit Scale is set to None first), a depth level at a time (each level is evaluated before the next, since the setter reads
    the parent's evaluated pose); bones without a partner are cleared to their rest transform, so they
    follow their parent. Raises :class:`LayoutError` when no bone matches (nothing changed then)."""
    context.view_layer.update()
    target_frames = _world_frames(target)
    names = [bone.name for bone in template.data.bones]
    matched = armature_maths.matched_bones(names, target_frames.keys())
    if not matched:
        raise LayoutError(
            f"No bone of '{template.name}' has a partner of the same name in '{target.name}' "
            f"({len(names)} and {len(target.data.bones)} bones): nothing to align"
        )
    template_world = matrix_array(template.matrix_world)
    if abs(np.linalg.det(template_world[:3, :3])) < 1e-12:
        raise LayoutError(f"Armature '{template.name}' has zero scale")
    to_template = np.linalg.inv(template_world)
    desired = {}
    for name in matched:
        bone = template.data.bones[name]
        frame = armature_maths.frame_in_space(target_frames[name], to_template)
        try:
            desired[name] = armature_maths.desired_pose_matrix(
                frame, matrix_array(bone.matrix_local), bone.length, match_roll, scale_mode
            )
        except ValueError as error:
            raise LayoutError(f"Bone '{name}': {error}") from error
    if scale_mode == SCALE_ALONG:
        # A child inherits its parent's stretch along the parent's axis as a shear, which a pose
        # (location, rotation, scale) cannot undo: matched bones take no scale from their parent.
        for name in matched:
            template.data.bones[name].inherit_scale = "NONE"
    levels = armature_maths.depth_levels(
        names, [bone.parent.name if bone.parent else "" for bone in template.data.bones]
    )
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
    mismatch = max(armature_maths.bone_mismatch(posed_frames[name], target_frames[name]) for name in matched)
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
        positions = read_evaluated_mesh(depsgraph, layout, world=False).vertices
    finally:
        for modifier in switched:
            modifier.show_viewport = True
    if positions.shape[0] != len(layout.data.vertices):
        raise LayoutError(
            f"Layout '{layout.name}': its armature deformation changed the vertex count "
            f"({len(layout.data.vertices)} -> {positions.shape[0]})"
        )
    return positions


def release_skinning(layout) -> int:
    """Remove the layout's Armature modifiers and turn an armature parent into a plain parent (world
    matrix kept), so the baked pose is not deformed a second time. Returns how many were released."""
    released = 0
    for modifier in [
        modifier for modifier in layout.modifiers if modifier.type == "ARMATURE" and modifier.show_viewport
    ]:
        layout.modifiers.remove(modifier)
        released += 1
    if layout.parent is not None and layout.parent_type == "ARMATURE":
        world = layout.matrix_world.copy()
        layout.parent_type = "OBJECT"
        layout.matrix_world = world
        released += 1
    return released
