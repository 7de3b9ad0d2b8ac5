"""The pair tool's reads and edits under Blender, without a window (``blender/pair_tool.py``): the vertex and the
target point under a mouse position of a view built here, pairs placed, replaced, dragged along the surface,
moved to another vertex and removed, symmetric twins, one undo step per edit, the Live re-settle kept or cancelled
bit for bit, and bad input (no target, a hidden or empty target, a click off the target). The modal operator
itself runs in the GUI lane (``tests/gui/gui_workflow.py``)."""

import time

import bpy

import numpy as np
import pytest
from mathutils import Matrix

from bpy_helpers import (
    activate,
    addon_module,
    plane_scene,
    snapshot,
    symmetric_head_scene,
    world_plane,
    world_positions,
)

WIDTH, HEIGHT = 1000, 800


def top_view(target, normal, distance=5.0, scale=0.35):
    """An orthographic view looking down ``normal`` onto the plane target, its centre over the target's."""
    pair_pick = addon_module("core.pair_pick")
    camera = Matrix.Translation(target.matrix_world.translation + distance * __import__("mathutils").Vector(normal))
    camera = camera @ target.matrix_world.to_quaternion().to_matrix().to_4x4()
    projection = np.diag([scale * HEIGHT / WIDTH, scale, -2.0 / 100.0, 1.0])
    return pair_pick.make_view(projection @ np.array(camera.inverted()), WIDTH, HEIGHT)


def pixel_of(view, point):
    return addon_module("core.pair_pick").project(view, np.asarray(point).reshape(1, 3))[0][0]


def anchors_state(layout):
    """The anchor list as bytes, to compare bit for bit."""
    anchor_list = addon_module("blender.anchors").read_anchors(layout)
    return tuple(np.asarray(field).tobytes() for field in anchor_list)


@pytest.fixture
def plane():
    target, layout, normal = plane_scene()
    return target, layout, normal, top_view(target, normal)


def test_the_vertex_under_the_mouse_and_the_target_point_under_it(plane):
    target, layout, normal, view = plane
    tool = addon_module("blender.pair_tool")
    world = world_positions(layout)
    for vertex in (0, 17, 60, len(world) - 1):
        mouse = pixel_of(view, world[vertex]) + (3.0, -2.0)  # a few pixels off: still that vertex
        assert tool.vertex_under_mouse(layout, view, mouse) == vertex
    assert tool.vertex_under_mouse(layout, view, (3.0, 3.0)) == -1  # a corner of the view: no vertex near
    mouse = pixel_of(view, world[17])
    point = tool.target_under_mouse(bpy.context, layout, view, mouse)
    centre = np.array(target.matrix_world.translation)
    assert abs((point - centre) @ normal) < 1e-5  # on the plane
    np.testing.assert_allclose(pixel_of(view, point), mouse, atol=1e-3)  # under the mouse


def test_two_clicks_make_a_pair_exactly_on_the_surface_and_one_undo_step(plane):
    target, layout, normal, view = plane
    tool = addon_module("blender.pair_tool")
    world = world_positions(layout)
    bpy.ops.ed.undo_push(message="before")
    before = anchors_state(layout)
    vertex = tool.vertex_under_mouse(layout, view, pixel_of(view, world[40]))
    point = tool.target_under_mouse(bpy.context, layout, view, pixel_of(view, world[40]) + (20.0, 5.0))
    outcome = tool.place_pair(bpy.context, layout, vertex, point)
    bpy.ops.ed.undo_push(message="Pair Tool: Add Pair")
    item = layout.springwrap.anchors[0]
    assert (len(layout.springwrap.anchors), item.vertex_index, item.target_kind) == (1, 40, "FACE")
    np.testing.assert_allclose(item.location, point, atol=1e-6)
    target_mesh = addon_module("blender.target").read_target(bpy.context.evaluated_depsgraph_get(), layout).mesh
    on_surface = target_mesh.face_point_positions(
        np.array([item.triangle], dtype=np.uint32), np.array([item.barycentric], dtype=np.float32)
    )
    np.testing.assert_allclose(on_surface[0], point, atol=1e-6)
    assert outcome.active_index == 0 and layout.springwrap.active_anchor_index == 0
    bpy.ops.ed.undo()
    assert anchors_state(bpy.data.objects["Layout"]) == before


def place_pairs(layout, normal, vertices):
    """Pairs on ``vertices``, each to the target point 0.3 under it."""
    tool = addon_module("blender.pair_tool")
    world = world_positions(layout)
    for vertex in vertices:
        tool.place_pair(bpy.context, layout, vertex, world[vertex] - 0.3 * normal)
    return tool, world


def test_a_pair_on_an_anchored_vertex_replaces_it_and_keeps_its_number(plane):
    target, layout, normal, view = plane
    tool, world = place_pairs(layout, normal, (10, 40, 70))
    dragged = []
    for shift in np.linspace(0.0, 60.0, 7):  # a drag of the target end: a ray cast at every mouse move
        mouse = pixel_of(view, world[40]) + (shift, -0.5 * shift)
        point = tool.target_under_mouse(bpy.context, layout, view, mouse)
        tool.place_pair(bpy.context, layout, 40, point)
        item = layout.springwrap.anchors[1]
        assert item.vertex_index == 40 and item.target_kind == "FACE"
        np.testing.assert_allclose(item.location, point, atol=1e-6)
        dragged.append(np.array(item.location))
    assert [item.vertex_index for item in layout.springwrap.anchors] == [10, 40, 70]
    assert np.linalg.norm(dragged[-1] - dragged[0]) > 0.1


def test_dragging_the_layout_end_moves_the_pair_to_another_vertex(plane):
    target, layout, normal, view = plane
    tool, world = place_pairs(layout, normal, (10, 40))
    location = np.array(layout.springwrap.anchors[0].location)
    tool.repick_pair(bpy.context, layout, 0, tool.vertex_under_mouse(layout, view, pixel_of(view, world[12])))
    assert [item.vertex_index for item in layout.springwrap.anchors] == [12, 40]
    np.testing.assert_allclose(layout.springwrap.anchors[0].location, location, atol=1e-6)


def test_remove_takes_the_pair_away_and_needs_no_target(plane):
    target, layout, normal, view = plane
    tool, world = place_pairs(layout, normal, (10, 40, 70))
    layout.springwrap.target = None
    tool.remove_pair(layout, 1)
    assert [item.vertex_index for item in layout.springwrap.anchors] == [10, 70]
    assert layout.springwrap.active_anchor_index == 1


def test_a_space_pair_is_placed_where_asked(plane):
    target, layout, normal, view = plane
    tool = addon_module("blender.pair_tool")
    point = world_positions(layout)[5] - 0.1 * normal  # between the layout and the target
    tool.place_pair(bpy.context, layout, 5, point, on_surface=False)
    item = layout.springwrap.anchors[0]
    assert item.target_kind == "SPACE"
    np.testing.assert_allclose(item.location, point, atol=1e-12)


def test_bad_input_is_refused_and_changes_nothing(plane):
    target, layout, normal, view = plane
    tool = addon_module("blender.pair_tool")
    errors = addon_module("core.errors")
    world = world_positions(layout)
    tool.place_pair(bpy.context, layout, 10, world[10] - 0.3 * normal)
    before = anchors_state(layout)
    assert tool.target_under_mouse(bpy.context, layout, view, (2.0, 2.0)) is None  # off the target
    with pytest.raises(errors.LayoutError, match="out of range"):
        tool.place_pair(bpy.context, layout, 10_000, world[10])
    with pytest.raises(errors.LayoutError, match="NaN or infinite"):
        tool.place_pair(bpy.context, layout, 10, (np.nan, 0.0, 0.0))
    target.hide_set(True)
    with pytest.raises(errors.LayoutError, match="hidden"):
        tool.target_under_mouse(bpy.context, layout, view, pixel_of(view, world[10]))
    target.hide_set(False)
    empty = bpy.data.objects.new("Empty Target", bpy.data.meshes.new("Empty Target"))
    bpy.context.scene.collection.objects.link(empty)
    layout.springwrap.target = empty
    with pytest.raises(errors.LayoutError, match="no faces"):
        tool.target_under_mouse(bpy.context, layout, view, pixel_of(view, world[10]))
    with pytest.raises(errors.LayoutError, match="no faces"):
        tool.place_pair(bpy.context, layout, 10, world[10])
    layout.springwrap.target = None
    with pytest.raises(errors.LayoutError, match="no target"):
        tool.target_under_mouse(bpy.context, layout, view, pixel_of(view, world[10]))
    with pytest.raises(errors.LayoutError, match="no target"):
        tool.place_pair(bpy.context, layout, 10, world[10])
    assert anchors_state(layout) == before


def test_symmetric_pairs_are_made_moved_and_removed_with_their_twins():
    target, layout, twins = symmetric_head_scene()
    activate(layout)
    tool = addon_module("blender.pair_tool")
    layout.springwrap.anchor_symmetric = True
    world = world_positions(layout)
    point, normal = world_plane()
    side = (world - point) @ normal
    vertex = int(np.argmax(side))  # well off the plane
    location = world[vertex] * 0.97 + np.array(target.matrix_world.translation) * 0.03
    tool.place_pair(bpy.context, layout, vertex, location)
    items = layout.springwrap.anchors
    assert sorted(item.vertex_index for item in items) == sorted([vertex, int(twins[vertex])])

    def ends():
        own = next(np.array(item.location) for item in items if item.vertex_index == vertex)
        twin = next(np.array(item.location) for item in items if item.vertex_index == twins[vertex])
        return own, twin - (own - 2.0 * ((own - point) @ normal) * normal)  # the twin's end, off the reflection

    own, off = ends()
    assert np.linalg.norm(off) < 0.05
    moved = location + 0.1 * np.cross(normal, [0.0, 0.0, 1.0])
    tool.place_pair(bpy.context, layout, vertex, moved)  # the target end dragged: the twin follows
    own_after, off_after = ends()
    assert np.linalg.norm(own_after - own) > 0.05 and np.linalg.norm(off_after) < 0.05
    assert len(items) == 2
    tool.remove_pair(layout, 0)
    assert len(layout.springwrap.anchors) == 0


def test_live_re_settle_is_kept_by_finish_and_put_back_bit_for_bit_by_cancel(plane):
    target, layout, normal, view = plane
    tool = addon_module("blender.pair_tool")
    world = world_positions(layout)
    tool.place_pair(bpy.context, layout, 40, world[40] - 0.3 * normal)
    before = snapshot(layout)
    anchors_before = anchors_state(layout)
    session = tool.start_settle(bpy.context, layout)
    tool.advance_settle(session)
    assert session.pacer.max_solve_seconds > tool.LIVE_FIRST_FRAME_SECONDS  # only the first frame is shortened
    while session.frames < 2:  # the later frames write what the worker thread solved
        tool.advance_settle(session)
        time.sleep(0.002)
    assert snapshot(layout) != before
    session.cancel()
    assert snapshot(layout) == before and anchors_state(layout) == anchors_before
    session = tool.start_settle(bpy.context, layout)
    session.run()
    session.finish()
    after = world_positions(layout)
    assert np.abs((after - np.array(target.matrix_world.translation)) @ normal).max() < 1e-3  # on the plane
    # Warm start: a second re-settle from the settled layout has nothing left to do.
    again = tool.start_settle(bpy.context, layout)
    again.run()
    assert again.total_iterations < session.total_iterations


def test_the_operator_says_it_needs_a_3d_view_in_background(plane):
    for how in ("INVOKE_DEFAULT", "EXEC_DEFAULT"):
        with pytest.raises(RuntimeError, match="works in a 3D view"):
            bpy.ops.springwrap.pair_tool(how)
