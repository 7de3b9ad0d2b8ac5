"""Plain tests of the add-on's bpy-free feature-line pairing (``addon/springwrap/core/feature_lines.py``), no
Blender: marked lines on a flat quad grid paired with straight target curves laid just above them."""

import numpy as np

from helpers import core_module

fl = core_module("feature_lines")
lp = core_module("line_placement")
cu = core_module("curves")

SIZE = 9  # vertices a side; vertex x + SIZE * y at (x, y, 0)


def grid():
    """(positions (SIZE², 3), face corners (flat), face sizes) of a SIZE x SIZE vertex quad grid of unit spacing."""
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float64)
    index = np.arange(SIZE * SIZE).reshape(SIZE, SIZE)
    quads = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1).reshape(-1, 4)
    return positions, quads.ravel(), np.full(len(quads), 4)


def row_and_column(middle=SIZE // 2):
    """(K, 2) edges of the grid's middle row and middle column: two marked lines crossing at their middles."""
    row = [(middle * SIZE + x, middle * SIZE + x + 1) for x in range(SIZE - 1)]
    column = [(middle + y * SIZE, middle + (y + 1) * SIZE) for y in range(SIZE - 1)]
    return np.array(row + column, dtype=np.uint32)


def straight_curves(lift=0.05):
    """The target's curves: a ridge over the middle row and a valley over the middle column, ``lift`` above."""
    along = np.linspace(0.0, SIZE - 1.0, 33)
    middle = np.full_like(along, SIZE // 2)
    height = np.full_like(along, lift)
    row = np.stack([along, middle, height], axis=1).astype(np.float32)
    column = np.stack([middle, along, height], axis=1).astype(np.float32)
    return [("RIDGE", row, False), ("VALLEY", column, False)]


def test_crossing_marked_lines_never_share_a_vertex_between_their_constraints():
    """Two marked lines through one vertex both find a curve; only the more confident one becomes a constraint
    (a vertex follows one curve), the other stays free as constrained."""
    positions, corners, sizes = grid()
    lines = fl.find_lines(positions, corners, sizes, row_and_column(), 0.0, False)
    assert len(lines) == 2 and all(line.kind == "ANY" for line in lines)
    crossing = (SIZE // 2) * SIZE + SIZE // 2
    assert all(crossing in line.vertices.tolist() for line in lines)
    anchored = np.zeros(len(positions), dtype=bool)
    pairing = fl.pair_lines(lines, positions, straight_curves(), anchored, [], 0.5)
    assert len(pairing.constraints) == 1
    assert [reason for _line, reason in pairing.free] == ["CONSTRAINED"]
    cu.check_free(pairing.constraints[0].layout_vertices, [], anchored)


def test_crossing_lines_both_pair_when_the_shared_vertex_is_anchored():
    """An anchored vertex may be shared: both crossing lines become constraints."""
    positions, corners, sizes = grid()
    lines = fl.find_lines(positions, corners, sizes, row_and_column(), 0.0, False)
    anchored = np.zeros(len(positions), dtype=bool)
    anchored[(SIZE // 2) * SIZE + SIZE // 2] = True
    pairing = fl.pair_lines(lines, positions, straight_curves(), anchored, [], 0.5)
    assert len(pairing.constraints) == 2 and not pairing.free


def test_a_line_apart_from_the_others_pairs_as_before():
    """A single marked row pairs with the ridge above it, its confidence high (the ridge is 0.05 away)."""
    positions, corners, sizes = grid()
    lines = fl.find_lines(positions, corners, sizes, row_and_column()[: SIZE - 1], 0.0, False)
    pairing = fl.pair_lines(lines, positions, straight_curves(), np.zeros(len(positions), dtype=bool), [], 0.5)
    assert len(pairing.constraints) == 1 and pairing.constraints[0].confidence > 0.8


def side_columns():
    """(K, 2) edges of the grid's first and last columns, top to bottom."""
    return [(x + y * SIZE, x + (y + 1) * SIZE) for x in (0, SIZE - 1) for y in range(SIZE - 1)]


def test_junctions_are_where_two_or_more_open_lines_end():
    """The crossing of two marked lines is no junction (both run through it), nor is a bend (one line runs
    round it); where the middle row meets the two side columns, three lines end at each end (two corners)."""
    positions, corners, sizes = grid()
    crossing = fl.find_lines(positions, corners, sizes, row_and_column(), 0.0, False)
    assert fl.line_junctions(crossing).size == 0
    bend = [(x, x + 1) for x in range(SIZE - 1)] + [(y * SIZE, (y + 1) * SIZE) for y in range(SIZE - 1)]
    assert fl.line_junctions(fl.find_lines(positions, corners, sizes, np.array(bend), 0.0, False)).size == 0
    marked = np.array(row_and_column()[: SIZE - 1].tolist() + side_columns(), dtype=np.uint32)
    lines = fl.find_lines(positions, corners, sizes, marked, 0.0, False)
    middle = (SIZE // 2) * SIZE
    np.testing.assert_array_equal(fl.line_junctions(lines), [middle, middle + SIZE - 1])


def test_junctions_match_mutual_nearest_within_the_distance():
    """Each layout junction takes its nearest target junction when that is near enough and takes it back; two
    layout junctions nearest one target junction: only the nearer matches."""
    current = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.2, 0, 0], [9.0, 0, 0]])
    targets = np.array([[0.1, 0, 0], [1.15, 0, 0], [20.0, 0, 0]])
    matched = fl.match_junctions([0, 1, 2, 3], current, targets, 0.5)
    assert sorted(matched) == [0, 2]
    np.testing.assert_allclose(matched[0], targets[0])
    np.testing.assert_allclose(matched[2], targets[1])
    assert fl.match_junctions([0, 1], current, np.zeros((0, 3)), 0.5) == {}


def test_a_chain_between_matched_junctions_takes_its_share_of_the_curve_by_rest_length():
    """A line of 5 rest vertices (unevenly spaced: 0, 1, 3, 4, 8) between two corners; its chain leaves the
    corners out. On a curve twice as long between the matched corners (the curve's ends), the chain's stretch
    runs from twice 1 to twice 4 along it."""
    rest = np.array([[0.0, 0, 0], [1, 0, 0], [3, 0, 0], [4, 0, 0], [8, 0, 0]])
    curve = np.stack([np.linspace(0.0, 16.0, 9), np.full(9, 5.0), np.zeros(9)], axis=1)
    stretch = lp.between_junctions(rest, np.array([1, 2, 3]), curve, [0.0, 5, 0], [16.0, 5, 0])
    np.testing.assert_allclose(stretch[0], [2.0, 5, 0], atol=1e-9)
    np.testing.assert_allclose(stretch[-1], [8.0, 5, 0], atol=1e-9)
    # The corners in the other order: the stretch runs the other way, from the far end.
    stretch = lp.between_junctions(rest, np.array([1, 2, 3]), curve, [16.0, 5, 0], [0.0, 5, 0])
    np.testing.assert_allclose(stretch[0], [14.0, 5, 0], atol=1e-9)
    np.testing.assert_allclose(stretch[-1], [8.0, 5, 0], atol=1e-9)
    # A curve between the corners far shorter than the line: no stretch (the fit's is kept).
    assert lp.between_junctions(rest, np.array([1, 2, 3]), curve[:2], [0.0, 5, 0], [2.0, 5, 0]) is None
    # A corner off the curve (the curve stops short of it, another crease goes on to it): no stretch either.
    assert lp.between_junctions(rest, np.array([1, 2, 3]), curve[:8], [0.0, 5, 0], [16.0, 5, 0]) is None


def test_pairing_between_matched_junctions_moves_the_stretch_to_the_corners():
    """The middle row between two side columns (a corner at each end); the fit slid the row by a third of an
    edge along itself. With both of its corners matched to the curve's true corners the row's stretch is the
    true one (the chain's ends at their rest places), without junctions the slid one."""
    positions, corners, sizes = grid()
    marked = np.array(row_and_column()[: SIZE - 1].tolist() + side_columns(), dtype=np.uint32)
    lines = fl.find_lines(positions, corners, sizes, marked, 0.0, False)
    middle = SIZE // 2
    row = middle * SIZE + np.arange(SIZE)
    along = np.linspace(0.0, SIZE - 1.0, 33)
    curve = np.stack([along, np.full_like(along, middle), np.full_like(along, 0.05)], 1).astype(np.float32)
    current = positions.copy()
    current[row, 0] += 0.33
    anchored = np.zeros(len(positions), dtype=bool)
    true_corners = [[0.0, middle, 0.05], [SIZE - 1.0, middle, 0.05]]
    junctions = fl.match_junctions(fl.line_junctions(lines), current, true_corners, 1.0)
    assert sorted(junctions) == [row[0], row[-1]]
    paired = fl.pair_lines(
        lines, current, [("RIDGE", curve, False)], anchored, [], 0.5, rest=positions, junctions=junctions
    )
    slid = fl.pair_lines(lines, current, [("RIDGE", curve, False)], anchored, [], 0.5)
    assert paired.between_junctions == 1 and slid.between_junctions == 0
    (constraint,) = paired.constraints
    assert sorted(constraint.layout_vertices.tolist()) == row[1:-1].tolist()
    ends = constraint.layout_vertices[[0, -1]]
    np.testing.assert_allclose(constraint.points[[0, -1], 0], positions[ends, 0], atol=1e-5)
    np.testing.assert_allclose(slid.constraints[0].points[[0, -1], 0], current[ends, 0], atol=1e-3)


def slid_row():
    """The grid's lines with its middle row slid along itself by a third of an edge under the fit: (rest positions,
    lines, the row's vertices, the fitted positions, no vertex anchored, the grid's border vertices)."""
    positions, corners, sizes = grid()
    lines = fl.find_lines(positions, corners, sizes, row_and_column()[: SIZE - 1], 0.0, False)
    row = (SIZE // 2) * SIZE + np.arange(SIZE)
    current = positions.copy()
    current[row, 0] += 0.33
    anchored = np.zeros(len(positions), dtype=bool)
    index = np.arange(SIZE * SIZE).reshape(SIZE, SIZE)
    border = np.unique(np.concatenate([index[0], index[-1], index[:, 0], index[:, -1]]))
    return positions, lines, row, current, anchored, border


def test_a_placement_map_puts_each_paired_vertex_where_the_anchors_say_not_where_the_fit_slid_it():
    """The middle row slid along itself by a third of an edge under the fit; anchors round the grid's border (at their
    rest places, the truth) give a map that places each vertex of the row back at its own x along the ridge; four
    anchors are too few to place a line without matched corners: it goes as spaced."""
    positions, lines, row, current, anchored, border = slid_row()
    maps = lp.placement_maps(positions, border, positions[border] + [0, 0, 0.05])
    placed = fl.pair_lines(lines, current, straight_curves(), anchored, [], 0.5, rest=positions, maps=maps)
    spaced = fl.pair_lines(lines, current, straight_curves(), anchored, [], 0.5)
    (constraint,) = placed.constraints
    assert constraint.fractions.size == constraint.layout_vertices.size and spaced.constraints[0].fractions.size == 0
    targets = cu.arc_length_points(current[constraint.layout_vertices], constraint.points, constraint.fractions)
    np.testing.assert_allclose(targets[:, 0], positions[constraint.layout_vertices, 0], atol=1e-6)
    slid = cu.arc_length_points(current[constraint.layout_vertices], spaced.constraints[0].points)
    assert np.abs(slid[:, 0] - positions[spaced.constraints[0].layout_vertices, 0]).max() > 0.1
    assert lp.placement_maps(positions, [], np.zeros((0, 3))) == []
    coarse = lp.placement_maps(positions, border[:4], positions[border[:4]] + [0, 0, 0.05])  # too few points
    assert len(coarse) == 1  # no quadratic through four points
    as_spaced = fl.pair_lines(lines, current, straight_curves(), anchored, [], 0.5, rest=positions, maps=coarse)
    assert as_spaced.constraints[0].fractions.size == 0


def test_a_map_that_misses_the_feature_does_not_place_the_line_along_it():
    """The map's distance across the feature is a sample of its error: anchors whose targets lie sideways of the
    ridge by more than MAP_REACH maximum distances take the row beside it, and the row goes as the fit spaces it;
    a map within that reach places it."""
    positions, lines, row, current, anchored, border = slid_row()
    reach = lp.MAP_REACH * 0.5
    for sideways, placed in ((1.5 * reach, False), (0.5 * reach, True)):
        maps = lp.placement_maps(positions, border, positions[border] + [0, sideways, 0.05])
        assert lp.map_reaches(maps[0], positions[row], straight_curves()[0][1], 0.5) == placed
        pairing = fl.pair_lines(lines, current, straight_curves(), anchored, [], 0.5, rest=positions, maps=maps)
        (constraint,) = pairing.constraints
        assert (constraint.fractions.size == constraint.layout_vertices.size) == placed


def test_vertices_the_map_takes_past_the_end_of_a_feature_are_left_to_the_fit():
    """The ridge stops two edges short of the row's end (a crease a scan lost before a corner): the map takes the
    row's last two vertices past its end, by more than MAP_REACH maximum distances, and they are left out of the
    constraint instead of pinned to the ridge's end; the rest of the row is placed along it as before."""
    positions, lines, row, current, anchored, border = slid_row()
    short = [
        (kind, points[points[:, 0] <= SIZE - 3.0] if kind == "RIDGE" else points, closed)
        for kind, points, closed in straight_curves()
    ]
    maps = lp.placement_maps(positions, border, positions[border] + [0, 0, 0.05])
    assert lp.past_ends(maps[0], positions[row], short[0][1], lp.MAP_REACH * 0.5) == (0, 2)
    assert lp.past_ends(maps[0], positions[row][::-1], short[0][1], lp.MAP_REACH * 0.5) == (2, 0)
    assert lp.past_ends(maps[0], positions[row], straight_curves()[0][1], lp.MAP_REACH * 0.5) == (0, 0)
    pairing = fl.pair_lines(lines, current, short, anchored, [], 0.5, rest=positions, maps=maps)
    (constraint,) = pairing.constraints
    ends = {int(v) for v in constraint.layout_vertices[[0, -1]]}
    assert ends == {int(row[0]), int(row[-3])}
    targets = cu.arc_length_points(current[constraint.layout_vertices], constraint.points, constraint.fractions)
    np.testing.assert_allclose(targets[:, 0], positions[constraint.layout_vertices, 0], atol=1e-6)
