"""Plain tests of the smooth map through matched points and the placements along a curve it gives
(``addon/springwrap/core/smooth_map.py``), no Blender."""

import numpy as np
import pytest

from helpers import bend_and_taper as bend
from helpers import core_module

sm = core_module("smooth_map")


def corners_of_a_box():
    """(8, 3): the corners of a 2 x 1 x 1 box."""
    return np.array([[x, y, z] for x in (0.0, 2.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])


def test_the_map_takes_each_source_to_its_target_and_an_affine_change_everywhere():
    sources = corners_of_a_box()
    matrix = np.array([[1.1, 0.2, 0.0], [0.0, 0.9, 0.1], [0.05, 0.0, 1.2]])
    mapping = sm.fit(sources, sources @ matrix.T + [0.3, -0.2, 0.5])
    inside = np.array([[0.5, 0.5, 0.5], [1.7, 0.2, 0.9], [3.0, -1.0, 2.0]])
    np.testing.assert_allclose(sm.apply(mapping, sources), sources @ matrix.T + [0.3, -0.2, 0.5], atol=1e-9)
    np.testing.assert_allclose(sm.apply(mapping, inside), inside @ matrix.T + [0.3, -0.2, 0.5], atol=1e-9)


def test_the_map_bends_through_its_points_and_counts_a_repeated_source_once():
    sources = np.concatenate([corners_of_a_box(), [[1.0, 0.5, 0.5], [1.0, 0.5, 0.5]]])
    targets = sources.copy()
    targets[8:] += [0.0, 0.0, 0.3]  # the middle raised: no affine map does that
    mapping = sm.fit(sources, targets)
    np.testing.assert_allclose(sm.apply(mapping, sources[:9]), targets[:9], atol=1e-9)
    lifted = sm.apply(mapping, [[0.9, 0.5, 0.5], [1.5, 0.5, 0.5]])[:, 2] - 0.5
    assert np.all((lifted > 0.05) & (lifted < 0.3))


def test_few_points_move_by_their_mean_offset():
    mapping = sm.fit([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0], [1.0, 1.2, 0.0]])
    np.testing.assert_allclose(sm.apply(mapping, [[5.0, 5.0, 5.0]]), [[5.0, 6.1, 5.0]])
    with pytest.raises(ValueError):
        sm.fit(np.zeros((0, 3)), np.zeros((0, 3)))


def test_placements_follow_the_map_along_the_curve_and_never_go_back():
    # The map shifts everything by 1 along x; the chain's rest points at x = 0, 1, 2.5, 2.4 (the last behind).
    sources = corners_of_a_box() * 4.0
    mapping = sm.fit(sources, sources + [1.0, 0.0, 0.0])
    chain_rest = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.5, 0.0, 0.0], [2.4, 0.0, 0.0], [20.0, 0.0, 0.0]])
    curve = np.array([[0.0, 0.1, 0.0], [2.0, 0.1, 0.0], [10.0, 0.1, 0.0]])
    np.testing.assert_allclose(sm.placements(mapping, chain_rest, curve), [0.1, 0.2, 0.35, 0.35, 1.0], atol=1e-9)


def box_points(count: int, seed: int = 3):
    return np.random.default_rng(seed).uniform([0.0, 0.0, 0.0], [2.0, 1.0, 1.0], size=(count, 3))


def test_a_quadratic_map_follows_a_bend_between_its_points_where_the_affine_one_does_not():
    sources = box_points(24)
    quadratic = sm.fit(sources, bend(sources), degree=2)
    affine = sm.fit(sources, bend(sources))
    assert (quadratic.degree, affine.degree) == (2, 1)
    inside = box_points(50, seed=5)
    np.testing.assert_allclose(sm.apply(quadratic, sources), bend(sources), atol=1e-8)
    np.testing.assert_allclose(sm.apply(quadratic, inside), bend(inside), atol=1e-8)  # the bend, reproduced
    assert np.abs(sm.apply(affine, inside) - bend(inside)).max() > 1e-3


def test_no_quadratic_map_through_too_few_points_or_points_on_one_plane():
    assert sm.fit(box_points(sm.MIN_QUADRATIC_POINTS - 1), box_points(sm.MIN_QUADRATIC_POINTS - 1), degree=2) is None
    flat = box_points(30) * [1.0, 1.0, 0.0]
    assert sm.fit(flat, flat, degree=2) is None
    assert sm.fit(flat, flat + [0.0, 0.0, 1.0]).degree == 1  # the affine map through them moves them by their offset
