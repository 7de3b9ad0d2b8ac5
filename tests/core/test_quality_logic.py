"""The quality read-out on arrays (``addon/springwrap/core/quality.py``): distance, stretch and flips on known
shapes, the selection rule, the report's numbers and the batch's outlier rule. No Blender."""

import numpy as np
import pytest

from helpers import core_module, grid, quad_layout

quality = core_module("quality")
target_module = core_module("target")
subdivision = core_module("subdivision")
layout_state = core_module("layout_state")
transforms = core_module("transforms")


def plane_mesh(size=8, offset=(0.0, 0.0, 0.0)):
    """A flat target in z = offset[2], from offset to offset + size in x and y (a CentredMesh)."""
    vertices, triangles = grid(size)
    return target_module.CentredMesh(vertices.astype(np.float64) + np.asarray(offset), triangles)


def layout_over(mesh_offset=(0.0, 0.0, 0.0), height=0.3, n=6):
    """An n x n quad grid over the middle of :func:`plane_mesh`, ``height`` above it: positions and topology."""
    positions, corners, sizes = quad_layout(n=n, size=0.5, height=height)
    positions = positions.astype(np.float64) + np.array([4.0, 4.0, 0.0]) + np.asarray(mesh_offset)
    quads = corners.reshape(-1, 4).astype(np.int64)
    edges = np.unique(
        np.sort(np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]]), axis=1),
        axis=0,
    )
    topology = subdivision.LayoutTopology(
        positions.shape[0], corners, sizes, edges.astype(np.uint32), np.zeros((0, 2), np.uint32)
    )
    return positions, topology


@pytest.mark.parametrize("height", [0.0, 0.3, 1.75])
def test_a_plane_layout_at_height_h_over_a_plane_target_is_h_away(height):
    positions, topology = layout_over(height=height)
    readout = quality.measure(positions, positions, topology, plane_mesh())
    assert np.allclose(readout.distances, height, atol=1e-6)


def test_distances_are_world_units_far_from_the_origin():
    offset = (3.0e5, -2.0e5, 1.0e5)
    positions, topology = layout_over(mesh_offset=offset, height=0.3)
    readout = quality.measure(positions, positions, topology, plane_mesh(offset=offset))
    assert np.allclose(readout.distances, 0.3, atol=1e-6)


def test_a_layout_scaled_by_two_has_stretch_two_and_unchanged_reads_one():
    positions, topology = layout_over()
    centre = positions.mean(axis=0)
    doubled = centre + 2.0 * (positions - centre)
    assert np.allclose(quality.measure(doubled, positions, topology, plane_mesh()).stretch, 2.0)
    assert np.allclose(quality.measure(positions, positions, topology, plane_mesh()).stretch, 1.0)
    halved = centre + 0.5 * (positions - centre)
    assert np.allclose(quality.measure(halved, positions, topology, plane_mesh()).stretch, 0.5)


def test_stretch_is_local_one_edge_pulled_long():
    positions, topology = layout_over(n=4)
    moved = positions.copy()
    moved[12] += np.array([0.0, 0.0, 1.0])  # an inner vertex lifted: its edges and its neighbours' grow
    stretch = quality.vertex_stretch(moved, positions, topology.edges)
    assert stretch[12] == pytest.approx(np.hypot(0.5, 1.0) / 0.5)
    far = [0, 4, 20, 24]  # corners, no edge to vertex 12
    assert np.allclose(stretch[far], 1.0)


def test_without_a_rest_shape_or_with_collapsed_rest_edges_stretch_reads_one_and_no_nan():
    positions, topology = layout_over(n=3)
    readout = quality.measure(positions * 3.0, None, topology, plane_mesh())
    assert np.array_equal(readout.stretch, np.ones(positions.shape[0]))
    collapsed = np.repeat(positions[:1], positions.shape[0], axis=0)  # every rest edge of length 0
    stretch = quality.vertex_stretch(positions, collapsed, topology.edges)
    assert np.array_equal(stretch, np.ones(positions.shape[0]))
    assert quality.world_rest_or_none(np.eye(4), positions[:-1], positions.shape[0]) is None


def test_unchanged_or_reversed_everywhere_is_not_flipped():
    positions, topology = layout_over(n=4)
    assert not quality.measure(positions, positions, topology, plane_mesh()).flipped.any()
    reversed_faces = topology._replace(face_corners=topology.face_corners.reshape(-1, 4)[:, ::-1].reshape(-1))
    assert not quality.measure(positions, positions, reversed_faces, plane_mesh()).flipped.any()  # rest reversed too


def test_a_fold_flips_the_faces_it_turns_over():
    positions, topology = layout_over(n=4)
    folded = positions.copy()
    folded[6] = positions[18] + [0.2, 0.2, 0.0]  # an inner vertex dragged over its neighbours
    flipped = quality.measure(folded, positions, topology, plane_mesh()).flipped
    normals = quality.face_normals(folded, topology.face_corners, topology.face_sizes)
    assert flipped.any()
    assert np.array_equal(flipped, normals[:, 2] < 0.0)  # the faces that now face down, and only they


@pytest.mark.parametrize("angle", [90.0, 180.0])
def test_a_rigid_turn_of_the_whole_layout_is_not_flipped(angle):
    positions, topology = layout_over(n=4)
    theta = np.radians(angle)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(theta), -np.sin(theta)], [0.0, np.sin(theta), np.cos(theta)]])
    turned = (positions - positions.mean(axis=0)) @ turn.T + positions.mean(axis=0)
    assert not quality.measure(turned, positions, topology, plane_mesh()).flipped.any()


def test_a_bent_layout_is_not_flipped_a_limb_posed_by_120_degrees():
    positions, topology = layout_over(n=8)
    x0 = positions[:, 0].mean()
    bent = positions.copy()
    beyond = positions[:, 0] > x0  # the half beyond x0 turned 120 degrees about the line x = x0 (a hinge)
    theta = np.radians(120.0)
    offset = positions[beyond] - [x0, 0.0, positions[0, 2]]
    bent[beyond, 0] = x0 + offset[:, 0] * np.cos(theta) - offset[:, 2] * np.sin(theta)
    bent[beyond, 2] = positions[0, 2] + offset[:, 0] * np.sin(theta) + offset[:, 2] * np.cos(theta)
    normals = quality.face_normals(bent, topology.face_corners, topology.face_sizes)
    assert (normals[:, 2] < 0.0).any()  # against the layout's rest normal (+z), some faces face away now
    assert not quality.measure(bent, positions, topology, plane_mesh()).flipped.any()


def test_degenerate_faces_are_not_flipped_and_give_no_nan():
    positions, topology = layout_over(n=3)
    collapsed = positions.copy()
    collapsed[topology.face_corners[:4]] = collapsed[topology.face_corners[0]]  # face 0 to a point
    readout = quality.measure(collapsed, positions, topology, plane_mesh())
    assert not readout.flipped[0]
    assert np.isfinite(readout.distances).all() and np.isfinite(readout.stretch).all()
    normals = quality.face_normals(collapsed, topology.face_corners, topology.face_sizes)
    assert np.array_equal(normals[0], [0.0, 0.0, 0.0])


def test_newell_normals_of_triangles_and_ngons():
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 1.5, 0], [2, 0, 0], [2, 1, 0]], float)
    corners = np.array([0, 1, 2, 4, 3, 1, 5, 6])  # a pentagon (area 1.25), a triangle (area 0.5)
    normals = quality.face_normals(points, corners, np.array([5, 3]))
    assert np.allclose(normals, [[0, 0, 2.5], [0, 0, 1.0]])


def test_problem_masks():
    stretch = np.array([1.0, 1.6, 0.6, 1.2, 0.7])
    assert quality.problem_mask("STRETCHED", stretch, 0.0, 1.0).tolist() == [False, True, True, False, False]
    assert quality.problem_mask("STRETCHED", stretch, 1.25, 1.0).tolist() == [False, True, True, False, True]
    assert quality.problem_mask("STRETCHED", stretch, 0.8, 1.0).tolist() == [False, True, True, False, True]
    distances = np.array([0.0, 0.0005, 0.002, 0.3])
    assert quality.problem_mask("OFF_SURFACE", distances, 0.0, 1.0).tolist() == [False, False, True, True]
    assert quality.problem_mask("OFF_SURFACE", distances, 0.1, 1.0).tolist() == [False, False, False, True]
    assert quality.problem_mask("FLIPPED", np.array([0, 1, 0], bool), 0.0, 1.0).tolist() == [False, True, False]
    with pytest.raises(ValueError, match="unknown problem kind"):
        quality.problem_mask("BAD", distances, 0.0, 1.0)


def test_summary_numbers():
    readout = quality.Readout(
        distances=np.arange(101, dtype=float) / 100.0,
        stretch=np.linspace(0.5, 1.5, 101),
        flipped=np.array([True, False, True]),
        diagonal=100.0,
    )
    numbers = quality.summary(readout)
    assert numbers["distance_mean"] == pytest.approx(0.5)
    assert numbers["distance_p50"] == pytest.approx(0.5) and numbers["distance_p95"] == pytest.approx(0.95)
    assert numbers["distance_max"] == pytest.approx(1.0)
    assert numbers["stretch_p5"] == pytest.approx(0.55) and numbers["stretch_p95"] == pytest.approx(1.45)
    assert numbers["stretch_p50"] == pytest.approx(1.0) and numbers["stretch_max"] == pytest.approx(1.5)
    assert numbers["flipped"] == 2
    assert numbers["off_surface_threshold"] == pytest.approx(0.1)  # 0.1 % of the diagonal
    assert numbers["off_surface"] == 90  # 0.11 ... 1.0
    assert quality.summary(readout, threshold=0.5)["off_surface"] == 50


def _turn(axis, degrees):
    """The 3x3 rotation by ``degrees`` about ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    theta = np.radians(degrees)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(theta) * cross + (1.0 - np.cos(theta)) * cross @ cross


PLACEMENTS = {
    "identity": (np.eye(3), (0.0, 0.0, 0.0)),
    "turned, scaled unevenly, far away": (_turn((1, 2, 3), 40.0) @ np.diag([1.7, 0.4, 2.5]), (3.0e4, -2.0e4, 950.0)),
    "mirrored (negative determinant)": (
        np.diag([-1.0, 1.0, 1.0]) @ _turn((0, 1, 1), 75.0) @ np.diag([0.7, 1.3, 0.9]),
        (5.0, -3.0, 0.25),
    ),
}


def placed_case(linear, translation, seed):
    """A crumpled layout with a few faces folded over, stored in the object space of the placement ``linear``,
    ``translation``: (object matrix, local float32 positions, local float32 rest, topology, face-point state, the
    target under it). Half the vertices are face-points on the target (a snap's result), the rest above it."""
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = linear, translation
    rest, topology = layout_over(n=10, height=0.0)
    rng = np.random.default_rng(seed)
    world = rest + rng.normal(scale=0.04, size=rest.shape) + [0.0, 0.0, 0.2]
    world[[30, 64, 97]] = world[[42, 76, 85]] + [0.05, 0.05, 0.0]  # dragged over their neighbours: folds
    mesh = plane_mesh(offset=translation)
    world += translation
    snapped = rng.random(rest.shape[0]) < 0.5
    hits = mesh.closest_points(world[snapped])
    world[snapped] = hits.positions
    faces = np.full(rest.shape[0], -1, np.int32)
    faces[snapped] = hits.triangles
    states = np.where(snapped, layout_state.FACE_POINT, layout_state.SPACE_POINT).astype(np.int32)
    state = layout_state.LayoutState(states, faces, np.zeros((rest.shape[0], 3), np.float32))
    inverse = np.linalg.inv(matrix)
    local = transforms.transform_points(inverse, world).astype(np.float32)
    local_rest = transforms.transform_points(inverse, rest + translation).astype(np.float32)
    return matrix, local, local_rest, topology, state, mesh


def separate_steps(matrix, local, local_rest, topology, mesh, state):
    """The read-out by separate steps: the world positions and rest shape made in numpy, then :func:`measure`."""
    world = transforms.transform_points(matrix, local.astype(np.float64))
    return quality.measure(world, quality.world_rest_or_none(matrix, local_rest, world.shape[0]), topology, mesh, state)


def assert_same_readout(placed, reference):
    assert np.array_equal(placed.flipped, reference.flipped)
    assert np.allclose(placed.stretch, reference.stretch, rtol=1e-12, atol=0.0)
    assert np.allclose(placed.distances, reference.distances, rtol=1e-9, atol=1e-9 * reference.diagonal)
    assert placed.diagonal == pytest.approx(reference.diagonal, rel=1e-12)


@pytest.mark.parametrize("placement", PLACEMENTS)
@pytest.mark.parametrize("seed", [1, 2])
def test_the_one_call_readout_of_a_placed_layout_is_the_separate_steps_readout(placement, seed):
    matrix, local, local_rest, topology, state, mesh = placed_case(*PLACEMENTS[placement], seed)
    reference = separate_steps(matrix, local, local_rest, topology, mesh, state)
    placed = quality.measure_placed(
        local, local_rest, np.asfortranarray(matrix), topology, mesh, state
    )  # as Blender gives it
    assert reference.flipped.any() and not reference.flipped.all()  # the folds are found, and only they
    assert_same_readout(placed, reference)
    assert_same_readout(
        quality.measure_placed(local, local_rest, matrix, topology, mesh),
        separate_steps(matrix, local, local_rest, topology, mesh, None),
    )
    stray = local_rest.copy()
    stray[5] = np.nan  # a rest shape not finite in the world, or of another length: none usable, as no rest
    for unusable in (stray, local_rest[:-1], None):
        readout = quality.measure_placed(local, unusable, matrix, topology, mesh, state)
        assert_same_readout(readout, separate_steps(matrix, local, unusable, topology, mesh, state))
        assert np.array_equal(readout.stretch, np.ones(local.shape[0])) and not readout.flipped.any()
