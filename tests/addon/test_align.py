"""``springwrap.align`` under Blender (PyPI ``bpy``): anchor fits and ICP, applied to the object or baked.

The layout is a copy of the target mesh (Suzanne, subdivided once) moved by a known transform, so
the true alignment is known: every layout vertex must come back onto its target vertex.
"""

import math

import bpy

import numpy as np
import pytest
from mathutils import Euler, Matrix, Vector

from bpy_helpers import SPACE_POINT, PanelRecorder, read_state, snapshot, world_positions

KNOWN = {
    # A transform of the layout away from the target: rotation, translation, scale (and shear for affine).
    "RIGID": Matrix.Translation((0.3, -0.5, 0.2)) @ Euler((0.5, -0.3, 0.8)).to_matrix().to_4x4(),
    "SIMILARITY": Matrix.Translation((0.3, -0.5, 0.2))
    @ Euler((0.5, -0.3, 0.8)).to_matrix().to_4x4()
    @ Matrix.Scale(1.7, 4),
    "AFFINE": Matrix.Translation((0.3, -0.5, 0.2))
    @ Matrix(((1.2, 0.3, 0.0, 0.0), (0.1, 0.8, -0.2, 0.0), (0.0, 0.25, 1.4, 0.0), (0.0, 0.0, 0.0, 1.0))),
}
ANCHOR_VERTICES = (0, 57, 130, 208, 301, 377, 444)


def make_scene(misalignment, delete_faces=0):
    """Suzanne as the target (optionally with faces deleted) and a copy of it moved by ``misalignment``⁻¹."""
    bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0.2, 0.1, -0.3), rotation=(0.2, 0.1, 0.4))
    target = bpy.context.active_object
    target.name = "Target"
    layout = target.copy()
    layout.data = target.data.copy()
    layout.name = "Layout"
    bpy.context.collection.objects.link(layout)
    layout.matrix_world = misalignment.inverted() @ target.matrix_world
    if delete_faces:
        import bmesh

        mesh = bmesh.new()
        mesh.from_mesh(target.data)
        mesh.faces.ensure_lookup_table()
        doomed = [mesh.faces[index] for index in range(0, len(mesh.faces), len(mesh.faces) // delete_faces)]
        bmesh.ops.delete(mesh, geom=doomed, context="FACES_ONLY")
        mesh.to_mesh(target.data)
        mesh.free()
        target.data.update()
    layout.springwrap.target = target
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    return target, layout


def true_positions(target, layout):
    """Where each layout vertex belongs: its own vertex of the (undeleted) target, in world space."""
    matrix = np.array(target.matrix_world, dtype=np.float64)
    local = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", local)
    return local.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def add_exact_anchors(target, layout, vertices=ANCHOR_VERTICES):
    truth = true_positions(target, layout)
    for vertex in vertices:
        result = bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=tuple(truth[vertex]), use_location=True, on_surface=False
        )
        assert result == {"FINISHED"}
    return truth


def reports(capfd):
    """What the operators reported (Blender prints reports to stdout or stderr, depending on its version)."""
    captured = capfd.readouterr()
    return captured.out + captured.err


def diagonal(obj):
    points = world_positions(obj)
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def max_error(layout, truth):
    return float(np.linalg.norm(world_positions(layout) - truth, axis=1).max())


def test_registered_with_undo_and_a_poll_that_says_why():
    operator = bpy.types.SPRINGWRAP_OT_align
    assert operator.bl_options == {"REGISTER", "UNDO"}
    assert bpy.ops.springwrap.align.get_rna_type().description
    assert not bpy.ops.springwrap.align.poll()
    target, layout = make_scene(KNOWN["RIGID"])
    assert bpy.ops.springwrap.align.poll()
    layout.springwrap.target = None
    assert not bpy.ops.springwrap.align.poll()
    with pytest.raises(RuntimeError, match="No target set"):
        bpy.ops.springwrap.align()


@pytest.mark.parametrize("method", ["RIGID", "SIMILARITY"])
@pytest.mark.parametrize("apply", ["OBJECT", "BAKE"])
def test_exact_anchors_recover_a_known_transform(method, apply, capfd):
    target, layout = make_scene(KNOWN[method])
    truth = add_exact_anchors(target, layout)
    matrix_before = layout.matrix_world.copy()
    before = max_error(layout, truth)
    assert before > 0.3

    assert bpy.ops.springwrap.align(method=method, use_icp=False, apply=apply) == {"FINISHED"}
    bpy.context.view_layer.update()
    assert max_error(layout, truth) <= 1e-5 * max(1.0, diagonal(target))
    if apply == "OBJECT":
        assert layout.matrix_world != matrix_before
    else:
        assert layout.matrix_world == matrix_before
    assert f"{method.lower()} fit to {len(ANCHOR_VERTICES)} anchors" in reports(capfd)


def test_exact_anchors_recover_an_affine_transform_baked():
    target, layout = make_scene(KNOWN["AFFINE"])
    truth = add_exact_anchors(target, layout)
    assert bpy.ops.springwrap.align(method="AFFINE", use_icp=False, apply="BAKE") == {"FINISHED"}
    assert max_error(layout, truth) <= 1e-5 * max(1.0, diagonal(target))


def test_a_similarity_fit_cannot_recover_a_shear():
    """The similarity fit is the least-squares best one, not exact: the affine fit is needed."""
    target, layout = make_scene(KNOWN["AFFINE"])
    truth = add_exact_anchors(target, layout)
    assert bpy.ops.springwrap.align(method="SIMILARITY", use_icp=False, apply="BAKE") == {"FINISHED"}
    assert max_error(layout, truth) > 0.01


def test_a_shearing_fit_on_the_object_transform_is_refused_and_nothing_changes():
    target, layout = make_scene(Matrix.Identity(4))
    truth = add_exact_anchors(target, layout)
    # The layout's mesh (not its object transform) is sheared: undoing it needs a shear.
    local = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", local)
    shear = np.array(KNOWN["AFFINE"].inverted(), dtype=np.float64)
    layout.data.vertices.foreach_set(
        "co", (local.reshape(-1, 3) @ shear[:3, :3].T + shear[:3, 3]).astype(np.float32).ravel()
    )
    layout.data.update()
    before, matrix = snapshot(layout), layout.matrix_world.copy()
    with pytest.raises(RuntimeError, match="shears the layout"):
        bpy.ops.springwrap.align(method="AFFINE", use_icp=False, apply="OBJECT")
    assert snapshot(layout) == before and layout.matrix_world == matrix
    assert bpy.ops.springwrap.align(method="AFFINE", use_icp=False, apply="BAKE") == {"FINISHED"}
    assert max_error(layout, truth) <= 1e-5 * max(1.0, diagonal(target))


def test_object_transform_under_a_parent():
    target, layout = make_scene(KNOWN["SIMILARITY"])
    truth = add_exact_anchors(target, layout)
    bpy.ops.object.empty_add(location=(1.0, 2.0, -1.0), rotation=(0.3, 0.0, 0.7))
    parent = bpy.context.active_object
    parent.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    world = layout.matrix_world.copy()
    layout.parent = parent
    layout.matrix_world = world
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()

    assert bpy.ops.springwrap.align(method="SIMILARITY", use_icp=False, apply="OBJECT") == {"FINISHED"}
    bpy.context.view_layer.update()
    assert layout.parent == parent
    assert max_error(layout, truth) <= 1e-5 * max(1.0, diagonal(target))


def misalignment(degrees=10.0, shift_fraction=0.05, target_diagonal=3.4):
    """A rotation by ``degrees`` about a skew axis and a shift of ``shift_fraction`` of the diagonal."""
    axis = Vector((0.3, 0.8, 0.5)).normalized()
    shift = Vector((0.6, -0.5, 0.62)).normalized() * shift_fraction * target_diagonal
    return Matrix.Translation(shift) @ Matrix.Rotation(math.radians(degrees), 4, axis)


@pytest.mark.parametrize("delete_faces", [0, 40])
def test_icp_alone_converges_from_10_degrees_and_5_percent(delete_faces, capfd):
    target, layout = make_scene(misalignment(), delete_faces=delete_faces)
    truth = true_positions(target, layout)
    size = diagonal(layout)
    assert max_error(layout, truth) > 0.05 * size

    result = bpy.ops.springwrap.align(method="RIGID", use_anchors=False, use_icp=True, icp_iterations=100)
    assert result == {"FINISHED"}
    errors = np.linalg.norm(world_positions(layout) - truth, axis=1)
    assert errors.max() <= 1e-4 * size, f"max error {errors.max() / size:.2e} of the diagonal"
    report = reports(capfd)
    assert "converged" in report and "not converged" not in report
    from benchmarks.retarget.springwrap_methods import _ALIGN_REPORT

    assert _ALIGN_REPORT.search(report)["ending"] == "converged"  # the benchmark reads this report


def test_rough_anchors_then_icp_recover_a_similarity():
    """Three rough anchors (1 % off) bring the layout close; ICP finishes the job, exactly when told to
    follow the surface alone (anchor weight 0), partly when it also keeps the rough anchors."""
    errors = {}
    for weight in (None, 1.0, 0.0):
        bpy.ops.wm.read_homefile(use_empty=True)
        target, layout = make_scene(KNOWN["SIMILARITY"])
        truth = true_positions(target, layout)
        rng = np.random.default_rng(5)
        size = diagonal(target)
        for vertex in ANCHOR_VERTICES[:3]:
            noisy = truth[vertex] + rng.normal(size=3) * 0.01 * size
            bpy.ops.springwrap.anchor_add(
                vertex_index=vertex, location=tuple(noisy), use_location=True, on_surface=False
            )
        options = {"use_icp": False} if weight is None else {"use_icp": True, "anchor_weight": weight}
        assert bpy.ops.springwrap.align(method="SIMILARITY", icp_iterations=100, apply="BAKE", **options) == {
            "FINISHED"
        }
        errors[weight] = max_error(layout, truth) / size
    assert errors[0.0] <= 1e-4, errors
    assert errors[1.0] < 0.7 * errors[None], errors


def test_the_anchor_weight_holds_icp_to_the_anchors_where_the_shapes_differ():
    """The layout is Suzanne stretched 20 % along one axis: no similarity puts it on the target, so
    ICP drifts from the anchors' fit; the heavier the anchors, the closer they stay."""
    residuals = []
    for weight in (0.0, 1.0, 10.0):
        bpy.ops.wm.read_homefile(use_empty=True)
        target, layout = make_scene(KNOWN["SIMILARITY"])
        truth = add_exact_anchors(target, layout)
        local = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
        layout.data.vertices.foreach_get("co", local)
        local = local.reshape(-1, 3) * np.array([1.2, 1.0, 1.0], dtype=np.float32)
        layout.data.vertices.foreach_set("co", local.ravel())
        layout.data.update()
        assert bpy.ops.springwrap.align(method="SIMILARITY", use_icp=True, anchor_weight=weight, apply="BAKE") == {
            "FINISHED"
        }
        anchored = list(ANCHOR_VERTICES)
        residuals.append(float(np.linalg.norm(world_positions(layout)[anchored] - truth[anchored], axis=1).mean()))
    assert residuals[0] > residuals[1] > residuals[2], residuals


def test_alignment_detaches_every_face_point_and_keeps_the_rest_shape():
    target, layout = make_scene(KNOWN["RIGID"])
    add_exact_anchors(target, layout)
    local_before = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", local_before)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert (read_state(layout)[0] != SPACE_POINT).any()
    assert bpy.ops.springwrap.align(method="RIGID", use_icp=False, apply="BAKE") == {"FINISHED"}
    assert (read_state(layout)[0] == SPACE_POINT).all()
    from springwrap.blender import attributes

    rest = attributes.read_rest(layout)
    assert rest is not None
    np.testing.assert_array_equal(rest.reshape(-1), local_before)


@pytest.mark.parametrize(
    ("anchor_vertices", "method", "options", "message"),
    [
        ((0, 57), "RIGID", {}, "needs at least 3 anchors"),
        ((0, 57, 130), "AFFINE", {}, "needs at least 4 anchors"),
        ((), "SIMILARITY", {"use_icp": False}, "needs at least 3 anchors"),
        ((0, 57, 130), "SIMILARITY", {"use_anchors": False, "use_icp": False}, "Nothing to do"),
    ],
)
def test_bad_input_is_reported_and_leaves_the_scene_untouched(anchor_vertices, method, options, message):
    target, layout = make_scene(KNOWN[method])
    add_exact_anchors(target, layout, anchor_vertices)
    before, matrix = snapshot(layout), layout.matrix_world.copy()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.align(method=method, **options)
    assert snapshot(layout) == before and layout.matrix_world == matrix


@pytest.mark.parametrize(
    ("method", "offsets", "message"),
    [
        # Target points on one line: the rotation about it is unknown.
        ("RIGID", [(0.1, 0.2, 0.05), (0.2, 0.4, 0.1), (0.3, 0.6, 0.15), (0.4, 0.8, 0.2)], "lie on one line"),
        # Target points in one plane: the affine fit flattens the layout.
        ("AFFINE", [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.0), (0.5, 0.5, 0.0), (0.2, 0.7, 0.0)], "collapses"),
    ],
)
def test_degenerate_anchor_targets_are_named(method, offsets, message):
    target, layout = make_scene(KNOWN["RIGID"])
    base = true_positions(target, layout)[0]
    for vertex, offset in zip(ANCHOR_VERTICES, offsets):
        location = base + np.array(offset)
        bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=tuple(location), use_location=True, on_surface=False
        )
    before, matrix = snapshot(layout), layout.matrix_world.copy()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.align(method=method, use_icp=False)
    assert snapshot(layout) == before and layout.matrix_world == matrix


def test_undo_restores_the_transform_and_the_vertices():
    target, layout = make_scene(KNOWN["SIMILARITY"])
    add_exact_anchors(target, layout)
    bpy.ops.ed.undo_push(message="Before align")
    before, matrix = snapshot(layout), layout.matrix_world.copy()
    # The second positional argument asks bpy.ops to push the operator's own undo step.
    assert bpy.ops.springwrap.align("EXEC_DEFAULT", True, method="SIMILARITY", apply="OBJECT") == {"FINISHED"}
    assert bpy.data.objects["Layout"].matrix_world != matrix
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]  # undo replaced the data blocks: fetch again
    assert snapshot(layout) == before and layout.matrix_world == matrix

    bpy.context.view_layer.objects.active = layout
    assert bpy.ops.springwrap.align("EXEC_DEFAULT", True, method="SIMILARITY", apply="BAKE") == {"FINISHED"}
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert snapshot(layout) == before and layout.matrix_world == matrix


def test_sidebar_panel_offers_the_anchor_fit_and_icp_alone():
    from springwrap.ui.panels import SPRINGWRAP_PT_align

    class Recorder(PanelRecorder):
        def operator_menu_enum(self, idname, property_name, **kwargs):
            self.operators.append((idname + ":" + property_name, None))

    target, layout = make_scene(KNOWN["RIGID"])
    add_exact_anchors(target, layout, ANCHOR_VERTICES[:4])
    assert SPRINGWRAP_PT_align.bl_parent_id == "SPRINGWRAP_PT_layout"
    recorder = Recorder()
    SPRINGWRAP_PT_align.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    buttons = dict(recorder.operators)
    assert set(buttons) == {"springwrap.align:method", "springwrap.align"}
    assert buttons["springwrap.align"].use_anchors is False
    assert "Fit to 4 anchors, then ICP" in recorder.labels
