"""Plain tests of which smooth map places paired lines along their features (``addon/springwrap/core/
line_placement.py``'s ``placement_maps`` and ``choose_map``), no Blender."""

import numpy as np

from helpers import bend_and_taper as bend
from helpers import core_module

lp = core_module("line_placement")


def scene(change):
    """Rest points on a 4 x 3 x 3 grid (36: anchors), their targets under ``change``, and two lines of the rest
    shape (along x at the top, along y at the far end) with their changed curves."""
    xs, ys, zs = np.meshgrid(np.linspace(0, 3, 4), np.linspace(0, 2, 3), np.linspace(0, 2, 3), indexing="ij")
    rest = np.stack([xs.ravel(), ys.ravel(), zs.ravel()], axis=1)
    along_x = np.stack([np.linspace(0.2, 2.8, 14), np.full(14, 1.3), np.full(14, 1.9)], axis=1)
    along_y = np.stack([np.full(12, 2.7), np.linspace(0.1, 1.9, 12), np.full(12, 0.4)], axis=1)
    dense = [np.linspace(line[0], line[-1], 200) for line in (along_x, along_y)]
    chains = [(line, change(curve)) for line, curve in zip((along_x, along_y), dense)]
    return rest, change(rest), chains


def test_the_quadratic_map_is_chosen_when_it_lands_the_lines_nearer_their_features():
    rest, targets, chains = scene(bend)
    maps = lp.placement_maps(rest, np.arange(len(rest)), targets)
    assert [m.degree for m in maps] == [1, 2]
    chosen, affine_miss, chosen_miss = lp.choose_map(maps, chains)
    assert chosen.degree == 2 and chosen_miss < 0.01 * affine_miss  # the bend, followed


def test_the_affine_map_stays_when_the_quadratic_is_no_nearer():
    def affine(points):
        return np.asarray(points) @ np.array([[1.1, 0.1, 0.0], [0.0, 0.9, 0.0], [0.0, 0.05, 1.0]]).T + [0.3, 0.0, -0.2]

    rest, targets, chains = scene(affine)
    maps = lp.placement_maps(rest, np.arange(len(rest)), targets)
    chosen, _affine_miss, _chosen_miss = lp.choose_map(maps, chains)
    assert chosen.degree == 1  # both land the lines on their curves: the simpler map
    assert lp.choose_map([], chains) == (None, 0.0, 0.0)
    few = lp.placement_maps(rest, np.arange(8), targets[:8])
    assert [m.degree for m in few] == [1]  # too few points for a quadratic
