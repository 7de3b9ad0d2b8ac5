"""Plain tests of the armature alignment's bpy-free logic (``addon/springwrap/core/armature.py``), no Blender."""

import numpy as np
import pytest

from helpers import core_module

armature_align = core_module("armature")


def rotation_about(axis, degrees):
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    angle = np.radians(degrees)
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * skew + (1.0 - np.cos(angle)) * skew @ skew


def rest_matrix(rotation, head):
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = head
    return matrix


def test_matched_bones_keep_the_templates_order():
    assert armature_align.matched_bones(["hip", "knee", "toe", "ankle"], {"ankle", "hip", "wing"}) == ["hip", "ankle"]
    assert armature_align.matched_bones(["a", "b"], ["c"]) == []


def test_depth_levels_put_parents_before_children():
    names = ["hand", "root", "arm", "spine", "finger", "loose"]
    parents = ["arm", "", "spine", "root", "hand", "not-in-the-armature"]
    levels = armature_align.depth_levels(names, parents)
    assert levels == [["root", "loose"], ["spine"], ["arm"], ["hand"], ["finger"]]


def test_depth_levels_refuse_a_cycle():
    with pytest.raises(ValueError, match="cycle"):
        armature_align.depth_levels(["a", "b", "c"], ["c", "a", "b"])


@pytest.mark.parametrize("degrees", [0.0, 37.0, 90.0, 179.0, 180.0])
def test_rotation_between_turns_one_direction_onto_another(degrees):
    source = np.array([0.3, -0.2, 0.9])
    destination = rotation_about([1.0, 2.0, -0.5], degrees) @ source
    rotation = armature_align.rotation_between(source, destination)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    np.testing.assert_allclose(rotation @ source, destination, atol=1e-12)


def test_desired_pose_puts_the_bone_on_the_target_with_its_roll():
    """The pose matrix's head is the target's head, its y axis runs to the target's tail, its z axis is the target's."""
    target = armature_align.BoneFrame(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 5.0]), np.array([0.0, 1.0, 0.0]))
    rest = rest_matrix(rotation_about([1.0, 0.0, 0.0], 30.0), [0.0, 0.0, 0.0])
    matrix = armature_align.desired_pose_matrix(target, rest, rest_length=1.0)
    np.testing.assert_allclose(matrix[:3, 3], target.head)
    np.testing.assert_allclose(matrix[:3, 3] + matrix[:3, 1] * 1.0, target.tail, atol=1e-12)  # stretched to length 2
    np.testing.assert_allclose(matrix[:3, 2], target.z_axis, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(matrix[:3, [0, 2]], axis=0), [1.0, 1.0])  # girth kept
    assert np.linalg.det(matrix[:3, :3]) == pytest.approx(2.0)  # a proper frame, stretched 2x along y


def test_desired_pose_without_roll_keeps_the_templates_twist():
    """Without roll matching, the rest frame only swings (smallest rotation) onto the target direction."""
    rest_rotation = rotation_about([0.0, 1.0, 0.0], 40.0)  # a bone along +Y, twisted 40 degrees about itself
    target = armature_align.BoneFrame(np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    matrix = armature_align.desired_pose_matrix(
        target, rest_matrix(rest_rotation, [0.0, 0.0, 0.0]), 1.0, match_roll=False
    )
    swing = armature_align.rotation_between([0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(matrix[:3, :3], swing @ rest_rotation, atol=1e-12)
    rolled = armature_align.desired_pose_matrix(target, rest_matrix(rest_rotation, [0.0, 0.0, 0.0]), 1.0)
    np.testing.assert_allclose(rolled[:3, 2], [1.0, 0.0, 0.0], atol=1e-12)
    assert not np.allclose(rolled[:3, :3], matrix[:3, :3], atol=1e-3)


@pytest.mark.parametrize(
    "mode, column_norms",
    [("ALONG", [1.0, 1.5, 1.0]), ("UNIFORM", [1.5, 1.5, 1.5]), ("NONE", [1.0, 1.0, 1.0])],
)
def test_scale_modes(mode, column_norms):
    target = armature_align.BoneFrame(np.zeros(3), np.array([0.0, 3.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    matrix = armature_align.desired_pose_matrix(target, np.eye(4), rest_length=2.0, scale_mode=mode)
    np.testing.assert_allclose(np.linalg.norm(matrix[:3, :3], axis=0), column_norms)


def test_zero_length_bones_and_unknown_modes_are_refused():
    target = armature_align.BoneFrame(np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="zero length"):
        armature_align.desired_pose_matrix(target, np.eye(4), 1.0)
    target = armature_align.BoneFrame(np.zeros(3), np.ones(3), np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="scale mode"):
        armature_align.desired_pose_matrix(target, np.eye(4), 1.0, scale_mode="STRETCH")


def test_frames_move_between_spaces_with_a_unit_z_axis():
    """A frame taken into a scaled, turned space keeps its points exact and its z axis a unit vector orthogonal to the bone."""
    frame = armature_align.frame_from_matrix(rest_matrix(rotation_about([0.0, 0.0, 1.0], 90.0), [1.0, 0.0, 0.0]), 2.0)
    np.testing.assert_allclose(frame.tail, [-1.0, 0.0, 0.0], atol=1e-12)  # +Y turned to -X, length 2
    space = np.diag([2.0, 3.0, 0.5, 1.0])
    space[:3, :3] = space[:3, :3] @ rotation_about([1.0, 1.0, 0.0], 25.0)
    space[:3, 3] = [0.5, -1.0, 2.0]
    moved = armature_align.frame_in_space(frame, space)
    np.testing.assert_allclose(moved.head, armature_align.transform_points(space, frame.head))
    np.testing.assert_allclose(moved.tail, armature_align.transform_points(space, frame.tail))
    assert np.linalg.norm(moved.z_axis) == pytest.approx(1.0)
    assert abs(np.dot(moved.z_axis, moved.tail - moved.head)) < 1e-12
    assert armature_align.bone_mismatch(moved, moved) == 0.0
