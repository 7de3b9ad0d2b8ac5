"""The cage fit's logic on arrays (``core.cage_fit``, no Blender): which vertices move, the distances
reported, the pairing of another numbering of the subdivided points with the stencils', the rounds."""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import core_module, cube_sphere_cage, uv_sphere

cage_fit = core_module("cage_fit")
errors = core_module("errors")


def test_movable_vertices_are_on_a_face_and_selected_when_asked():
    on_face = np.array([True, True, True, False])
    selection = np.array([True, True, False, True])
    assert cage_fit.movable_mask(4, on_face, selection, False).tolist() == [True, True, True, False]
    assert cage_fit.movable_mask(4, on_face, selection, True).tolist() == [True, True, False, False]


def test_summaries_leave_out_the_points_with_no_distance():
    summary = cage_fit.summarize(np.array([1.0, np.nan, 3.0]))
    assert summary == cage_fit.FitDistances(2.0, 3.0, 2, 3)
    nothing = cage_fit.summarize(np.array([np.nan]))
    assert np.isnan(nothing.mean) and nothing.matched == 0


def shuffled_subdivision(stencils, cage, seed=3):
    """The stencils' points in another order (as Blender numbers them its own way), and its triangles."""
    order = np.random.default_rng(seed).permutation(stencils.fine_vertex_count)
    inverse = np.argsort(order)
    quads = inverse[stencils.fine_quads().astype(np.int64)]
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)
    return stencils.apply(cage)[order].astype(np.float64), triangles, order


def test_another_numbering_of_the_same_points_is_paired_back():
    positions, corners, sizes = cube_sphere_cage(2)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)
    points, triangles, order = shuffled_subdivision(stencils, positions)
    matching = cage_fit.match_fine_points(stencils.apply(positions), stencils.fine_quads(), points, triangles)
    assert matching is not None and (order[matching] == np.arange(stencils.fine_vertex_count)).all()
    # Points that are not the same surface's are not paired.
    moved = points + np.random.default_rng(1).normal(scale=0.05, size=points.shape)
    assert cage_fit.match_fine_points(stencils.apply(positions), stencils.fine_quads(), moved, triangles) is None
    assert cage_fit.match_fine_points(stencils.apply(positions), stencils.fine_quads(), points[:10], triangles) is None
    # Two points at one place (cage vertices snapped onto one target point): either pairing is right, and the
    # nearest-point query gives both the same partner.
    fine = stencils.apply(positions).astype(np.float64)
    fine[5] = fine[6]
    points, triangles, order = shuffled_subdivision(stencils, positions)
    points[np.argsort(order)[5]] = fine[6]
    matching = cage_fit.match_fine_points(fine, stencils.fine_quads(), points, triangles)
    assert matching is not None and matching[5] == matching[6]
    assert np.abs(points[matching] - fine).max() < 1e-6


def test_a_fit_with_blenders_points_in_another_order_is_the_fit_of_the_stencils():
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    movable = np.ones(len(positions), dtype=bool)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)

    def evaluate(cage):
        points, triangles, _ = shuffled_subdivision(stencils, cage)
        return points, triangles

    plain = cage_fit.fit_cage(target, positions, corners, sizes, movable)
    paired = cage_fit.fit_cage(target, positions, corners, sizes, movable, evaluate=evaluate)
    assert paired.exact and not plain.exact
    assert np.abs(paired.positions - plain.positions).max() < 1e-4
    assert plain.after.max * 5.0 < plain.before.max
    assert plain.rounds == cage_fit.DEFAULT_ROUNDS and plain.fine_vertex_count == stencils.fine_vertex_count
    assert "level-2" in cage_fit.summary(plain, 2, 12.0)


def test_anchors_pull_their_vertices_limit_points_onto_their_points():
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    points = np.array([[0.0, 0.0, 1.0], positions[9] * 1.0])
    vertices = np.array([np.argmax(positions[:, 2]), 9])
    points[0] = positions[vertices[0]]
    outcome = cage_fit.fit_cage(
        target,
        positions,
        corners,
        sizes,
        np.ones(len(positions), dtype=bool),
        anchor_vertices=vertices,
        anchor_points=points,
    )
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)
    fine = stencils.apply(outcome.positions.astype(np.float32))
    assert np.linalg.norm(fine[vertices] - points, axis=1).max() < 2e-3
    assert outcome.anchors == 2


def test_blenders_own_offsets_are_fitted_away():
    """Where Blender's points differ from the stencils' (a fixed offset here), the fit puts Blender's on the target."""
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    stencils = sk.SubdivisionStencils(len(positions), corners, sizes, 2)
    order = np.arange(stencils.fine_vertex_count)
    quads = stencils.fine_quads()
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)

    def evaluate(cage):
        return stencils.apply(cage)[order].astype(np.float64) + 0.002, triangles

    outcome = cage_fit.fit_cage(
        target, positions, corners, sizes, np.ones(len(positions), dtype=bool), evaluate=evaluate
    )
    exact = evaluate(outcome.positions.astype(np.float32))[0]
    assert np.abs(target.closest_points(exact.astype(np.float32)).distances).max() < outcome.before.max / 5.0


def test_refusals_name_the_problem():
    target = sk.TargetMesh(*uv_sphere(rings=8, segments=16))
    positions, corners, sizes = cube_sphere_cage(1)
    movable = np.ones(len(positions), dtype=bool)
    with pytest.raises(errors.LayoutError, match="at least one round"):
        cage_fit.fit_cage(target, positions, corners, sizes, movable, rounds=0)
    bad = positions.copy()
    bad[1, 0] = np.inf
    with pytest.raises(errors.LayoutError, match="NaN or infinite"):
        cage_fit.fit_cage(target, bad, corners, sizes, movable)
    with pytest.raises(sk.InvalidArgumentError, match="levels"):
        cage_fit.fit_cage(target, positions, corners, sizes, movable, levels=7)
