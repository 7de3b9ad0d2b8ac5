"""The wrap's spring resolution (coarse to fine): the layout relaxed, then its faces cut k x k relaxed again."""

import bpy

import numpy as np
import pytest

from bpy_helpers import (
    SPHERE_CENTER,
    SPHERE_RADIUS,
    Reference,
    assert_no_flipped_quads,
    assert_wrapped_onto,
    local_positions,
    plane_scene,
    radial,
    read_state,
    snapshot,
    sphere_scene,
    world_positions,
    wrap_session,
    wrap_with_anchors,
)


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
