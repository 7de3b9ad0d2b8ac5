"""Plain tests of the add-on's bpy-free curve-constraint logic (``addon/springwrap/core/curves.py``), no Blender.

Chains, shortest paths and automatic pairing run on generated grids (a W x H lattice of unit
spacing in the plane z = 0) whose answers are known: a row of the grid is the shortest path
between its ends, a border of a quad grid is one curve. Orientation and chain-following paths run
on rings and tubes: an opened ring's two ends are next to each other, and between two
points of a ring the shortest path is the short way round whichever way the layout chain runs.
"""

import sys

import numpy as np
import pytest

from helpers import core_module

cu = core_module("curves")
ep = sys.modules[cu.__name__.rpartition(".")[0] + ".edge_paths"]
LayoutError = cu.LayoutError


def grid(width, height, diagonals=False):
    """Vertices (width*height, 3) of a unit lattice (vertex x + width*y) and its edges (rows, columns, optional diagonals)."""
    ys, xs = np.mgrid[0:height, 0:width]
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float64)
    index = np.arange(width * height).reshape(height, width)
    edges = [np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], axis=1)]
    edges.append(np.stack([index[:-1, :].ravel(), index[1:, :].ravel()], axis=1))
    if diagonals:
        edges.append(np.stack([index[:-1, :-1].ravel(), index[1:, 1:].ravel()], axis=1))
    return positions, np.concatenate(edges), index


# ---------------------------------------------------------------- chains


def test_chain_from_shuffled_edges_is_in_order_from_the_lower_end():
    edges = np.array([[7, 3], [3, 9], [1, 7], [9, 4]])
    np.testing.assert_array_equal(ep.chain_from_edges(edges), [1, 7, 3, 9, 4])
    np.testing.assert_array_equal(ep.chain_from_edges(edges[::-1, ::-1]), [1, 7, 3, 9, 4])


@pytest.mark.parametrize(
    "edges, reason",
    [
        (np.zeros((0, 2)), "No edge"),
        ([[0, 1], [1, 2], [1, 3]], "branch at vertex 1"),
        ([[0, 1], [1, 2], [2, 0]], "closed loop"),
        ([[0, 1], [2, 3]], "more than one piece"),
        ([[0, 1], [1, 2], [5, 6], [6, 7], [7, 5]], "more than one piece"),
    ],
)
def test_chain_refusals_say_why(edges, reason):
    with pytest.raises(LayoutError, match=reason):
        ep.chain_from_edges(edges)


# ---------------------------------------------------------------- shortest paths


def test_shortest_path_on_a_grid_is_the_straight_row():
    positions, edges, index = grid(9, 6, diagonals=True)
    path = ep.shortest_path(positions, edges, index[3, 0], index[3, 8])
    np.testing.assert_array_equal(path, index[3, :])
    np.testing.assert_array_equal(ep.shortest_path(positions, edges, index[3, 8], index[3, 0]), index[3, ::-1])


def test_shortest_path_takes_the_diagonal_when_shorter_and_refuses_unreachable():
    positions, edges, index = grid(5, 5, diagonals=True)
    np.testing.assert_array_equal(ep.shortest_path(positions, edges, index[0, 0], index[4, 4]), np.diag(index))
    cut = edges[~np.isin(edges, index[:, 2]).any(axis=1)]  # column 2 removed: left and right halves apart
    with pytest.raises(LayoutError, match="No chain of target edges"):
        ep.shortest_path(positions, cut, index[0, 0], index[0, 4])


def test_shortest_path_scales_to_a_large_grid():
    positions, edges, index = grid(400, 400)  # 160,000 vertices, 319,200 edges
    path = ep.shortest_path(positions, edges, index[200, 0], index[200, 399])
    np.testing.assert_array_equal(path, index[200, :])


def ring(count, turn=0.0, radius=1.0, z=0.0):
    """(count, 3) points round the z axis, 2 pi / count apart, the first at ``turn`` steps from +x."""
    angles = 2.0 * np.pi * (np.arange(count) + turn) / count
    return np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(count, z)], axis=1)


def tube(segments, rings, diagonals=False):
    """A tube's vertices (radius 1, ring r at z = 0.1 r; vertex r * segments + s) and its quad edges
    (round and along, optionally one diagonal per quad)."""
    positions = np.concatenate([ring(segments, z=0.1 * r) for r in range(rings)])
    index = np.arange(segments * rings).reshape(rings, segments)
    edges = [np.stack([index.ravel(), np.roll(index, -1, axis=1).ravel()], axis=1)]
    edges.append(np.stack([index[:-1].ravel(), index[1:].ravel()], axis=1))
    if diagonals:
        edges.append(np.stack([index[:-1].ravel(), np.roll(index, -1, axis=1)[1:].ravel()], axis=1))
    return positions, np.concatenate(edges), index


def test_orientation_follows_a_straight_chain():
    points = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    chain = np.array([[2.1, 0.3, 0], [1.0, 0.3, 0], [-0.1, 0.3, 0]])
    np.testing.assert_array_equal(cu.orient_to_chain(points, chain), points[::-1])
    np.testing.assert_array_equal(cu.orient_to_chain(points, chain[::-1]), points)
    np.testing.assert_array_equal(cu.orient_to_chain(points, chain[:1]), points[::-1])  # one vertex: the nearer end


@pytest.mark.parametrize("turn", [-0.6, -0.4, 0.0, 0.4, 0.6])
def test_an_opened_ring_keeps_its_direction_on_a_turned_chain(turn):
    """Regression on a ring: the chain (an opened 16-vertex ring) turned by 0.6 of an edge backwards has its first
    vertex 0.4 of an edge from the curve's *last* point; the end-nearest rule of v1 reversed the
    curve (90 degrees of mean error). The whole chain decides."""
    points = ring(16)
    chain = ring(16, turn)
    kept = cu.orient_to_chain(points, chain)
    np.testing.assert_array_equal(kept, points)
    np.testing.assert_array_equal(cu.orient_to_chain(points[::-1], chain), points)  # drawn backwards: turned round
    assert cu.matching_error(chain, kept) < 0.5 * cu.matching_error(chain, points[::-1])
    along = cu.arc_length_points(chain, kept)
    np.testing.assert_allclose(along, points, atol=1e-12)  # vertex k goes to curve point k
    if turn == -0.6:  # the trap: the first vertex is nearer the curve's end than its start
        assert np.linalg.norm(chain[0] - points[-1]) < np.linalg.norm(chain[0] - points[0])


def test_a_closed_curve_is_cut_where_the_chain_starts_and_ends():
    """A closed curve (its last point on its first, as a closed feature curve) has no ends of its
    own: the chain's ends decide where the piece starts and ends, the whole chain which way round."""
    loop = np.concatenate([ring(32, turn=5.0), ring(32, turn=5.0)[:1]])  # starts at 5 steps, ends there again
    assert cu.is_closed(loop) and not cu.is_closed(loop[:-1]) and not cu.is_closed(loop[:3])
    for chain, turn_sign in ((ring(16, turn=-0.3), 1.0), (ring(16, turn=-0.3)[::-1], -1.0)):  # both ways round
        piece = cu.orient_to_chain(loop, chain)
        sag = 1.0 - np.cos(np.pi / 32)  # the loop's chords pass inside the ring the chain is on
        np.testing.assert_allclose(piece[0], chain[0], atol=sag)  # the loop's point nearest to the chain's ends
        np.testing.assert_allclose(piece[-1], chain[-1], atol=sag)
        assert cu.matching_error(chain, piece) < 0.01  # vertex k within a chord's sag of its place
        angles = np.unwrap(np.arctan2(piece[:, 1], piece[:, 0]))
        assert np.all(turn_sign * np.diff(angles) > 0)
        assert np.isclose(abs(angles[-1] - angles[0]), 2 * np.pi * 15 / 16)  # the gap is left out
    half = ring(32)[8:25]  # half a ring (90 to 270 degrees), the other way round from the loop's start
    piece = cu.orient_to_chain(loop, half[::-1])
    np.testing.assert_allclose(piece, half[::-1], atol=1e-12)
    closed_chain = np.concatenate([ring(16, turn=0.2), ring(16, turn=0.2)[:1]])  # ends on one point: the whole loop
    piece = cu.orient_to_chain(loop, closed_chain)
    assert np.isclose(ep.cumulative_lengths(piece)[-1], ep.cumulative_lengths(loop)[-1])
    assert cu.matching_error(closed_chain, piece) < 0.01


def test_nearest_vertices_and_pieces():
    generator = np.random.default_rng(11)
    positions = generator.normal(size=(500, 3))
    points = generator.normal(size=(70, 3))
    brute = np.argmin(((points[:, None, :] - positions[None, :, :]) ** 2).sum(axis=2), axis=1)
    np.testing.assert_array_equal(ep.nearest_vertices(positions, points), brute)
    assert ep.nearest_vertex(positions, points[3]) == brute[3]
    first, first_edges, _ = grid(4, 3)
    two = ep.edge_graph(np.concatenate([first, first + 10.0]), np.concatenate([first_edges, first_edges + 12]))
    np.testing.assert_array_equal(two.pieces, np.repeat([0, 12], 12))  # each piece labelled by its lowest vertex


def test_chain_course_moves_the_ends_onto_the_anchors():
    chain = np.array([[0.0, 0, 1], [1, 0, 1], [3, 0, 1]])  # fractions 0, 1/3, 1
    course = ep.chain_course(chain, [0.0, 0, 0], [3.0, 0, 3])  # the ends move by (0, 0, -1) and (0, 0, 2)
    np.testing.assert_allclose(course, [[0, 0, 0], [1, 0, 1 - 2 / 3 + 2 / 3], [3, 0, 3]])


@pytest.mark.parametrize("diagonals", [False, True])
def test_a_path_follows_the_chain_the_long_way_round(diagonals):
    """Regression on a ring: between two points of a ring 135 degrees apart the shortest edge path is the short
    way round; a layout chain going the long way (225 degrees) must be followed that way."""
    positions, edges, index = tube(48, 5, diagonals)
    chain = ring(16, radius=1.05, z=0.2)[:11]  # 0 to 225 degrees, beside the tube
    start, end = index[2, 0], index[2, 30]
    np.testing.assert_array_equal(ep.shortest_path(positions, edges, start, end), index[2, [0, *range(47, 29, -1)]])
    graph = ep.edge_graph(positions, edges)
    course = ep.chain_course(chain, positions[start], positions[end])
    np.testing.assert_array_equal(ep.following_path(positions, graph, course, start, end), index[2, :31])
    constraint = cu.target_edge_constraint(np.arange(11), chain, positions[start], positions[end], positions, edges)
    np.testing.assert_array_equal(constraint.target_vertices, index[2, :31])
    np.testing.assert_allclose(constraint.points, positions[index[2, :31]])


def test_a_path_follows_an_opened_ring_past_its_gap():
    """The chain's ends anchor to neighbouring target vertices: the one edge between them is the
    shortest path, the ring all the way round is the chain's course."""
    positions, edges, index = tube(48, 3)
    chain = ring(16, radius=1.02, z=0.1)  # ends on target vertices 0 and 45 (22.5 degrees x 15 = 337.5)
    graph = ep.edge_graph(positions, edges)
    path = ep.following_path(positions, graph, chain, index[1, 0], index[1, 45])
    np.testing.assert_array_equal(path, index[1, :46])


def test_a_path_cuts_out_loops_and_ignores_other_pieces():
    positions, edges, index = grid(12, 7)
    # A chain along row 3 with a spike out to row 1 and back, and a step back.
    chain = np.array([[0, 3], [2, 3], [2, 1], [2, 3], [4, 3], [6, 3], [5.4, 3], [8, 3], [11, 3]], dtype=np.float64)
    chain = np.c_[chain, np.full(9, 0.5)]
    graph = ep.edge_graph(positions, edges)
    path = ep.following_path(positions, graph, chain, index[3, 0], index[3, 11])
    assert len(set(path.tolist())) == path.size  # a simple path
    assert path[0] == index[3, 0] and path[-1] == index[3, 11]
    np.testing.assert_array_equal(path, index[3, :])  # the spike out to row 1 and the step back are cut out
    # A second piece (a copy of the grid lifted by 0.4, nearer the chain than the first): not followed.
    both = np.concatenate([positions, positions + [0.0, 0.0, 0.4]])
    both_edges = np.concatenate([edges, edges + positions.shape[0]])
    path = ep.following_path(both, ep.edge_graph(both, both_edges), chain, index[3, 0], index[3, 11])
    np.testing.assert_array_equal(path, index[3, :])
    with pytest.raises(LayoutError, match="No chain of target edges joins"):
        ep.following_path(both, ep.edge_graph(both, both_edges), chain, index[3, 0], index[3, 11] + positions.shape[0])


# ---------------------------------------------------------------- automatic pairing


def test_auto_pairs_a_border_with_anchored_ends_and_counts_the_refusals():
    target_positions, target_edges, target_index = grid(11, 11)
    layout_curves = [
        ("BORDER", np.array([0, 1, 2, 3, 4]), False),  # both ends anchored: paired
        ("BORDER", np.array([4, 5, 6]), False),  # end 6 not anchored
        ("SEAM", np.array([10, 11, 12]), True),  # closed
        ("LOOSE", np.array([20, 21, 22]), False),  # both anchors near the same target vertex
        ("LOOSE", np.array([0, 2, 30, 31]), False),  # vertex 2 (not anchored) taken by the first pairing
    ]
    anchor_vertices = np.array([0, 4, 20, 22, 31])
    anchor_locations = np.array([[0.1, 2.0, 0.2], [7.9, 2.1, 0.1], [5.0, 5.0, 0.0], [5.2, 4.9, 0.0], [9.0, 9.0, 0.0]])
    layout_positions = np.zeros((40, 3))
    layout_positions[:5] = [[2.0 * k, 2.2, 0.3] for k in range(5)]  # the first curve runs along row y = 2
    outcome = cu.auto_pairs(
        layout_curves, anchor_vertices, anchor_locations, [], target_positions, target_edges, layout_positions
    )
    assert len(outcome.constraints) == 1
    constraint = outcome.constraints[0]
    np.testing.assert_array_equal(constraint.layout_vertices, [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(constraint.target_vertices, target_index[2, 0:9])  # row y=2, x 0..8
    np.testing.assert_allclose(constraint.points, target_positions[target_index[2, 0:9]])
    assert outcome.skipped == {"closed": 1, "unanchored": 1, "ambiguous": 1, "constrained": 1, "unreachable": 0}
    report = cu.skip_report(outcome.skipped)
    assert report.startswith("4 skipped") and "same target vertex" in report

    again = cu.auto_pairs(
        layout_curves[:1],
        anchor_vertices,
        anchor_locations,
        outcome.constraints,
        target_positions,
        target_edges,
        layout_positions,
    )
    assert not again.constraints and again.skipped["constrained"] == 1


# ---------------------------------------------------------------- kernel arrays


def test_kernel_arrays_are_flat_and_checked():
    first = cu.make_constraint([0, 1, 2], [[0, 0, 0], [1, 0, 0]], cu.CURVE_OBJECT)
    second = cu.make_constraint([2, 3], [[0, 1, 0], [1, 1, 0], [2, 1, 0]], cu.TARGET_EDGES, [5, 6, 7])
    assert cu.kernel_arrays([], 4) is None
    anchored = np.array([False, False, True, False])
    second = second._replace(fractions=np.array([0.0, 0.8]))
    vertices, vertex_counts, points, point_counts, fractions = cu.kernel_arrays([first, second], 4, anchored)
    np.testing.assert_array_equal(vertices, [0, 1, 2, 2, 3])
    np.testing.assert_allclose(fractions, [np.nan, np.nan, np.nan, 0.0, 0.8], rtol=1e-6)  # the first as spaced
    np.testing.assert_array_equal(vertex_counts, [3, 2])
    assert points.dtype == np.float32 and points.shape == (5, 3) and points.flags.c_contiguous
    np.testing.assert_array_equal(point_counts, [2, 3])
    with pytest.raises(LayoutError, match="belongs to curve constraints 0 and 1"):
        cu.kernel_arrays([first, second], 4)  # vertex 2 shared and not anchored
    with pytest.raises(LayoutError, match="no longer has"):
        cu.kernel_arrays([second], 3)
    with pytest.raises(LayoutError, match="at least two"):
        cu.kernel_arrays([cu.make_constraint([0, 1], [[0, 0, 0]], cu.CURVE_OBJECT)], 4)
    with pytest.raises(LayoutError, match="NaN"):
        cu.kernel_arrays([cu.make_constraint([0, 1], [[0, 0, 0], [np.nan, 0, 0]], cu.CURVE_OBJECT)], 4)
    with pytest.raises(LayoutError, match="placements"):
        cu.kernel_arrays([second._replace(fractions=np.array([0.0, 1.5]))], 4)
    with pytest.raises(ValueError, match="fractions for a chain"):
        cu.make_constraint([0, 1], [[0, 0, 0], [1, 0, 0]], cu.FEATURE_LINE, fractions=[0.5])


def test_arc_length_points_and_dashes():
    chain = np.array([[0.0, 1, 0], [1, 1, 0], [3, 1, 0]])  # fractions 0, 1/3, 1
    polyline = np.array([[0.0, 0, 0], [6, 0, 0]])
    np.testing.assert_allclose(cu.arc_length_points(chain, polyline), [[0, 0, 0], [2, 0, 0], [6, 0, 0]])
    starts, ends = cu.dashed_segments(chain, cu.arc_length_points(chain, polyline), dash_count=3)
    assert starts.shape == ends.shape == (9, 3)
    np.testing.assert_allclose(starts[:3, 1], [1.0, 0.6, 0.2], atol=1e-6)  # pieces of 1/5, every other one
    np.testing.assert_allclose(ends[:3, 1], [0.8, 0.4, 0.0], atol=1e-6)


def test_index_text_round_trip():
    np.testing.assert_array_equal(cu.parse_indices(cu.format_indices([4, 0, 17])), [4, 0, 17])
    assert cu.parse_indices("").size == 0
    with pytest.raises(LayoutError, match="Malformed"):
        cu.parse_indices("1 x 2")
