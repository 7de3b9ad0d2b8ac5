"""The subdivision cage fit through the kernel's Python binding (no bpy): the stencils' matrix and array
contract, the fit's rounds and refusals."""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import cube_sphere_cage, uv_sphere


def csr_apply(stencils, cage):
    """The stencils' matrix times the cage, in numpy: the reference for ``apply``."""
    offsets, vertices, weights = stencils.matrix()
    rows = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets.astype(np.int64)))
    fine = np.zeros((len(offsets) - 1, 3))
    np.add.at(fine, rows, weights[:, None] * cage.astype(np.float64)[vertices])
    return fine


@pytest.mark.parametrize("boundary", ["ALL", "PRESERVE_CORNERS"])
def test_the_matrix_is_what_apply_computes_and_each_row_is_affine(boundary):
    positions, corners, sizes = cube_sphere_cage(2)
    # An open cage: one face off, so there are borders and corners.
    corners, sizes = corners[:-4], sizes[:-1]
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2, boundary=boundary)
    assert (stencils.levels, stencils.boundary, stencils.cage_vertex_count) == (2, boundary, len(positions))
    offsets, vertices, weights = stencils.matrix()
    assert offsets.dtype == np.uint32 and weights.dtype == np.float64
    assert len(offsets) == stencils.fine_vertex_count + 1
    assert np.allclose(np.add.reduceat(weights, offsets[:-1].astype(np.int64)), 1.0)
    fine = stencils.apply(positions)
    assert fine.dtype == np.float32 and fine.shape == (stencils.fine_vertex_count, 3)
    assert np.abs(fine - csr_apply(stencils, positions)).max() < 1e-6
    quads = stencils.fine_quads()
    assert quads.shape == (len(sizes) * 16, 4) and quads.max() < stencils.fine_vertex_count
    assert stencils.on_surface().all()


def test_bad_stencil_inputs_raise_the_kernels_exceptions():
    positions, corners, sizes = cube_sphere_cage(1)
    with pytest.raises(sk.InvalidArgumentError, match="levels"):
        sk.SubdivisionStencils(len(positions), corners, sizes, 0)
    with pytest.raises(sk.InvalidArgumentError, match="Boundary Smooth"):
        sk.SubdivisionStencils(len(positions), corners, sizes, 1, boundary="SMOOTH")
    with pytest.raises(sk.ArrayError, match="uint32"):
        sk.SubdivisionStencils(len(positions), corners.astype(np.int64), sizes, 1)
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.SubdivisionStencils(3, corners, sizes, 1)
    with pytest.raises(sk.InvalidArgumentError, match="three or more faces"):
        three = np.array([0, 1, 2, 3, 1, 0, 4, 5, 0, 1, 6, 7], dtype=np.uint32)
        sk.SubdivisionStencils(8, three, np.full(3, 4, dtype=np.uint32), 1)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 1)
    with pytest.raises(sk.ArrayError, match="float32"):
        stencils.apply(positions.astype(np.float64))
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        stencils.apply(positions[:3])


def test_rounds_bring_a_sphere_cages_surface_onto_the_sphere():
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)
    fit = sk.SubdivisionFit(stencils)
    assert not fit.fixed().any()
    before = fit.distances(target, positions)
    cage = positions
    for _ in range(5):
        cage, distances, trusted = fit.round(target, cage)
        assert trusted == stencils.fine_vertex_count and distances.shape == (stencils.fine_vertex_count,)
    after = fit.distances(target, cage)
    assert np.nanmax(after) * 5.0 < np.nanmax(before)
    # The distances are the closest-point distances of the fine points.
    fine = fit.fine_points(cage)
    assert np.allclose(after, target.closest_points(fine).distances)


def test_fixed_vertices_hold_and_offsets_shift_the_fine_points():
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)
    fixed = np.arange(len(positions)) % 4 == 0
    fit = sk.SubdivisionFit(stencils, fixed=fixed, smoothness=0.5)
    offsets = np.full((stencils.fine_vertex_count, 3), 0.01, dtype=np.float32)
    assert np.allclose(fit.fine_points(positions, offsets) - fit.fine_points(positions), 0.01, atol=1e-6)
    cage, _, _ = fit.round(target, positions, offsets)
    assert cage[fixed].tobytes() == positions[fixed].tobytes()
    assert (np.linalg.norm(cage[~fixed] - positions[~fixed], axis=1) > 0).all()


def test_bad_fit_inputs_raise_the_kernels_exceptions():
    target = sk.TargetMesh(*uv_sphere(rings=8, segments=16))
    positions, corners, sizes = cube_sphere_cage(1)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 1)
    with pytest.raises(TypeError, match="SubdivisionStencils"):
        sk.SubdivisionFit("stencils")
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        sk.SubdivisionFit(stencils, fixed=np.zeros(3, dtype=bool))
    with pytest.raises(sk.ArrayError, match="bool"):
        sk.SubdivisionFit(stencils, fixed=np.zeros(len(positions), dtype=np.int32))
    settings = (("smoothness", -1.0), ("max_distance", 0.0), ("min_facing", 1.5), ("damping", float("nan")))
    for name, value in (*settings, ("anchor_weight", 0.0)):
        with pytest.raises(sk.InvalidArgumentError, match=name):
            sk.SubdivisionFit(stencils, **{name: value})
    with pytest.raises(sk.IndexOutOfRangeError, match="anchor 0"):
        sk.SubdivisionFit(
            stencils, anchor_vertices=np.array([99], np.uint32), anchor_points=np.zeros((1, 3), np.float32)
        )
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        sk.SubdivisionFit(
            stencils, anchor_vertices=np.array([1], np.uint32), anchor_points=np.zeros((2, 3), np.float32)
        )
    fit = sk.SubdivisionFit(stencils)
    bad = positions.copy()
    bad[2, 1] = np.nan
    with pytest.raises(sk.NonFiniteError, match="cage position 2"):
        fit.round(target, bad)
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        fit.round(target, positions, np.zeros((2, 3), dtype=np.float32))


def test_the_defaults_come_from_the_kernel():
    defaults = sk.subdivision_fit_defaults()
    assert set(defaults) == {"smoothness", "max_distance", "min_facing", "damping", "anchor_weight", "max_levels"}
    assert defaults["max_levels"] == 6 and defaults["max_distance"] == float("inf")
