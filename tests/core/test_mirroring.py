"""Mirroring's bpy-free logic (``addon/springwrap/core/mirroring.py``): planes, the seam, crossing faces, the state.

Plain numpy on generated geometry, no Blender: the add-on package is imported from ``addon/``
without running its ``__init__`` (which needs ``bpy``).
"""

import types

import numpy as np
import pytest

from helpers import core_module

layout_state = core_module("layout_state")
mirroring = core_module("mirroring")


def grid(columns=4, rows=3, spacing=0.1):
    """A flat quad grid in z = 0 from x = 0 to (columns - 1) * spacing: (positions, corners, sizes, edges)."""
    xs, ys = np.meshgrid(np.arange(columns) * spacing, np.arange(rows) * spacing)
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    corners = []
    for row in range(rows - 1):
        for column in range(columns - 1):
            a = row * columns + column
            corners += [a, a + 1, a + columns + 1, a + columns]
    corners = np.array(corners)
    sizes = np.full(len(corners) // 4, 4)
    edges = mirroring._face_edges(corners, sizes)
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    return positions, corners, sizes, edges


def test_planes_of_an_object_are_its_local_planes_in_world_space():
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z
    matrix = np.eye(4)
    matrix[:3, :3] = turn @ np.diag([2.0, 3.0, 1.0])  # non-uniform scale: the plane's normal is still the X axis
    matrix[:3, 3] = [1.0, 2.0, 3.0]
    plane = mirroring.plane_from_matrix(matrix, "X")
    assert np.allclose(plane.point, [1.0, 2.0, 3.0]) and np.allclose(plane.normal, [0.0, 1.0, 0.0])
    point = np.array([[4.0, 7.0, -1.0]])
    assert np.allclose(mirroring.reflect(point, plane), [[4.0, -3.0, -1.0]])
    assert np.allclose(mirroring.project(point, plane), [[4.0, 2.0, -1.0]])
    assert np.allclose(mirroring.signed_distances(point, plane), [5.0])
    with pytest.raises(layout_state.LayoutError, match="axis"):
        mirroring.plane_from_matrix(matrix, "W")
    with pytest.raises(layout_state.LayoutError, match="zero scale"):
        mirroring.plane_from_matrix(np.diag([0.0, 1.0, 1.0, 1.0]), "X")


def test_the_seam_uses_each_vertex_own_edge_length():
    positions, corners, sizes, edges = grid()
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    positions[0, 0] = 0.009  # within 0.1 x 0.1
    positions[4, 0] = 0.011  # beyond
    decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
    assert np.flatnonzero(decided.seam).tolist() == [0, 8]
    assert decided.crossing_faces.size == 0 and decided.duplicate_faces.all()


def test_faces_across_the_plane_are_crossing_and_a_missing_plane_is_refused():
    positions, corners, sizes, edges = grid()
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    positions[4, 0] = -0.05  # a midline vertex pulled across: the faces of it reach both sides
    decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
    assert sorted(decided.crossing_faces.tolist()) == [0, 3]
    far = mirroring.Plane(np.array([5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    with pytest.raises(layout_state.LayoutError, match="misses the grid.*all on one side"):
        mirroring.plan(positions, corners, sizes, edges, far, 0.1, layout_name="the grid")
    with pytest.raises(layout_state.LayoutError, match="positive"):
        mirroring.plan(positions, corners, sizes, edges, plane, 0.0)


def test_faces_in_the_plane_and_loose_edges():
    positions, corners, sizes, edges = grid()
    plane = mirroring.Plane(np.zeros(3), np.array([0.0, 0.0, 1.0]))  # the grid lies in it
    decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
    assert decided.seam.all() and decided.in_plane_faces == len(sizes) and not decided.duplicate_faces.any()
    loose = np.vstack([edges, [[3, 12]]])
    positions = np.vstack([positions, [[0.5, 0.0, 0.0]]])
    decided = mirroring.plan(positions, corners, sizes, loose, mirroring.Plane(np.zeros(3), np.array([1.0, 0, 0])))
    assert decided.duplicate_edges.tolist() == [False] * len(edges) + [True]


def test_the_mirrored_state_copies_are_space_points_and_the_seam_is_on_the_plane():
    positions, *_ = grid(columns=3, rows=2)
    positions[0, 0] = 0.004  # a seam vertex slightly off the plane
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    state = layout_state.LayoutState(
        np.ones(6, dtype=np.int32), np.arange(6, dtype=np.int32), np.full((6, 3), 1 / 3, dtype=np.float32)
    )
    seam = np.abs(positions[:, 0]) < 0.01
    source = np.concatenate([np.arange(6), np.flatnonzero(~seam)])
    result = mirroring.mirrored_layout(
        positions, state, positions * 2.0, source, seam, plane, keep_seam_face_points=False, on_plane_tolerance=1e-6
    )
    assert np.allclose(result.positions[6:], positions[~seam] * [-1.0, 1.0, 1.0])
    assert np.allclose(result.positions[seam.nonzero()[0], 0], 0.0)
    assert np.allclose(result.rest[6:], positions[~seam] * [-2.0, 2.0, 2.0])
    assert result.state.states.tolist() == [0, 1, 1, 1, 1, 1] + [0] * 4  # vertex 0 moved onto the plane: detached
    kept = mirroring.mirrored_layout(
        positions, state, positions, source, seam, plane, keep_seam_face_points=True, on_plane_tolerance=1e-6
    )
    assert kept.state.states[:6].tolist() == [1] * 6
    with pytest.raises(layout_state.LayoutError, match="seam vertex was copied"):
        mirroring.mirrored_layout(positions, state, positions, np.arange(7) % 6, seam, plane, True, 1e-6)


def test_pins_replace_anchors_on_the_surfaced_half():
    operations_inputs = types.SimpleNamespace
    inputs = operations_inputs(
        states=np.array([1, 0, 1, 0], dtype=np.int32),
        triangles=np.array([5, -1, 7, -1], dtype=np.int32),
        barycentrics=np.full((4, 3), 0.25, dtype=np.float32),
        positions=np.arange(12, dtype=np.float32).reshape(4, 3),
        anchor_vertices=np.array([0, 3], dtype=np.uint32),
        anchor_triangles=np.array([9, -1], dtype=np.int32),
        anchor_barycentrics=np.zeros((2, 3), dtype=np.float32),
        anchor_positions=np.ones((2, 3), dtype=np.float32),
        origin=np.array([1.0, 2.0, 3.0]),  # the kernel's frame: world minus the target's centre
    )
    inputs._replace = lambda **changes: types.SimpleNamespace(**(vars(inputs) | changes))
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    held = mirroring.hold_inputs(inputs, np.array([True, True, False, False]), np.array([2]), plane, slide=False)
    assert held.anchor_vertices.tolist() == [3, 0, 1]  # the user anchor on 0 replaced by its pin
    assert held.anchor_triangles.tolist() == [-1, 5, -1]
    assert np.array_equal(held.anchor_positions[1:], inputs.positions[:2])
    assert held.plane_vertices.tolist() == [2] and held.plane_slide is False
    assert held.plane_point == (-1.0, -2.0, -3.0)  # the world plane through the origin, in the kernel's frame


def test_held_on_plane_holds_the_midline_and_leaves_its_anchors_out():
    positions = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2e-3, 2, 0]], dtype=np.float64)
    edges = np.array([[0, 1], [0, 2], [1, 3], [2, 3], [2, 4]])
    inputs = types.SimpleNamespace(
        anchor_vertices=np.array([0, 3, 4], dtype=np.uint32),
        anchor_triangles=np.array([9, -1, 2], dtype=np.int32),
        anchor_barycentrics=np.zeros((3, 3), dtype=np.float32),
        anchor_positions=np.ones((3, 3), dtype=np.float32),
        origin=np.zeros(3),
    )
    inputs._replace = lambda **changes: _namespace_with_replace(vars(inputs) | changes)
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    held = mirroring.held_on_plane(inputs, positions, edges, plane)
    # Vertices 0 and 2 on x = 0; 4 is 2e-3 off, within a tenth of its edge (1.0): on it too.
    assert held.plane_vertices.tolist() == [0, 2, 4] and held.plane_slide is True
    assert held.plane_normal == (1.0, 0.0, 0.0)
    assert held.anchor_vertices.tolist() == [3] and held.anchor_triangles.tolist() == [-1]
    with pytest.raises(layout_state.LayoutError, match="No layout vertex lies on the hold plane"):
        mirroring.held_on_plane(inputs, positions + [5.0, 0.0, 0.0], edges, plane)


def _namespace_with_replace(values):
    namespace = types.SimpleNamespace(**values)
    namespace._replace = lambda **changes: _namespace_with_replace(vars(namespace) | changes)
    return namespace
