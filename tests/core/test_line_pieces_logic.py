"""Plain tests of a free feature line cut into pieces and paired again (``addon/springwrap/core/line_pieces.py``
and ``feature_lines.pair_lines``' second pass), no Blender: straight lines beside straight target curves."""

import numpy as np

from helpers import core_module

fl = core_module("feature_lines")
lpc = core_module("line_pieces")
lp = core_module("line_placement")


def straight(count, start=(0.0, 0.0, 0.0), step=(1.0, 0.0, 0.0)):
    """(count, 3): points from ``start`` in steps of ``step``."""
    return np.asarray(start, dtype=np.float64) + np.arange(count)[:, None] * np.asarray(step, dtype=np.float64)


def ridge(x0, x1, lift=0.05, y=0.0, accuracy=None):
    """A target ridge along x from ``x0`` to ``x1`` at height ``lift`` (and ``y``), with an ``accuracy`` if given."""
    along = np.linspace(x0, x1, 4 * int(round(x1 - x0)) + 1)
    points = np.stack([along, np.full_like(along, y), np.full_like(along, lift)], axis=1).astype(np.float32)
    return ("RIDGE", points, False) if accuracy is None else ("RIDGE", points, False, accuracy)


def line(vertices, closed=False, kind="RIDGE"):
    return fl.FeatureLine(kind, "CREASE", np.asarray(vertices, dtype=np.int64), closed, 90.0)


def test_turning_is_measured_at_each_inner_point():
    points = np.concatenate([straight(4), straight(3, (3.0, 1.0, 0.0), (0.0, 1.0, 0.0))])
    turning = lpc.turning_degrees(points)
    np.testing.assert_allclose(turning, [0, 0, 0, 90, 0, 0, 0], atol=1e-9)
    assert lpc.turning_degrees(points[:2]).tolist() == [0.0, 0.0]


def test_the_nearest_curve_of_the_line_kind_within_reach():
    curves = [ridge(0, 4), ridge(4, 8), ("VALLEY", ridge(0, 8, lift=0.01)[1], False)]
    found = lpc.nearest_curves(straight(10), curves, "RIDGE", 0.5)
    assert found.tolist() == [0, 0, 0, 0, 0, 1, 1, 1, 1, -1]  # the valley is nearer but of another kind
    assert lpc.nearest_curves(straight(3), curves, "VALLEY", 0.5).tolist() == [2, 2, 2]
    assert lpc.nearest_curves(straight(3), curves, "ANY", 0.5).tolist() == [2, 2, 2]
    assert lpc.nearest_curves(straight(3) + [0, 3, 0], curves, "RIDGE", 0.5).tolist() == [-1, -1, -1]


def test_a_line_along_two_curves_in_turn_is_cut_where_the_nearest_changes():
    positions = straight(9)
    curves = [ridge(0, 4), ridge(4, 8)]
    found = lpc.pieces(np.arange(9), False, "RIDGE", positions, positions, curves, 0.5, set())
    assert [piece.tolist() for piece in found] == [[0, 1, 2, 3, 4], [5, 6, 7, 8]]
    # A vertex held elsewhere cuts it too, and runs shorter than MIN_PIECE are dropped.
    found = lpc.pieces(np.arange(9), False, "RIDGE", positions, positions, curves, 0.5, {2})
    assert [piece.tolist() for piece in found] == [[5, 6, 7, 8]]
    # A line along one curve all the way is one piece: nothing new to try.
    assert lpc.pieces(np.arange(9), False, "RIDGE", positions, positions, [ridge(0, 8)], 0.5, set()) == []
    assert lpc.pieces(np.arange(3), False, "RIDGE", positions, positions, curves, 0.5, set()) == []


def test_a_jog_is_cut_out_and_a_loop_s_run_across_its_first_vertex_is_one_piece():
    # Ten points along x, then a jog of three points straight up in y: the corner and the jog go.
    positions = np.concatenate([straight(10), straight(3, (9.0, 1.0, 0.0), (0.0, 1.0, 0.0))])
    curves = [ridge(0, 9), ridge(0, 9, y=2.0)]
    found = lpc.pieces(np.arange(13), False, "RIDGE", positions, positions, curves, 0.3, set())
    assert [piece.tolist() for piece in found] == [list(range(9))]
    # A loop of 12 along x and back (a long thin rectangle), ridges beside its two long sides; the loop starts in
    # the middle of its lower side, so that side's run crosses its first vertex and is joined into one piece.
    lower, upper = straight(11, (0, 0, 0)), straight(11, (10, 1, 0), (-1, 0, 0))
    loop = np.concatenate([lower, upper])
    curves = [ridge(-1, 11, y=0.0), ridge(-1, 11, y=1.0)]
    order = np.roll(np.arange(22), -5)  # starts at vertex 5
    found = lpc.pieces(order, True, "RIDGE", loop, loop, curves, 0.3, set())
    assert sorted(sorted(piece.tolist()) for piece in found) == [list(range(1, 10)), list(range(12, 21))]
    assert found[0].tolist() == [1, 2, 3, 4, 5, 6, 7, 8, 9]  # in the loop's order, across its first vertex


def test_pair_lines_pairs_a_line_no_curve_takes_whole_in_pieces():
    positions = straight(9)
    curves = [ridge(0, 4), ridge(4, 8)]
    anchored = np.zeros(9, dtype=bool)
    whole = fl.pair_lines([line(range(9))], positions, curves, anchored, [], 0.5)
    assert not whole.constraints and whole.free[0][1] in lpc.RETRIED  # no rest shape: no second pass
    cut = fl.pair_lines([line(range(9))], positions, curves, anchored, [], 0.5, rest=positions)
    assert (cut.pieces, cut.cut_lines, cut.free) == (2, 1, [])
    assert sorted(v for c in cut.constraints for v in c.layout_vertices.tolist()) == list(range(9))
    level, text = fl.pairing_report(1, cut)
    assert level == "INFO" and text.startswith("Paired 1 of 1 feature line (confidence")
    assert ", 1 of them in 2 pieces where no feature takes them whole" in text


def test_pair_lines_leaves_the_jog_free_and_pairs_the_run_beside_the_ridge():
    positions = np.concatenate([straight(10), straight(3, (9.0, 1.0, 0.0), (0.0, 1.0, 0.0))])
    anchored = np.zeros(len(positions), dtype=bool)
    whole = fl.pair_lines([line(range(13))], positions, [ridge(-2, 12)], anchored, [], 0.3)
    assert not whole.constraints and whole.free[0][1] in lpc.RETRIED  # the jog turns the line off its ridge
    pairing = fl.pair_lines([line(range(13))], positions, [ridge(-2, 12)], anchored, [], 0.3, rest=positions)
    (constraint,) = pairing.constraints
    assert constraint.layout_vertices.tolist() == list(range(9)) and pairing.pieces == 1


def slid_row_on_a_crest(accuracy):
    """A row of 9 vertices at y = 4 on a 9 x 9 grid of anchors' rest points, slid by a third along x under the fit,
    over a crest 0.02 above it known to within ``accuracy``: (rest, current, the row's line, curves, maps)."""
    ys, xs = np.mgrid[0:9, 0:9]
    rest = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype(np.float64)
    row = 4 * 9 + np.arange(9)
    current = rest.copy()
    current[row, 0] += 0.33
    index = np.arange(81).reshape(9, 9)
    border = np.unique(np.concatenate([index[0], index[-1], index[:, 0], index[:, -1]]))
    maps = lp.placement_maps(rest, border, rest[border] + [0, 0, 0.02])
    return rest, current, line(row), [ridge(-1, 9, lift=0.02, y=4.0, accuracy=accuracy)], maps


def test_a_line_within_a_crest_s_accuracy_is_placed_along_it_when_the_map_places_it():
    rest, current, row, curves, maps = slid_row_on_a_crest(0.04)
    anchored = np.zeros(len(rest), dtype=bool)
    free = fl.pair_lines([row], current, curves, anchored, [], 0.5, rest=rest)
    assert not free.constraints and free.free[0][1] == "WITHIN_ACCURACY"  # no map: the crest is no better a guide
    placed = fl.pair_lines([row], current, curves, anchored, [], 0.5, rest=rest, maps=maps)
    (constraint,) = placed.constraints
    targets = core_module("curves").arc_length_points(current[row.vertices], constraint.points, constraint.fractions)
    np.testing.assert_allclose(targets[:, 0], rest[row.vertices, 0], atol=1e-6)  # back where the anchors say
    # A curve known only coarsely (a ridge from curvatures: accuracy over PLACING_ACCURACY max distances) does not.
    rest, current, row, curves, maps = slid_row_on_a_crest(0.2)
    coarse = fl.pair_lines([row], current, curves, anchored, [], 0.5, rest=rest, maps=maps)
    assert not coarse.constraints and coarse.free[0][1] == "WITHIN_ACCURACY"


def test_a_line_the_chosen_map_misses_is_placed_by_another_map_that_reaches_it():
    """Two rows (the fit has row B on its ridge, 0.6 aside of its rest place): the first map lands row A on its ridge
    and misses row B's (past the reach), the second the other way round. The first is chosen (it misses less in
    all); row B is placed by the second."""
    sm = core_module("smooth_map")
    row_a, row_b = straight(9), straight(5, (0.0, 4.0, 0.0))
    rest = np.concatenate([row_a, row_b])
    curves = [ridge(-1, 9), ridge(-1, 5, y=4.6)]
    grid = np.stack(np.meshgrid(np.arange(0.0, 9.0, 2.0), np.arange(0.0, 5.0, 2.0), [0.0, 1.0]), -1).reshape(-1, 3)
    first = sm.fit(grid, grid + [0.0, 0.0, 0.05])
    second = sm.fit(grid, grid + [0.0, 0.6, 0.05])
    lines = [line(range(9)), line(range(9, 14))]
    anchored = np.zeros(len(rest), dtype=bool)
    current = rest.copy()
    current[9:, 1] += 0.6
    pairing = fl.pair_lines(lines, current, curves, anchored, [], 1.0, rest=rest, maps=[first, second])
    assert pairing.mapping._replace(bumps=None, bump_weights=None, bump_width=0.0) == first  # corrected, from the first
    placed = {int(c.layout_vertices[0]): c.fractions.size for c in pairing.constraints}
    assert placed[0] == 9 and placed[9] == 5  # both placed by a map (row B by the second)
    alone = fl.pair_lines(lines, current, curves, anchored, [], 1.0, rest=rest, maps=[first])
    assert {int(c.layout_vertices[0]): c.fractions.size for c in alone.constraints} == {0: 9, 9: 0}  # B as spaced


def test_a_piece_within_a_crest_s_accuracy_is_placed_along_it_when_the_map_places_it():
    """The row on its crest turns up the grid at its end (a line a retopology ran round a corner onto the next
    crease): the whole line is free, its run along the crest is a piece already within the crest's accuracy, and
    the map places that piece along the crest, as it does a whole line."""
    rest, current, row, curves, maps = slid_row_on_a_crest(0.04)
    vertices = np.concatenate([row.vertices, [53, 62, 71]])  # from (8, 4) up to (8, 7)
    anchored = np.zeros(len(rest), dtype=bool)
    whole = fl.pair_lines([line(vertices)], current, curves, anchored, [], 0.5)
    assert not whole.constraints and whole.free[0][1] in lpc.RETRIED
    placed = fl.pair_lines([line(vertices)], current, curves, anchored, [], 0.5, rest=rest, maps=maps)
    (constraint,) = placed.constraints
    assert constraint.layout_vertices.tolist() == row.vertices[:-1].tolist()  # the turning vertex left out
    targets = core_module("curves").arc_length_points(
        current[row.vertices[:-1]], constraint.points, constraint.fractions
    )
    np.testing.assert_allclose(targets[:, 0], rest[row.vertices[:-1], 0], atol=1e-6)
    assert placed.pieces == 1


def test_a_line_drifting_off_its_ridge_is_cut_where_it_is_no_longer_near():
    """Seven points along the ridge, then the line drifts off it by 0.3 a step (turning 17°, no jog): a piece runs
    only while each vertex is within PIECE_REACH max distances of the ridge (0.3 is, 0.6 is not for 1.0)."""
    positions = np.concatenate([straight(7), straight(3, (7.0, 0.3, 0.0), (1.0, 0.3, 0.0))])
    assert lpc.PIECE_REACH * 1.0 < 0.6
    found = lpc.pieces(np.arange(10), False, "RIDGE", positions, positions, [ridge(-1, 12)], 1.0, set())
    assert [piece.tolist() for piece in found] == [list(range(8))]
