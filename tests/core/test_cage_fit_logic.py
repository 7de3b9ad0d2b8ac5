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
    for levels in (0, 7, 99):  # never clamped to the range: refused, naming it
        with pytest.raises(errors.LayoutError, match=f"Levels must be 1 to 6, not {levels}"):
            cage_fit.fit_cage(target, positions, corners, sizes, movable, levels=levels)


def test_the_size_of_a_fit_is_estimated_and_what_will_not_fit_is_refused_naming_a_level_that_does():
    sizes = np.full(1350, 4, dtype=np.uint32)  # the body's 1,352-vertex cage: 1,350 quads
    size = cage_fit.fit_size(sizes, 6)
    assert size.points == 1350 * 4**6 and 9e9 < size.bytes < 12e9  # 5.5M points, about 10 GB measured
    assert cage_fit.fit_size(np.array([5, 3]), 1).points == 8  # an n-gon makes n quads
    assert cage_fit.check_fit_size(sizes, 6, None) == size  # memory unknown: not judged
    with pytest.raises(errors.LayoutError, match=r"Level 6 of this cage has 5,529,600 .* level 5 \(1,382,400 points"):
        cage_fit.check_fit_size(sizes, 6, 8_000_000_000)
    with pytest.raises(errors.LayoutError, match="no level fits: use a smaller cage"):
        cage_fit.check_fit_size(sizes, 2, 1_000_000)
    assert cage_fit.check_fit_size(sizes, 4, 8_000_000_000).levels == 4


class WorseningFit:
    """The kernel's fit, whose round ``bad_round`` moves the cage off the target (a round that makes it worse)."""

    def __init__(self, fit, bad_round):
        self.fit, self.bad_round, self.rounds = fit, bad_round, 0

    def __getattr__(self, name):
        return getattr(self.fit, name)

    def round(self, target, positions, offsets, cancel=None):
        self.rounds += 1
        cage, distances, trusted = self.fit.round(target, positions, offsets, cancel=cancel)
        if self.rounds == self.bad_round:
            cage = (cage * 1.3).astype(np.float32)
        return cage, distances, trusted


def test_a_round_that_makes_the_fit_worse_is_not_kept():
    target = sk.TargetMesh(*uv_sphere())
    positions, corners, sizes = cube_sphere_cage(3)
    run = cage_fit.CageFitRun(target, positions, corners, sizes, np.ones(len(positions), dtype=bool), rounds=3)
    run.fit = WorseningFit(run.fit, bad_round=3)
    distances = []
    while not run.done:
        run.step()
        distances.append(run._distances_at(run.positions, run.offsets).max)
    outcome = run.outcome()
    assert distances[2] > 1.1 * distances[1]  # the last round made it worse ...
    assert outcome.kept_round == 2 and outcome.after.max == pytest.approx(distances[1])  # ... and is not the result
    assert outcome.rounds == 3
    assert "kept round 2's cage (the later rounds made the fit worse)" in cage_fit.summary(outcome, 2, 10.0)


def test_a_smaller_mean_is_better_unless_the_max_grows_by_more_than_a_tenth():
    before = cage_fit.FitDistances(0.08, 0.60, 10, 10)
    assert cage_fit._better(cage_fit.FitDistances(0.02, 0.61, 10, 10), before)  # over a hole: the max creeps
    assert not cage_fit._better(cage_fit.FitDistances(0.07, 0.70, 10, 10), before)  # 0.60 -> 0.70: worse
    assert not cage_fit._better(cage_fit.FitDistances(0.09, 0.50, 10, 10), before)
    assert not cage_fit._better(cage_fit.FitDistances(float("nan"), float("nan"), 0, 10), before)
