"""The target cache: a target nothing changed is reused without being read again, and
every change of its evaluated mesh is seen: edit mode, modifiers, shape keys, an armature's pose, an
animated frame, undo, another object of the same name, handlers removed or installed late.

Each change moves the target's surface by 0.2 or more; a snap after it must land every vertex on the *new*
surface (a stale mesh leaves them 0.2 off), and the read must not have been the unread path.
"""

import bpy

import bmesh
import numpy as np
import pytest

from bpy_helpers import Reference, activate_layout, addon_module, scene, world_positions


def reads():
    return addon_module("blender.target").target_reads()


def snap_onto_current_target(target, layout):
    """Detach and snap the layout; check it landed on the target's current surface; the read's path."""
    activate_layout(layout, target)
    before = reads()
    assert bpy.ops.springwrap.detach() == {"FINISHED"}
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}
    after = reads()
    reference = Reference(target)
    for point in world_positions(layout):
        _location, _index, distance = reference.nearest(point)
        assert distance <= 1e-5, f"a snapped vertex is {distance:.3g} off the target's current surface"
    return {path: after[path] - before[path] for path in after}


def test_a_target_nothing_changed_is_not_read_again():
    target, layout = scene()
    first = snap_onto_current_target(target, layout)
    assert first["built"] == 1 and first["hashed"] == 0 and first["unread"] > 0, first  # read once, then reused
    layout.location.x += 0.01  # the layout's own changes do not touch the target's entry
    bpy.context.view_layer.update()
    second = snap_onto_current_target(target, layout)
    assert second["built"] == second["hashed"] == 0 and second["unread"] > 0, second


def _move_in_edit_mode(target):
    bpy.ops.object.select_all(action="DESELECT")
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    bpy.ops.object.mode_set(mode="EDIT")
    mesh = bmesh.from_edit_mesh(target.data)
    for vertex in mesh.verts:
        if vertex.co.z > 0.0:
            vertex.co.z += 0.3
    bmesh.update_edit_mesh(target.data)
    bpy.ops.object.mode_set(mode="OBJECT")


def _move_in_edit_mode_with_an_operator(target):
    bpy.ops.object.select_all(action="DESELECT")
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.transform.translate(value=(0.0, 0.0, 0.3))
    bpy.ops.object.mode_set(mode="OBJECT")


def _modifier_added(target):
    modifier = target.modifiers.new("Displace", "DISPLACE")
    modifier.strength = 0.3


def _modifier_input_changed(target):
    target.modifiers["Displace"].strength = 0.5  # prepared with strength 0.2


def _prepare_displace(target):
    target.modifiers.new("Displace", "DISPLACE").strength = 0.2


def _prepare_shape_key(target):
    target.shape_key_add(name="Basis")
    key = target.shape_key_add(name="Up")
    for point in key.data:
        point.co.z += 0.3
    key.value = 0.0  # a new key's value is not 0 in every version


def _shape_key_value(target):
    target.data.shape_keys.key_blocks["Up"].value = 1.0


def _prepare_armature(target):
    armature = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    bpy.context.scene.collection.objects.link(armature)
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.mode_set(mode="EDIT")
    bone = armature.data.edit_bones.new("Bone")
    bone.head, bone.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    bpy.ops.object.mode_set(mode="OBJECT")
    group = target.vertex_groups.new(name="Bone")
    group.add(list(range(len(target.data.vertices))), 1.0, "REPLACE")
    target.modifiers.new("Armature", "ARMATURE").object = armature


def _pose_changed(target):
    bpy.data.objects["Rig"].pose.bones["Bone"].location = (0.3, 0.0, 0.0)


def _prepare_animation(target):
    modifier = target.modifiers.new("Displace", "DISPLACE")
    modifier.strength = 0.0
    modifier.keyframe_insert("strength", frame=1)
    modifier.strength = 0.4
    modifier.keyframe_insert("strength", frame=10)
    bpy.context.scene.frame_set(1)


def _frame_changed(_target):
    bpy.context.scene.frame_set(10)


def _object_moved(target):
    target.location.z += 0.3


def _mesh_data_from_python(target):
    positions = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
    target.data.vertices.foreach_get("co", positions)
    positions[2::3] += 0.3
    target.data.vertices.foreach_set("co", positions)
    target.data.update()


def _nothing(_target):
    pass


CHANGES = {
    "edit mode (bmesh)": (_nothing, _move_in_edit_mode),
    "edit mode (translate)": (_nothing, _move_in_edit_mode_with_an_operator),
    "modifier added": (_nothing, _modifier_added),
    "modifier input": (_prepare_displace, _modifier_input_changed),
    "shape key value": (_prepare_shape_key, _shape_key_value),
    "armature pose": (_prepare_armature, _pose_changed),
    "animated frame": (_prepare_animation, _frame_changed),
    "object moved": (_nothing, _object_moved),
    "mesh data from Python": (_nothing, _mesh_data_from_python),
}


@pytest.mark.parametrize("guard", ["handlers and sanity key", "handlers alone"])
@pytest.mark.parametrize("change", CHANGES, ids=list(CHANGES))
def test_every_change_of_the_evaluated_target_is_seen(change, guard, monkeypatch):
    """The handlers see each change by themselves (the sanity key, made blind, does not help them)."""
    if guard == "handlers alone":
        monkeypatch.setattr(addon_module("blender.target"), "_sanity_key", lambda evaluated: ())
    prepare, change_target = CHANGES[change]
    target, layout = scene()
    prepare(target)
    snap_onto_current_target(target, layout)
    change_target(target)
    paths = snap_onto_current_target(target, layout)
    assert paths["built"] == 1 and paths["hashed"] == 0, paths  # a new content: read, hashed, built once
    assert paths["unread"] > 0, paths  # then reused: nothing changed after that


@pytest.mark.parametrize("guard", ["handlers and sanity key", "handlers alone"])
def test_undo_is_seen(guard, monkeypatch):
    if guard == "handlers alone":
        monkeypatch.setattr(addon_module("blender.target"), "_sanity_key", lambda evaluated: ())
    target, layout = scene()
    bpy.ops.ed.undo_push(message="sphere")
    _mesh_data_from_python(target)
    bpy.ops.ed.undo_push(message="sphere moved")
    snap_onto_current_target(target, layout)
    bpy.ops.ed.undo()
    target, layout = bpy.data.objects["Target"], bpy.data.objects["Layout"]
    before = reads()
    activate_layout(layout, target)
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}
    after = reads()
    assert after["hashed"] + after["built"] == before["hashed"] + before["built"] + 1, (before, after)
    reference = Reference(target)
    assert max(reference.nearest(point)[2] for point in world_positions(layout)) <= 1e-5


@pytest.mark.parametrize("guard", ["handlers and sanity key", "handlers alone"])
def test_another_object_of_the_same_name_is_read(guard, monkeypatch):
    if guard == "handlers alone":
        monkeypatch.setattr(addon_module("blender.target"), "_sanity_key", lambda evaluated: ())
    target, layout = scene()
    snap_onto_current_target(target, layout)
    matrix = target.matrix_world.copy()
    bpy.data.objects.remove(target)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.8)
    other = bpy.context.active_object
    other.name = "Target"
    other.matrix_world = matrix  # same name, counts and matrix: only the object differs
    paths = snap_onto_current_target(other, layout)
    assert paths["built"] == 1, paths


def test_without_its_handlers_the_cache_reads_the_target_every_time():
    target, layout = scene()
    snap_onto_current_target(target, layout)
    changes = addon_module("blender.target_changes")
    handler = changes._on_depsgraph_update
    bpy.app.handlers.depsgraph_update_post.remove(handler)
    try:
        assert not changes.installed()
        paths = snap_onto_current_target(target, layout)
        assert paths["unread"] == 0 and paths["hashed"] > 0, paths
    finally:
        bpy.app.handlers.depsgraph_update_post.append(handler)


def test_handlers_installed_after_a_change_read_the_target_again():
    target, layout = scene()
    snap_onto_current_target(target, layout)
    changes = addon_module("blender.target_changes")
    changes.uninstall()
    try:
        target.location.z += 0.3
        bpy.context.view_layer.update()  # seen by nobody
    finally:
        changes.install()
    paths = snap_onto_current_target(target, layout)
    assert paths["built"] == 1, paths
