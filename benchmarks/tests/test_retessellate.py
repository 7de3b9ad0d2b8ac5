"""The feature-lines benchmark's sharp re-tessellation (``benchmarks/_retessellate.py``): other triangles, the same
surface and the same sharp creases."""

import numpy as np

from benchmarks._retessellate import retessellate, split_edges
from benchmarks.feature_lines import sharp_segments


def folded_sheet(cells: int = 6):
    """A sheet of ``cells`` x ``cells`` squares folded by 90 degrees along its middle row of edges: (vertices,
    triangles, the fold's length)."""
    grid = np.linspace(0.0, 1.0, cells + 1)
    x, y = np.meshgrid(grid, grid, indexing="ij")
    half = 0.5
    z = np.where(y > half, y - half, 0.0)
    vertices = np.stack([x.ravel(), np.minimum(y, half).ravel(), z.ravel()], axis=1)
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b, c, d = index[:-1, :-1].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])
    return vertices, triangles, 1.0


def edge_set(triangles) -> set:
    return {
        tuple(sorted(map(int, pair)))
        for row in triangles
        for pair in ((row[0], row[1]), (row[1], row[2]), (row[2], row[0]))
    }


def area(vertices, triangles) -> float:
    corners = vertices[triangles]
    return float(np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum())


def sharp_length(vertices, triangles) -> float:
    segments = sharp_segments(np.asarray(vertices, dtype=np.float64), np.asarray(triangles, dtype=np.int64))
    return float(np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1).sum())


def test_the_sheet_keeps_its_surface_and_fold_under_other_triangles():
    vertices, triangles, fold = folded_sheet()
    split, corners = retessellate(vertices, triangles, seed=3)
    assert corners.shape[0] == 4 * triangles.shape[0]
    assert np.isclose(area(split, corners), area(vertices, triangles), rtol=1e-9)
    assert np.isclose(sharp_length(split, corners), fold, rtol=1e-9)
    # Every new vertex lies on the sheet: on its flat half (z = 0) or its raised half (y = 0.5).
    assert np.all(np.isclose(split[:, 2], 0.0) | np.isclose(split[:, 1], 0.5))
    # Flips inside the flat halves: some edges are not those of the plain four-way split.
    _, plain = split_edges(vertices, triangles, np.random.default_rng(3))
    assert len(edge_set(corners) - edge_set(plain)) > 0
