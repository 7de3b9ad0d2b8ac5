"""Plain tests of the pair tool's bpy-free logic, no Blender: screen-space picking (``core/pair_pick.py``) on a
camera built here, and the in-place pair edits (``core/pair_edits.py``) on small kernel targets."""

import sys

import numpy as np
import pytest

from helpers import core_module, grid_triangles

pp = core_module("pair_pick")
pe = core_module("pair_edits")
an = sys.modules[pp.__name__.rpartition(".")[0] + ".anchors"]
tg = sys.modules[pp.__name__.rpartition(".")[0] + ".target"]
sy = sys.modules[pp.__name__.rpartition(".")[0] + ".symmetry"]
mi = sys.modules[pp.__name__.rpartition(".")[0] + ".mirroring"]
er = sys.modules[pp.__name__.rpartition(".")[0] + ".errors"]

WIDTH, HEIGHT = 800, 600


def camera(eye=(0.0, 0.0, 10.0), perspective=True):
    """A view looking down -z from ``eye`` (OpenGL conventions, as Blender's ``perspective_matrix``)."""
    view = np.eye(4)
    view[:3, 3] = -np.asarray(eye, dtype=np.float64)
    near, far, aspect = 0.1, 100.0, WIDTH / HEIGHT
    projection = np.zeros((4, 4))
    if perspective:
        focal = 1.0 / np.tan(np.radians(30.0))
        projection[0, 0], projection[1, 1] = focal / aspect, focal
        projection[2, 2], projection[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
        projection[3, 2] = -1.0
    else:
        scale = 0.2
        projection[0, 0], projection[1, 1] = scale / aspect, scale
        projection[2, 2], projection[2, 3] = -2.0 / (far - near), -(far + near) / (far - near)
        projection[3, 3] = 1.0
    return pp.make_view(projection @ view, WIDTH, HEIGHT)


def grid_mesh(size=4.0, cells=8, height=0.0):
    coordinates = np.linspace(-size / 2, size / 2, cells + 1)
    x, y = np.meshgrid(coordinates, coordinates, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.full(x.size, height)], axis=1)
    return vertices, grid_triangles(cells)


@pytest.mark.parametrize("perspective", [True, False], ids=["perspective", "orthographic"])
def test_a_projected_point_lies_on_the_ray_under_its_pixel(perspective):
    view = camera(perspective=perspective)
    points = np.array([[0.3, -0.7, 1.0], [1.5, 1.0, -2.0]])
    pixels, in_front = pp.project(view, points)
    assert in_front.all()
    for point, pixel in zip(points, pixels):
        origin, direction = pp.mouse_ray(view, pixel)
        offset = point - origin
        assert np.linalg.norm(offset - (offset @ direction) * direction) < 1e-9


def test_points_behind_the_view_are_never_picked():
    view = camera()
    pixels, in_front = pp.project(view, [[0.0, 0.0, 20.0]])
    assert not in_front[0] and np.isnan(pixels).all()
    assert pp.pick_vertex(view, [[0.0, 0.0, 20.0]], (WIDTH / 2, HEIGHT / 2)) == -1


def test_the_vertex_nearest_on_the_screen_wins_not_the_nearest_in_3d():
    view = camera()
    # A vertex near the eye and a little to the side, and one far away exactly under the mouse.
    near_side = [0.05, 0.0, 9.0]
    far_under = [0.0, 0.0, -30.0]
    mouse = pp.project(view, [far_under])[0][0]
    origin, _direction = pp.mouse_ray(view, mouse)
    assert np.linalg.norm(np.subtract(near_side, origin)) < np.linalg.norm(np.subtract(far_under, origin))
    assert pp.pick_vertex(view, [near_side, far_under], mouse, radius=50.0) == 1


def test_nothing_is_picked_outside_the_pixel_radius():
    view = camera()
    pixel = pp.project(view, [[0.0, 0.0, 0.0]])[0][0]
    assert pp.pick_vertex(view, [[0.0, 0.0, 0.0]], pixel + [11.0, 0.0], radius=12.0) == 0
    assert pp.pick_vertex(view, [[0.0, 0.0, 0.0]], pixel + [13.0, 0.0], radius=12.0) == -1


def test_a_vertex_behind_the_layouts_own_surface_is_not_picked():
    view = camera()
    vertices, triangles = grid_mesh(height=1.0)  # a sheet between the eye and a vertex under it
    sheet = tg.CentredMesh(vertices, triangles)
    hidden = [0.01, 0.01, -1.0]
    shown = [0.0, 0.0, 1.0]  # a vertex of the sheet itself
    mouse = pp.project(view, [hidden])[0][0]
    assert pp.pick_vertex(view, [hidden], mouse, occluder=None) == 0
    assert pp.pick_vertex(view, [hidden], mouse, occluder=sheet, tolerance=1e-3) == -1
    assert pp.pick_vertex(view, [hidden, shown], mouse, occluder=sheet, tolerance=1e-3) == 1


def test_pick_end_tells_the_layout_end_from_the_target_end():
    view = camera()
    starts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    ends = np.array([[0.0, 1.0, 0.0], [np.nan, np.nan, np.nan]])
    at = pp.project(view, np.concatenate([starts, ends[:1]]))[0]
    assert pp.pick_end(view, starts, ends, at[0]) == (0, pp.LAYOUT_END)
    assert pp.pick_end(view, starts, ends, at[1]) == (1, pp.LAYOUT_END)
    assert pp.pick_end(view, starts, ends, at[2]) == (0, pp.TARGET_END)
    assert pp.pick_end(view, starts, ends, (1.0, 1.0)) == (-1, "")


def test_a_point_at_depth_is_on_the_mouse_ray_and_in_the_references_view_plane():
    view = camera()
    reference = np.array([0.4, 0.2, -3.0])
    origin, direction = pp.mouse_ray(view, (100.0, 450.0))
    point = pp.point_at_depth(origin, direction, reference, pp.view_forward(view))
    forward = pp.view_forward(view)
    assert abs((point - reference) @ forward) < 1e-9
    offset = point - origin
    assert np.linalg.norm(offset - (offset @ direction) * direction) < 1e-9


def test_fan_triangles_cut_each_polygon_from_its_first_corner():
    triangles = pp.fan_triangles([0, 1, 2, 3, 4, 5, 6, 7, 8, 9], [4, 3, 1, 2])
    assert triangles.tolist() == [[0, 1, 2], [0, 2, 3], [4, 5, 6]]


def test_a_bad_view_matrix_is_refused():
    with pytest.raises(ValueError, match="perspective matrix"):
        pp.make_view(np.zeros((4, 4)), WIDTH, HEIGHT)
    with pytest.raises(ValueError, match="perspective matrix"):
        pp.make_view(np.full((4, 4), np.nan), WIDTH, HEIGHT)


# ---------------------------------------------------------------- edits


def flat_target():
    vertices, triangles = grid_mesh(size=4.0, cells=8, height=0.0)
    return tg.make_target("Target", vertices, triangles)


def test_placing_a_pair_on_an_anchored_vertex_replaces_it_in_place():
    target = flat_target()
    anchors = an.no_anchors()
    for vertex, x in ((3, -1.0), (7, 0.0), (9, 1.0)):
        anchors = pe.place(20, anchors, target, "", vertex, (x, 0.5, 0.0))[0].anchors
    outcome, report = pe.place(20, anchors, target, "", 7, (0.25, -1.25, 0.0))
    assert report is None
    assert outcome.anchors.vertex_indices.tolist() == [3, 7, 9]
    assert outcome.active_index == 1
    assert outcome.anchors.kinds[1] == an.FACE_ANCHOR
    np.testing.assert_allclose(outcome.anchors.locations[1], [0.25, -1.25, 0.0], atol=1e-6)
    assert outcome.anchors.triangles[1] >= 0


def test_a_ray_hit_becomes_a_face_anchor_exactly_on_the_surface():
    target = flat_target()
    hit = target.mesh.ray_cast(np.array([[0.3, 0.7, 5.0]]), np.array([[0.0, 0.0, -1.0]]))
    location = np.asarray(hit.positions)[0]
    anchors = pe.place(4, an.no_anchors(), target, "", 2, location)[0].anchors
    surface = target.mesh.face_point_positions(anchors.triangles.astype(np.uint32), anchors.barycentrics)
    np.testing.assert_allclose(surface[0], location, atol=1e-6)
    np.testing.assert_allclose(anchors.locations[0], surface[0], atol=1e-12)


def test_a_space_pair_keeps_its_point():
    target = flat_target()
    anchors = pe.place(4, an.no_anchors(), target, "", 1, (0.2, 0.3, 0.9), on_surface=False)[0].anchors
    assert anchors.kinds[0] == an.SPACE_ANCHOR
    np.testing.assert_array_equal(anchors.locations[0], [0.2, 0.3, 0.9])


def test_repick_moves_the_layout_end_and_keeps_the_target_and_the_number():
    target = flat_target()
    anchors = an.no_anchors()
    for vertex, x in ((3, -1.0), (7, 0.0), (9, 1.0)):
        anchors = pe.place(20, anchors, target, "", vertex, (x, 0.5, 0.0))[0].anchors
    outcome, _report = pe.repick(20, anchors, target, "", 0, 12)
    assert outcome.anchors.vertex_indices.tolist() == [12, 7, 9]
    np.testing.assert_allclose(outcome.anchors.locations[0], anchors.locations[0], atol=1e-9)
    # Onto a vertex that has a pair: that pair is replaced, the moved one keeps its number.
    outcome, _report = pe.repick(20, anchors, target, "", 0, 9)
    assert outcome.anchors.vertex_indices.tolist() == [9, 7]
    with pytest.raises(er.LayoutError, match="out of range"):
        pe.repick(20, anchors, target, "", 0, 20)
    with pytest.raises(er.LayoutError, match="no anchor 5"):
        pe.repick(20, anchors, target, "", 5, 1)


def test_remove_makes_the_next_pair_active():
    target = flat_target()
    anchors = an.no_anchors()
    for vertex in (3, 7, 9):
        anchors = pe.place(20, anchors, target, "", vertex, (0.0, 0.0, 0.0))[0].anchors
    outcome = pe.remove(anchors, 1)
    assert outcome.anchors.vertex_indices.tolist() == [3, 9] and outcome.active_index == 1
    assert pe.remove(pe.remove(outcome.anchors, 0).anchors, 0).active_index == -1


def symmetric_case():
    """A layout grid symmetric across x = 0 over a flat target, its twins and plane."""
    vertices, triangles = grid_mesh(size=2.0, cells=4, height=0.5)
    sizes = np.full(triangles.shape[0], 3, dtype=np.uint32)
    plane = mi.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    edges = np.unique(
        np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), 1), axis=0
    )
    twins = sy.vertex_twins(vertices, triangles.reshape(-1), sizes, edges.astype(np.uint32), plane)
    return vertices, twins, plane


def test_symmetric_place_and_repick_move_the_twin_with_the_pair():
    target = flat_target()
    vertices, twins, plane = symmetric_case()
    count = vertices.shape[0]
    vertex = 1  # x = -1
    twin = int(twins.twins[vertex])
    assert twin != vertex and vertices[twin][0] == pytest.approx(1.0)
    outcome, report = pe.place(count, an.no_anchors(), target, "", vertex, (-0.8, 0.3, 0.0), True, (twins, plane))
    assert report.paired_count == 1
    assert sorted(outcome.anchors.vertex_indices.tolist()) == sorted([vertex, twin])
    mirrored = outcome.anchors.locations[pe.anchor_of(outcome.anchors, twin)]
    np.testing.assert_allclose(mirrored, [0.8, 0.3, 0.0], atol=1e-6)
    # Dragging the target end moves the twin's end too.
    moved, _ = pe.place(count, outcome.anchors, target, "", vertex, (-0.5, -0.2, 0.0), True, (twins, plane))
    assert moved.anchors.vertex_indices.tolist() == outcome.anchors.vertex_indices.tolist()
    np.testing.assert_allclose(moved.anchors.locations[pe.anchor_of(moved.anchors, twin)], [0.5, -0.2, 0.0], atol=1e-6)
    # Re-picking the layout end takes the twin to the new vertex's twin, in place.
    new_vertex = 6
    repicked, _ = pe.repick(count, moved.anchors, target, "", 0, new_vertex, (twins, plane))
    assert repicked.anchors.vertex_indices.tolist() == [new_vertex, int(twins.twins[new_vertex])]
    assert pe.remove(repicked.anchors, 0, symmetric=True).anchors.vertex_indices.size == 0


def test_dragging_a_proposed_pair_accepts_it():
    target = flat_target()
    anchors = an.no_anchors()
    for vertex, x in ((3, -1.0), (7, 0.0), (9, 1.0)):
        anchors = pe.place(20, anchors, target, "", vertex, (x, 0.5, 0.0))[0].anchors
    anchors = anchors._replace(
        proposed=np.array([False, True, True]), confidences=np.array([0.0, 0.7, 0.6], np.float32)
    )
    moved, _report = pe.place(20, anchors, target, "", 7, (0.25, -1.25, 0.0))  # its target end dragged
    assert moved.anchors.proposed.tolist() == [False, False, True]
    repicked, _report = pe.repick(20, anchors, target, "", 2, 12)  # its layout end dragged
    assert repicked.anchors.vertex_indices.tolist() == [3, 7, 12]
    assert repicked.anchors.proposed.tolist() == [False, True, False]
