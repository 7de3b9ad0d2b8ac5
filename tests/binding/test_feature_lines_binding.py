"""``springwrap_kernel.layout_feature_lines`` and ``pair_feature_lines``: a folded grid's crease and rim, a marked
line crossing itself refused, a line paired with the curve beside it or left free with the reason, bad arguments
refused naming them. No Blender."""

import numpy as np
import pytest

import springwrap_kernel as sk


def folded_grid(n=4, fold=2.0, degrees=60.0):
    """An n x n quad grid in XY (vertices row after row), the part beyond x = fold raised by ``degrees``."""
    x, y = np.meshgrid(np.arange(n + 1, dtype=np.float32), np.arange(n + 1, dtype=np.float32))
    z = np.maximum(x - fold, 0.0) * np.tan(np.radians(degrees))
    positions = np.ascontiguousarray(np.stack([x, y, z], axis=-1).reshape(-1, 3), dtype=np.float32)
    at = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([at[:-1, :-1], at[:-1, 1:], at[1:, 1:], at[1:, :-1]], axis=-1).reshape(-1)
    return positions, np.ascontiguousarray(quads, dtype=np.uint32), np.full(n * n, 4, dtype=np.uint32)


def test_a_fold_is_a_valley_crease_and_the_rim_a_border_loop():
    lines = sk.layout_feature_lines(*folded_grid())
    kinds = sorted((kind, source, closed, len(vertices)) for kind, source, vertices, closed, _angle in lines)
    assert kinds == [("BORDER", "BORDER", True, 16), ("VALLEY", "CREASE", False, 5)]
    crease = next(line for line in lines if line[1] == "CREASE")
    assert sorted(crease[2].tolist()) == [2, 7, 12, 17, 22]
    assert crease[4] == pytest.approx(-60.0, abs=0.1)
    # A crease angle above the fold, and no borders: nothing.
    assert sk.layout_feature_lines(*folded_grid(), crease_degrees=70.0, borders=False) == []


def test_marked_edges_are_lines_and_one_crossing_itself_is_refused():
    positions, corners, sizes = folded_grid(degrees=0.0)
    row = np.array([[10, 11], [11, 12], [12, 13], [13, 14]], dtype=np.uint32)
    lines = sk.layout_feature_lines(positions, corners, sizes, marked=row, crease_degrees=0.0, borders=False)
    assert [(kind, source, vertices.tolist()) for kind, source, vertices, _c, _a in lines] == [
        ("ANY", "MARKED", [10, 11, 12, 13, 14])
    ]
    eight = [12, 13, 8, 7, 12, 11, 16, 17, 12]
    marked = np.array(list(zip(eight[:-1], eight[1:])), dtype=np.uint32)
    with pytest.raises(sk.InvalidArgumentError, match="crosses itself at vertex 12"):
        sk.layout_feature_lines(positions, corners, sizes, marked=marked)
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.layout_feature_lines(positions, corners, sizes, marked=np.array([[0, 99]], dtype=np.uint32))
    with pytest.raises(sk.ArrayError, match="marked"):
        sk.layout_feature_lines(positions, corners, sizes, marked=np.array([[0, 1]], dtype=np.int64))


def test_a_line_pairs_with_the_parallel_curve_of_its_kind_or_stays_free_saying_why():
    positions = np.array([[i, 0.1, 0.0] for i in range(5)], dtype=np.float32)
    line = (np.arange(5, dtype=np.uint32), False, "RIDGE")
    ridge = ("RIDGE", np.array([[4.2, 0, 0], [-0.2, 0, 0]], dtype=np.float32), False)
    valley = ("VALLEY", np.array([[0, 0.05, 0], [4, 0.05, 0]], dtype=np.float32), False)
    [paired] = sk.pair_feature_lines(positions, [line], [valley, ridge], max_distance=0.5)
    assert paired.curve == 1 and paired.reason is None
    assert paired.confidence == pytest.approx(0.8, abs=0.01)
    assert paired.chain.tolist() == [0, 1, 2, 3, 4]
    np.testing.assert_allclose(paired.target[[0, -1]], [[0, 0, 0], [4, 0, 0]], atol=1e-4)
    [free] = sk.pair_feature_lines(positions, [line], [valley], max_distance=0.5)
    assert (free.curve, free.reason, free.confidence, free.chain.size) == (None, "NONE_NEARBY", 0.0, 0)


def test_bad_pairing_arguments_are_refused_naming_them():
    positions = np.zeros((2, 3), dtype=np.float32)
    line = (np.array([0, 1], dtype=np.uint32), False, "ANY")
    with pytest.raises(sk.InvalidArgumentError, match="max_distance"):
        sk.pair_feature_lines(positions, [line], [], max_distance=0.0)
    with pytest.raises(sk.InvalidArgumentError, match="line kind"):
        sk.pair_feature_lines(positions, [(line[0], False, "CURLY")], [], max_distance=1.0)
    with pytest.raises(sk.InvalidArgumentError, match="curve kind"):
        sk.pair_feature_lines(positions, [line], [("ANY", positions, False)], max_distance=1.0)
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.pair_feature_lines(positions, [(np.array([0, 5], dtype=np.uint32), False, "ANY")], [], max_distance=1.0)
