"""Openings on arrays (``addon/springwrap/core/openings.py``): closed edge loops, slits (loops whose halves touch)
and a slit paired with the rims of an opening the target has there, found by rays. No Blender."""

import numpy as np

from helpers import core_module

openings = core_module("openings")
cu = core_module("curves")
target_module = core_module("target")


def torus(rings, sides):
    """A quad torus: (V, 3) and (F, 4), ``rings`` loops round the tube and ``sides`` along it."""
    u, v = np.meshgrid(np.arange(rings) * 2 * np.pi / rings, np.arange(sides) * 2 * np.pi / sides, indexing="ij")
    points = np.stack([(2 + np.cos(v)) * np.cos(u), (2 + np.cos(v)) * np.sin(u), np.sin(v)], -1).reshape(-1, 3)
    index = np.arange(rings * sides).reshape(rings, sides)
    quads = np.stack(
        [index, np.roll(index, -1, 0), np.roll(np.roll(index, -1, 0), -1, 1), np.roll(index, -1, 1)], -1
    ).reshape(-1, 4)
    return points, quads


def ring(count, half_width, half_height, z=0.0):
    """(count, 3) points of an ellipse in the plane at height ``z``, starting at a corner (+x)."""
    angle = np.arange(count) * 2 * np.pi / count
    return np.stack([half_width * np.cos(angle), half_height * np.sin(angle), np.full(count, z)], -1)


def pit_target(half_width=0.6, half_height=0.3, depth=1.0, n=120):
    """A height field over [-1, 1]^2 at z = 0, with a rectangular pit ``depth`` deep (an open mouth seen from +z)."""
    steps = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(steps, steps, indexing="ij")
    z = np.where((np.abs(x) < half_width) & (np.abs(y) < half_height), -depth, 0.0)
    points = np.stack([x, y, z], -1).reshape(-1, 3)
    index = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
    triangles = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return target_module.CentredMesh(points, triangles.astype(np.uint32))


def test_every_closed_edge_loop_of_a_torus_is_found_once():
    points, quads = torus(12, 8)
    loops = openings.closed_loops(quads.reshape(-1), np.full(len(quads), 4))
    assert sorted(loop.size for loop in loops) == [8] * 12 + [12] * 8
    assert len({tuple(sorted(loop.tolist())) for loop in loops}) == 20


def quad_cube(n):
    """(F, 4) the quads of a cube's surface, ``n`` x ``n`` a face, its vertices shared along the edges."""
    numbers, quads = {}, []
    grid = np.linspace(-1.0, 1.0, n + 1)
    for axis in range(3):
        u, v = [other for other in range(3) if other != axis]
        for sign in (-1.0, 1.0):
            for i in range(n):
                for j in range(n):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        point = [0.0, 0.0, 0.0]
                        point[axis], point[u], point[v] = sign, grid[i + di], grid[j + dj]
                        quad.append(numbers.setdefault(tuple(point), len(numbers)))
                    quads.append(quad if sign > 0 else quad[::-1])
    return np.array(quads)


def test_the_loops_of_a_cube_go_round_it_past_its_corners_and_a_grid_with_a_border_has_none():
    quads = quad_cube(6)
    loops = openings.closed_loops(quads.ravel(), np.full(len(quads), 4))
    # 5 loops round the cube in each of its 3 directions, 24 vertices each; none through a corner (3 edges).
    assert len(loops) == 15 and all(loop.size == 24 for loop in loops)
    assert len({tuple(sorted(loop.tolist())) for loop in loops}) == 15
    assert openings.closed_loops(quads[:36].ravel(), np.full(36, 4)) == []


def test_a_loop_whose_halves_touch_is_a_slit_and_a_round_one_is_not():
    closed_lips = ring(24, 0.5, 0.004)
    slit = openings.find_slit(np.arange(24), closed_lips)
    assert slit is not None and slit.corner == 12 and slit.gap < 0.02
    assert openings.find_slit(np.arange(24), ring(24, 0.5, 0.3)) is None


def test_a_slit_is_paired_with_the_rims_of_the_opening_each_half_with_its_own():
    closed_lips = ring(24, 0.5, 0.004)
    slit = openings.find_slit(np.arange(24), closed_lips)
    pair = openings.pair_slit(pit_target(), slit, closed_lips, closed_lips, np.array([0.0, 0.0, 1.0]))
    assert pair is not None and len(pair.constraints) == 2 and pair.confidence > 0.9
    for constraint in pair.constraints:
        side = np.sign(closed_lips[constraint.layout_vertices, 1].sum())
        inner = constraint.points[np.abs(constraint.points[:, 0]) < 0.35]
        # The rim on the half's own side, on the pit's edge (to within the rays' bisection), at the surface.
        assert np.allclose(inner[:, 1], side * 0.3, atol=0.02), inner
        assert np.allclose(inner[:, 2], 0.0, atol=0.06)
    # The corners are held by one constraint only.
    first, second = (set(c.layout_vertices.tolist()) for c in pair.constraints)
    assert not first & second and first | second == set(range(24))


def test_a_slit_over_a_closed_surface_or_an_opening_no_wider_stays_free():
    closed_lips = ring(24, 0.5, 0.004)
    slit = openings.find_slit(np.arange(24), closed_lips)
    facing = np.array([0.0, 0.0, 1.0])
    assert openings.pair_slit(pit_target(depth=0.0), slit, closed_lips, closed_lips, facing) is None
    # Already open as wide as the target: each half (but the corners) on the pit's edge.
    opened = closed_lips.copy()
    opened[:, 1] = np.sign(opened[:, 1]) * 0.3
    assert openings.pair_slit(pit_target(), slit, closed_lips, opened, facing) is None


def test_with_a_map_each_half_of_a_slit_goes_along_its_rim_as_far_across_as_the_map_takes_it():
    """An identity map: each vertex of the closed lips goes to the rim's point as far across the opening as it lies
    between the corners (not to the rim's nearest point, nor where the lips' spacing puts it)."""
    closed_lips = ring(24, 0.5, 0.004)
    slit = openings.find_slit(np.arange(24), closed_lips)
    corners = closed_lips[[0, 6, 12, 18, 3, 9]] + np.array([[0, 0, 0]] * 4 + [[0, 0, 0.5]] * 2)  # not in a plane
    mapping = core_module("smooth_map").fit(corners, corners)
    pair = openings.pair_slit(pit_target(), slit, closed_lips, closed_lips, np.array([0.0, 0.0, 1.0]), mapping)
    spaced = openings.pair_slit(pit_target(), slit, closed_lips, closed_lips, np.array([0.0, 0.0, 1.0]))
    for placed, as_spaced in zip(pair.constraints, spaced.constraints):
        chain = placed.layout_vertices
        assert placed.fractions.size == chain.size and as_spaced.fractions.size == 0
        assert np.all(np.diff(placed.fractions) >= 0.0)
        points = cu.arc_length_points(closed_lips[chain], placed.points, placed.fractions)
        inner = np.abs(points[:, 0]) < 0.35  # within the pit's width, where the rim runs straight across
        np.testing.assert_allclose(points[inner, 0], closed_lips[chain][inner, 0], atol=0.02)
