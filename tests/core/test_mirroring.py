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
mirror_seam = core_module("mirror_seam")


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
    edges = mirror_seam.face_edges(corners, sizes)
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
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    for offset, on_seam in ((0.009, True), (0.013, False)):  # vertex 5 (inside the grid): 0.1 x its edges' ~0.117
        positions, corners, sizes, edges = grid()
        positions[5, 0] = offset
        decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
        assert bool(decided.seam[5]) == on_seam
        assert decided.seam[[0, 4, 8]].all() and not decided.drifted[[0, 4, 8]].any()


def test_an_open_border_a_wrap_moved_off_the_plane_is_still_the_seam():
    """A half's open border at the plane is its seam wherever a wrap left it (within 2.5 of its edge lengths, to
    either side); the faces beside it do not cross the plane, the border rows running away from it are no seam."""
    positions, corners, sizes, edges = grid(columns=5, rows=6)
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    border_column = np.arange(6) * 5
    positions[border_column, 0] = [0.0, 0.03, 0.06, 0.04, -0.02, -0.05]
    decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
    assert np.flatnonzero(decided.seam).tolist() == border_column.tolist()
    assert np.flatnonzero(decided.drifted).tolist() == border_column[1:].tolist()
    assert decided.crossing_faces.size == 0 and decided.duplicate_faces.all()


def test_a_border_drifted_too_far_from_the_plane_is_refused_with_what_to_do():
    positions, corners, sizes, edges = grid(columns=5, rows=6)
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    positions[15:, 0] += 0.35  # the border's upper half pushed 3.5 edge lengths off the plane with its rows
    with pytest.raises(layout_state.LayoutError, match="drifted too far.*Hold on Plane Y"):
        mirroring.plan(positions, corners, sizes, edges, plane, 0.1, layout_name="the grid", axis="Y")


def test_a_layout_on_both_sides_of_the_plane_is_refused_with_what_to_do():
    positions, corners, sizes, edges = grid(columns=11, rows=3)
    positions[:, 0] -= 0.5  # x from -0.5 to 0.5: both halves are there
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    with pytest.raises(layout_state.LayoutError, match="already covers both sides.*9 vertices.*Delete the other half"):
        mirroring.plan(positions, corners, sizes, edges, plane, 0.1, layout_name="the grid")


def test_faces_across_the_plane_are_crossing_and_a_missing_plane_is_refused():
    positions, corners, sizes, edges = grid()
    plane = mirroring.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    positions[5, 0] = -0.05  # a vertex next to the midline pulled across: its faces reach both sides
    decided = mirroring.plan(positions, corners, sizes, edges, plane, 0.1)
    assert sorted(decided.crossing_faces.tolist()) == [0, 1, 3, 4]
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


def test_the_midline_plane_is_the_one_a_half_s_open_border_lies_on_and_not_a_sheet_s_own():
    seam = core_module("mirror_seam")
    positions, corners, sizes, edges = grid(columns=5, rows=6)
    positions[:, 2] = 0.3 * positions[:, 0] ** 2  # bent away from the plane x = 0 along which its border runs
    positions[[4, 9, 14, 19, 24, 29], 2] += 0.05  # the far column bent too: the border is not all on a plane
    open_edges = seam.border_edges(seam.face_edges(corners, sizes))
    planes = [(axis, mirroring.plane_from_matrix(np.eye(4), axis)) for axis in mirroring.AXES]
    found = seam.midline_plane(positions, open_edges, edges, planes, 0.1)
    assert found is None  # the column x = 0 is less than half of the open border
    # A half whose only open border is its midline (the other sides closed by the rest of the half).
    open_column = open_edges[(positions[open_edges][:, :, 0] == 0.0).all(axis=1)]
    axis, _plane, vertices = seam.midline_plane(positions, open_column, edges, planes, 0.1)
    assert axis == "X" and sorted(vertices.tolist()) == [0, 5, 10, 15, 20, 25]
    flat = positions.copy()
    flat[:, 2] = 0.0  # a flat sheet in the plane z = 0: its border lies in that plane, but so does everything
    assert seam.midline_plane(flat, open_edges, edges, planes, 0.1) is None
