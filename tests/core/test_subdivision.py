"""The wrap's spring resolution: a layout subdivided k x k (pure numpy, no Blender)."""

import numpy as np
import pytest

from helpers import core_module

subdivision = core_module("subdivision")


def grid_topology(side):
    """A side x side quad grid (vertices row by row) with a triangle fan cap on one corner and a loose chain."""
    n = side + 1
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(side) for i in range(side)]
    vertices = np.array([(i, j, 0.0) for j in range(n) for i in range(n)], dtype=np.float64)
    return quads, vertices


def topology_of(faces, vertex_count, edges=(), seams=()):
    return subdivision.LayoutTopology(
        vertex_count,
        np.array([c for f in faces for c in f], dtype=np.uint32),
        np.array([len(f) for f in faces], dtype=np.uint32),
        np.array(edges, dtype=np.uint32).reshape(-1, 2),
        np.array(seams, dtype=np.uint32).reshape(-1, 2),
    )


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_a_quad_grid_becomes_a_k_times_finer_grid(k):
    quads, vertices = grid_topology(3)
    fine = subdivision.subdivide(topology_of(quads, len(vertices)), k)
    side = 3 * k
    assert fine.topology.vertex_count == (side + 1) ** 2
    assert len(fine.topology.face_sizes) == side * side and (fine.topology.face_sizes == 4).all()
    positions = fine.interpolate(vertices)
    np.testing.assert_array_equal(positions[: len(vertices)], vertices)  # the layout's vertices come first
    # Every fine point is a distinct node of the k-times finer lattice.
    lattice = np.round(positions[:, :2] * k).astype(int)
    assert len({tuple(p) for p in lattice}) == fine.topology.vertex_count
    np.testing.assert_allclose(positions[:, :2] * k, lattice, atol=1e-9)
    # Fine quads are unit cells of that lattice, wound like the layout's (counter-clockwise).
    corners = positions[fine.topology.face_corners.astype(np.int64).reshape(-1, 4)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 3] - corners[:, 0])
    np.testing.assert_allclose(normals[:, 2], 1.0 / k**2)
    np.testing.assert_allclose(fine.weights.sum(axis=1), 1.0)


def test_other_polygons_keep_their_corners_and_take_the_cut_edges_points():
    faces = [(0, 1, 2, 3), (1, 4, 2)]  # a quad and a triangle sharing the edge 1-2
    fine = subdivision.subdivide(topology_of(faces, 5), 2)
    sizes = fine.topology.face_sizes
    assert sorted(sizes.tolist()) == [4, 4, 4, 4, 6]
    assert fine.topology.vertex_count == 5 + 6 + 1  # 6 edges (one shared) cut once, one quad centre
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    hexagon = fine.topology.face_corners[int(starts[sizes == 6][0]) :][:6].tolist()
    assert hexagon[0::2] == [1, 4, 2]  # corners in order, each followed by its edge's midpoint
    middle_12 = fine.points_inside(1, 2)[0]
    assert middle_12 in hexagon and middle_12 in fine.topology.face_corners[:16].tolist()  # shared with the quad


def test_chains_seams_and_loose_edges_are_cut_too():
    quads, vertices = grid_topology(2)
    loose = [(9, 10), (10, 11)]
    fine = subdivision.subdivide(topology_of(quads, 12, edges=loose, seams=[(0, 1), (1, 2)]), 3)
    assert len(fine.topology.seams) == 6 and len(fine.topology.edges) == 6
    chain = fine.expand_chain(np.array([11, 10, 9]))
    assert chain[0] == 11 and chain[-1] == 9 and len(chain) == 7
    assert list(chain[1:3]) == list(fine.points_inside(11, 10)) == list(fine.points_inside(10, 11)[::-1])
    assert fine.points_inside(0, 11) is None  # no such edge


def test_resolution_out_of_range_is_refused():
    quads, vertices = grid_topology(1)
    with pytest.raises(ValueError, match="within 1 .. 8, not 9"):
        subdivision.subdivide(topology_of(quads, len(vertices)), 9)


def test_a_chains_placements_spread_evenly_over_the_points_cut_into_its_edges():
    expanded = core_module("wrap_inputs")._expanded_fractions
    chain, fine_chain = np.array([3, 7, 5]), np.array([3, 20, 21, 7, 22, 5])  # 20..22: points cut into its edges
    np.testing.assert_allclose(expanded(chain, fine_chain, np.array([0.0, 0.6, 0.9])), [0.0, 0.2, 0.4, 0.6, 0.75, 0.9])
    assert np.isnan(expanded(chain, fine_chain, np.full(3, np.nan))).all()  # as spaced stays as spaced
