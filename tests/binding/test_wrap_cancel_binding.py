"""A wrap step cancelled through a ``CancelFlag``, and anchors moved between steps, through the binding (no bpy)."""

import threading

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import make_solver, plane_target, quad_layout

ANCHORS = [0, 12, 156, 168, 84]


def _solver():
    target = plane_target()
    positions, face_corners, face_sizes = quad_layout()
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    solver, hits = make_solver(target, positions, structure, ANCHORS)
    return target, solver, hits


def test_a_step_with_an_unset_flag_is_the_plain_step():
    _, plain, _ = _solver()
    _, flagged, _ = _solver()
    flag = sk.CancelFlag()
    for _ in range(5):
        assert repr(plain.step(4)) == repr(flagged.step(4, cancel=flag))  # repr: NaN equals itself
        assert plain.positions().tobytes() == flagged.positions().tobytes()


def test_a_cancelled_step_raises_the_typed_error_and_leaves_the_points_as_before():
    _, solver, _ = _solver()
    solver.step(3)
    positions, states = solver.positions(), solver.states()
    flag = sk.CancelFlag()
    flag.cancel()
    with pytest.raises(sk.CancelledError, match="wrap step cancelled"):
        solver.step(100, cancel=flag)
    assert solver.positions().tobytes() == positions.tobytes()
    assert all(a.tobytes() == b.tobytes() for a, b in zip(solver.states(), states, strict=True))
    with pytest.raises(sk.CancelledError):  # the half-stepped solver is dropped: it stays cancelled
        solver.step(1)


def test_a_flag_set_from_another_thread_stops_a_long_step():
    _, solver, _ = _solver()
    flag = sk.CancelFlag()
    timer = threading.Timer(0.0, flag.cancel)
    timer.start()
    timer.join()
    with pytest.raises(sk.CancelledError):
        solver.step(1000, cancel=flag)


def test_moved_anchors_are_met_without_building_the_solver_anew():
    target, solver, hits = _solver()
    solver.step(6)
    moved = hits.positions.copy()
    moved[-1] += np.array([0.1, -0.05, 0.0], np.float32)  # the centre anchor, along the plane
    moved_hits = target.closest_points(np.ascontiguousarray(moved))
    solver.set_anchors(
        anchor_vertices=np.asarray(ANCHORS, np.uint32),
        anchor_triangles=moved_hits.triangles,
        anchor_barycentrics=moved_hits.barycentrics,
        anchor_positions=moved_hits.positions,
    )
    report = solver.step(100)
    while not report.converged and report.total_iterations < 5000:
        report = solver.step(100)
    assert report.converged
    np.testing.assert_allclose(solver.positions()[ANCHORS], moved_hits.positions, atol=1e-5)
    with pytest.raises(sk.InvalidArgumentError, match="more than one anchor"):
        solver.set_anchors(
            anchor_vertices=np.array([0, 0], np.uint32),
            anchor_triangles=moved_hits.triangles[:2],
            anchor_barycentrics=moved_hits.barycentrics[:2],
            anchor_positions=moved_hits.positions[:2],
        )
    solver.set_anchors()  # none: the wrap goes on without anchors
    assert solver.step(100).iterations > 0
