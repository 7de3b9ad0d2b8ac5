"""The wrap with ``solver='ENERGY'`` under Blender: the same scenes and independent checks as
``test_wrap`` (``mathutils`` BVHTree distances, analytic surface normals), plus what the energy solver
promises on top: few iterations, no quad turned over, and refusals that leave the layout as it was; and the
spring resolution (coarse to fine: the layout relaxed, then its faces cut k x k and relaxed again)."""

import bpy

import numpy as np
import pytest

from bpy_helpers import (
    SPHERE_CENTER,
    SPHERE_RADIUS,
    Reference,
    assert_no_flipped_quads,
    assert_wrapped_onto,
    edge_lengths,
    edges_of,
    head_scene,
    local_positions,
    midline_drift,
    mirror_outcome,
    plane_scene,
    radial,
    read_state,
    snapshot,
    sphere_scene,
    world_positions,
    wrap_session,
    wrap_with_anchors,
)


def test_grid_above_a_plane_lands_in_a_few_iterations(capfd):
    target, layout, normal = plane_scene()
    template = world_positions(layout)
    assert wrap_with_anchors(layout, spacing=0.5, solver="ENERGY") == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert_wrapped_onto(
        layout, Reference(target), template, lambda points: np.tile(normal, (len(points), 1)), (0.8, 1.25)
    )
    output = capfd.readouterr().out
    iterations = int(output.split("Wrapped 'Layout' in ")[1].split(" iterations")[0])
    assert iterations <= 40 and "(converged)" in output


def test_grid_over_a_hole_caps_it_on_the_plane():
    target, layout, normal = plane_scene(hole=True)
    template = world_positions(layout)
    assert wrap_with_anchors(layout, spacing=0.5, solver="ENERGY") == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    world = world_positions(layout)
    assert_wrapped_onto(
        layout, Reference(target), template, lambda points: np.tile(normal, (len(points), 1)), (0.6, 1.6)
    )
    space = states == 0
    assert space.sum() >= 4
    origin = np.array(target.matrix_world.translation)
    edge = np.median(edge_lengths(world, edges_of(layout)))
    assert np.abs((world[space] - origin) @ normal).max() < 0.1 * edge  # the plane continued over the hole


def test_sphere_cap_lands_on_the_sphere_without_a_flipped_quad():
    target, layout = sphere_scene()
    template = world_positions(layout)
    assert wrap_with_anchors(layout, spacing=0.6, solver="ENERGY") == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert_wrapped_onto(layout, Reference(target), template, radial, (0.6, 1.6))
    assert_no_flipped_quads(layout, radial)


def test_hold_on_plane_keeps_a_lone_half_s_midline_on_the_plane_with_the_energy_solver():
    """As ``test_mirror``'s test for the spring solver: the held midline ends on the plane, so the
    mirror that follows finds no face crossing it."""
    target, layout = head_scene()
    midline = np.flatnonzero(local_positions(layout)[:, 0] == 0.0)
    assert midline.size >= 10
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(solver="ENERGY", hold_plane="X") == {"FINISHED"}
    assert midline_drift(layout, midline) < 1e-5
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=3000) == {"FINISHED"}
    outcome = mirror_outcome()
    assert outcome.crossing_faces.size == 0
    assert outcome.seam_max_distance < 1e-5


def test_undo_after_an_energy_wrap_restores_the_template():
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto("EXEC_DEFAULT", True, spacing=0.5)
    before = snapshot(layout)
    bpy.ops.springwrap.wrap("EXEC_DEFAULT", True, solver="ENERGY")
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.ed.undo()
    assert snapshot(bpy.data.objects["Layout"]) == before


def test_the_report_says_what_the_wrap_did(capfd):
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    capfd.readouterr()
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    energy = capfd.readouterr().out
    assert "landed at the end" in energy and "held back" in energy and "fold tolerance" not in energy, energy
    # The last level ends on the energy's decrease or, here (a flat target reached early), on a step that barely
    # moved the points.
    assert "lowered the energy by" in energy or "which barely moved the points" in energy, energy


def _group(layout, name, vertices, weight=1.0):
    group = layout.vertex_groups.new(name=name)
    group.add([int(vertex) for vertex in vertices], weight, "REPLACE")
    return group


def test_the_free_group_floats_and_changes_nothing_far_from_it():
    target, layout, _normal = plane_scene()
    local = np.array([vertex.co[:] for vertex in layout.data.vertices])
    centre = np.flatnonzero(np.linalg.norm(local[:, :2], axis=1) < 0.3)
    far = np.linalg.norm(local[:, :2], axis=1) > 0.7
    assert centre.size >= 4
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert bpy.ops.springwrap.wrap(solver="ENERGY") == {"FINISHED"}
    plain = world_positions(layout).copy()
    assert (read_state(layout)[0] == 1).all()
    # Back to the template, then with the group.
    for vertex, co in zip(layout.data.vertices, local):
        vertex.co = co
    bpy.ops.springwrap.detach()
    _group(layout, "Sockets", centre)
    layout.springwrap.free_group = "Sockets"
    assert bpy.ops.springwrap.wrap(solver="ENERGY") == {"FINISHED"}
    states = read_state(layout)[0]
    anchored = [anchor.vertex_index for anchor in layout.springwrap.anchors]  # an anchor wins over the group
    floating = np.setdiff1d(centre, anchored)
    assert floating.size >= 4
    assert (states[floating] == 0).all() and (np.delete(states, floating) == 1).all()
    moved = np.linalg.norm(world_positions(layout) - plain, axis=1)
    assert moved[far].max() < 1e-3, moved[far].max()


def test_the_stiffness_group_reaches_the_wrap_and_the_operator_overrides_the_setting():
    target, layout, _normal = plane_scene()
    local = np.array([vertex.co[:] for vertex in layout.data.vertices])
    centre = np.flatnonzero(np.linalg.norm(local[:, :2], axis=1) < 0.3)
    _group(layout, "Rigid", centre, 1.0)  # 1: keeps the template's shape, no pull: stays in space
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    layout.springwrap.stiffness_group = "Missing"
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="no vertex group 'Missing'"):
        bpy.ops.springwrap.wrap(solver="ENERGY")
    assert snapshot(layout) == before
    assert bpy.ops.springwrap.wrap(solver="ENERGY", stiffness_group="Rigid") == {"FINISHED"}
    states = read_state(layout)[0]
    anchored = [anchor.vertex_index for anchor in layout.springwrap.anchors]  # an anchor wins over the group
    rigid = np.setdiff1d(centre, anchored)
    assert rigid.size >= 4
    assert (states[rigid] == 0).all() and (np.delete(states, rigid) == 1).all()


def test_the_groups_need_spring_resolution_1_and_leave_the_layout_as_it_was():
    target, layout, _normal = plane_scene()
    _group(layout, "Sockets", [0, 1, 2])
    layout.springwrap.free_group = "Sockets"
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="need Spring Resolution 1"):
        bpy.ops.springwrap.wrap(solver="ENERGY", spring_resolution=2)
    assert snapshot(layout) == before


def test_a_free_group_holding_every_vertex_is_refused_saying_why():
    """Every vertex free: nothing would pull the layout onto the target and the wrap would "converge" where it
    started. It is refused, naming the group, and the layout is left as it was."""
    target, layout, _normal = plane_scene()
    _group(layout, "Sockets", range(len(layout.data.vertices)))
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="Every vertex of layout 'Layout' is in the Free group 'Sockets'"):
        bpy.ops.springwrap.wrap(solver="ENERGY", free_group="Sockets")
    assert snapshot(layout) == before


# ---------------------------------------------------------------- spring resolution (coarse to fine)
# The layout relaxed, then its faces cut k x k and relaxed again.


def test_a_sphere_cap_wrapped_at_resolution_3_lies_on_the_sphere(capfd):
    target, layout = sphere_scene()
    template = world_positions(layout)
    reference = Reference(target)
    assert wrap_with_anchors(layout, spacing=0.6, spring_resolution=3) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert len(layout.data.vertices) == len(template)  # the fine grid is internal
    assert_wrapped_onto(layout, reference, template, radial, (0.5, 2.0))
    radii = np.linalg.norm(world_positions(layout) - np.array(SPHERE_CENTER), axis=1)
    assert radii.max() <= SPHERE_RADIUS + 1e-5 and radii.min() > 0.99 * SPHERE_RADIUS
    assert "(converged)" in capfd.readouterr().out


def test_the_fine_stage_starts_where_the_coarse_one_ended_and_both_count():
    _target, layout, normal = plane_scene(hole=True)
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    session = wrap_session(layout, spring_resolution=2)
    assert session.stage == "coarse"
    for _ in range(100):  # the coarse stage's limit is 2000 iterations
        if session.stage != "coarse":
            break
        session.step(50)
    coarse = session.coarse_iterations
    assert coarse > 0 and session.fine_vertex_count > len(layout.data.vertices)
    session.run()
    assert session.done and session.total_iterations > coarse
    result = session.finish()
    assert result.iterations == session.total_iterations and result.converged
    states, _faces, _barycentrics = read_state(layout)
    assert (states == 0).sum() >= 4  # over the hole
    assert_no_flipped_quads(layout, lambda points: np.tile(normal, (len(points), 1)))


def test_cancel_in_the_fine_stage_restores_the_layout_bit_for_bit():
    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    session = wrap_session(layout, spring_resolution=4)
    for _ in range(2000):
        if session.stage != "coarse":
            break
        session.advance()
    assert session.stage == "fine"
    session.advance()
    assert snapshot(layout) != before
    session.cancel()
    assert snapshot(layout) == before


def test_a_resolution_out_of_range_is_refused():
    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    from springwrap.core import layout_state

    with pytest.raises(layout_state.LayoutError, match="spring resolution must be within 1 .. 8, not 9"):
        wrap_session(layout, spring_resolution=9)
    with pytest.raises(TypeError):
        bpy.ops.springwrap.wrap(spring_resolution="fine")
    assert local_positions(layout) is not None
