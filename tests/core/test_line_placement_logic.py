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


def test_the_map_corrected_by_the_lines_misses_places_them_nearer_where_they_belong():
    """Eight anchors at a box's corners, a bend, taper and ripple along x between them: the affine map misses the
    lines' curves and misplaces their vertices along them. Corrected by the lines' misses across (rows along x and
    columns along y, each telling the map's error across itself), it places every line's vertices along its curve
    several times nearer their true places, and still takes the anchors where they are."""
    sm = core_module("smooth_map")

    def change(points):
        moved = bend(points)
        moved[:, 0] += 0.15 * np.sin(1.3 * np.asarray(points)[:, 0])
        return moved

    corners = np.array([[x, y, z] for x in (0, 3) for y in (0, 2) for z in (0, 2)], dtype=np.float64)
    grid = np.meshgrid(np.linspace(0, 3, 7), np.linspace(0, 2, 5), np.linspace(0, 2, 5), indexing="ij")
    rest = np.stack([axis.ravel() for axis in grid], axis=1)
    rows = [
        np.stack([np.linspace(0.2, 2.8, 14), np.full(14, y), np.full(14, z)], 1) for y in (0.5, 1.5) for z in (0.3, 1.7)
    ]
    columns = [
        np.stack([np.full(10, x), np.linspace(0.1, 1.9, 10), np.full(10, z)], 1)
        for x in (0.7, 1.5, 2.3)
        for z in (0.3, 1.7)
    ]
    chains = [(line, change(np.linspace(line[0], line[-1], 300))) for line in rows + columns]
    plain = sm.fit(corners, change(corners))
    corrected = lp.corrected(plain, chains, rest)

    def along_error(mapping):
        errors = []
        for line, curve in chains:
            cumulative = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
            truth = np.array([lp.parameter(curve, cumulative, point)[0] for point in change(line)])
            errors.append(np.abs(sm.placements(mapping, line, curve) * cumulative[-1] - truth))
        return np.concatenate(errors).mean()

    assert along_error(corrected) < 0.2 * along_error(plain)
    misses = [sum(lp.miss(mapping, line, curve) for line, curve in chains) for mapping in (plain, corrected)]
    assert misses[1] < 0.1 * misses[0]
    np.testing.assert_allclose(sm.apply(corrected, corners), change(corners), atol=0.01)  # the anchors kept
    assert corrected.degree == plain.degree and plain.bumps is None
    assert lp.corrected(plain, [], rest) is plain and lp.corrected(None, chains, rest) is None
