"""Plain tests of the add-on's bpy-free feature-line pairing (``addon/springwrap/core/feature_lines.py``), no
Blender: marked lines on a flat quad grid paired with straight target curves laid just above them."""

import numpy as np

from helpers import core_module

fl = core_module("feature_lines")
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
