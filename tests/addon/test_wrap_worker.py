"""The live wrap's solve off Blender's main thread, and a wrap's reads of Blender data.

The modal wrap's first frame solves on the main thread; ``WrapSession.start_worker`` then runs the rest in a worker
thread, and each later frame writes the newest positions it solved. The solver is never called from two threads at
once (PyO3 would raise "Already borrowed"), a cancel puts the layout back bit for bit, a finish ends exactly where a
synchronous run does, an error in the worker restores the layout. One Wrap reads the layout, its anchors, its curve
constraints and its target from Blender once each, and a live frame reads none of them.
"""

import threading
import time

import bpy

import numpy as np
import pytest

from bpy_helpers import anchor_snapshot, plane_scene, snapshot, wrap_session, wrapped_at_once

ITERATION_SECONDS = 0.01
"""What each of the solver's iterations costs at least here: the plane's wrap ends in about ten iterations, which
a quiet machine solves before the test has looked at the worker it started; slowed, the worker's chunks are an
iteration or two (they are sized from the measured cost) and the wrap outlasts the checks on any machine."""


class _OneThreadAtATime:
    """Wraps the kernel's solver, records every call made while another thread was inside it, and slows its steps
    (:data:`ITERATION_SECONDS`)."""

    def __init__(self, solver):
        self._solver, self._lock, self.overlaps, self.threads = solver, threading.Lock(), [], set()

    def __getattr__(self, name):
        attribute = getattr(self._solver, name)
        if not callable(attribute):
            return attribute

        def call(*args, **kwargs):
            if name == "step":
                time.sleep(ITERATION_SECONDS * max(int(args[0]) if args else 1, 1))
            if not self._lock.acquire(blocking=False):
                self.overlaps.append(name)
                return attribute(*args, **kwargs)
            try:
                self.threads.add(threading.get_ident())
                return attribute(*args, **kwargs)
            finally:
                self._lock.release()

        return call


def _threaded_loop(layout, **keywords):
    """A ``WrapLoop`` as the operator's ``invoke`` leaves it: one frame solved here, the rest in the worker."""
    from springwrap.core.wrap_run import WrapLoop

    session = wrap_session(layout, **keywords)
    session.solver = _OneThreadAtATime(session.solver)
    loop = WrapLoop(session)
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    session.start_worker()
    assert session.worker is not None and session.worker.running
    return loop


def _frames(loop, count, seconds=60.0):
    """Timer events until ``count`` more frames were written or the wrap ended; the last outcome."""
    target, outcome, start = loop.session.frames + count, "RUNNING_MODAL", time.perf_counter()
    while outcome == "RUNNING_MODAL" and loop.session.frames < target and time.perf_counter() - start < seconds:
        outcome = loop.handle("TIMER")
        time.sleep(0.002)  # the main thread's redraw
    return outcome


def test_the_worker_finishes_where_a_synchronous_wrap_ends():
    plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    loop = _threaded_loop(bpy.context.active_object)
    outcome = "RUNNING_MODAL"
    while outcome == "RUNNING_MODAL":
        outcome = _frames(loop, 1)
    assert outcome == "FINISHED" and loop.result.converged and loop.result.frames >= 2
    assert loop.session.worker is None
    assert not loop.session.solver.overlaps and len(loop.session.solver.threads) == 2  # main, then the worker
    live = snapshot(bpy.data.objects["Layout"])
    assert live == wrapped_at_once()


@pytest.mark.parametrize("key", ["ESC", "RIGHTMOUSE"])
def test_cancel_stops_the_worker_and_restores_the_layout_bit_for_bit(key):
    target, layout, _normal = plane_scene(subdivisions=120)  # a wrap long enough to be stopped mid-way
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before, anchors_before = snapshot(layout), anchor_snapshot(layout)
    loop = _threaded_loop(layout)
    assert _frames(loop, 2) == "RUNNING_MODAL"
    assert snapshot(layout)["positions"] != before["positions"]  # the worker's frames were written
    worker = loop.session.worker
    assert loop.handle(key, "PRESS") == "CANCELLED"
    assert not worker.running and loop.session.worker is None
    assert snapshot(layout) == before and anchor_snapshot(layout) == anchors_before
    assert not loop.session.solver.overlaps
    assert loop.handle("TIMER") == "CANCELLED"


def test_an_error_in_the_worker_restores_the_layout():
    import springwrap_kernel

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    loop = _threaded_loop(layout)
    solver, calls = loop.session.solver._solver, []

    class Failing:
        def step(self, iterations, **keywords):
            calls.append(iterations)
            if len(calls) > 3:
                raise springwrap_kernel.InternalError("simulated failure")
            return solver.step(iterations, **keywords)

        def __getattr__(self, name):
            return getattr(solver, name)

    loop.session.solver._solver = Failing()
    assert _frames(loop, 1000) == "CANCELLED"
    assert "simulated failure" in str(loop.error)
    assert snapshot(layout) == before


def test_esc_cuts_the_kernels_step_in_progress_short_and_restores_the_layout_bit_for_bit():
    import springwrap_kernel

    target, layout, _normal = plane_scene(subdivisions=120)
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    loop = _threaded_loop(layout)
    solver, entered, raised = loop.session.solver._solver, threading.Event(), []

    class Slow:
        """A step that waits before the kernel's: Esc comes while it runs."""

        def step(self, iterations, **keywords):
            entered.set()
            time.sleep(0.3)
            try:
                return solver.step(iterations, **keywords)
            except springwrap_kernel.CancelledError as error:
                raised.append(error)
                raise

        def __getattr__(self, name):
            return getattr(solver, name)

    loop.session.solver._solver = Slow()
    assert entered.wait(30.0)
    worker = loop.session.worker
    assert loop.handle("ESC", "PRESS") == "CANCELLED"
    assert worker.interrupted and worker.error is None and loop.error is None
    assert len(raised) == 1 and "wrap step cancelled" in str(raised[0])
    assert snapshot(layout) == before
    with pytest.raises(springwrap_kernel.CancelledError):  # the half-stepped solver was dropped
        solver.step(1)


def test_an_anchor_moved_while_the_worker_runs_is_met_by_the_same_solver():
    from springwrap.core import anchors, layout_state

    target, layout, normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    loop = _threaded_loop(layout, tolerance=1e-9)
    session = loop.session
    solver = session.solver
    along = np.cross(np.asarray(normal, dtype=np.float64), [1.0, 0.0, 0.0])
    moved = session.anchors
    index = 0
    location = moved.locations[index] + 0.15 * along / np.linalg.norm(along)  # on the plane, moved along it
    moved = moved._replace(
        kinds=np.where(np.arange(len(moved.kinds)) == index, anchors.SPACE_ANCHOR, moved.kinds).astype(np.int32),
        triangles=np.where(np.arange(len(moved.kinds)) == index, layout_state.NO_FACE, moved.triangles).astype(
            np.int32
        ),
        locations=np.where(np.arange(len(moved.kinds))[:, None] == index, location, moved.locations),
    )
    assert session.move_anchors(moved)
    outcome = "RUNNING_MODAL"
    while outcome == "RUNNING_MODAL":
        outcome = _frames(loop, 1)
    assert outcome == "FINISHED" and loop.result.converged
    assert session.solver is solver and not solver.overlaps  # the same solver, edited by its own thread
    vertex = int(moved.vertex_indices[index])
    world = np.array(layout.matrix_world) @ np.append(layout.data.vertices[vertex].co[:], 1.0)
    np.testing.assert_allclose(world[:3], location, atol=1e-4)
    np.testing.assert_allclose(layout.springwrap.anchors[index].location, location, atol=1e-5)  # finish wrote it


def test_an_anchor_moved_after_the_worker_ended_solves_in_a_new_worker_not_on_the_main_thread():
    target, layout, normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    loop = _threaded_loop(layout)
    session = loop.session
    start = time.perf_counter()
    while session.worker is not None and time.perf_counter() - start < 60.0:
        session.advance()  # the frames the operator's timer draws, until the worker's end is seen
        time.sleep(0.002)
    assert session.worker is None and session.done  # ended; the operator has not finished it yet
    moved = session.anchors
    moved = moved._replace(locations=moved.locations + 0.05 * np.asarray(normal, dtype=np.float64))
    assert session.move_anchors(moved)
    assert not session.done and session.worker is not None  # the schedule goes on, off the main thread
    outcome = "RUNNING_MODAL"
    while outcome == "RUNNING_MODAL":
        outcome = _frames(loop, 1)
    assert outcome == "FINISHED" and loop.result.converged


def test_pair_tool_edit_finishes_the_running_re_settle_between_two_iterations():
    from springwrap.blender import pair_tool

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    settle = wrap_session(layout, tolerance=1e-9, max_iterations=100_000)
    settle.solver = _OneThreadAtATime(settle.solver)
    pair_tool.advance_settle(settle)
    assert settle.worker is not None and settle.worker.running  # the rest solves in the worker
    while settle.frames < 3:
        pair_tool.advance_settle(settle)
        time.sleep(0.002)
    result = settle.finish()  # what an edit does first: keep the re-settle as it is now
    assert settle.worker is None and not settle.solver.overlaps
    positions = np.array([v.co[:] for v in layout.data.vertices])
    assert result.iterations == settle.total_iterations >= 3
    assert not np.isnan(positions).any()


# ---------------------------------------------------------------- reads of Blender data


def _count_reads(monkeypatch):
    """Counts of the calls to the functions that read the layout, its anchors and curves, and its target."""
    from springwrap.blender import anchors, attributes, curves, layout, shape_keys, target

    counts = {}
    for module, name in (
        (layout, "read_layout"),
        (layout, "read_layout_topology"),
        (layout, "read_positions"),  # read_layout's, or a read-back of what was written
        (attributes, "read_rest"),
        (shape_keys, "read"),
        (anchors, "read_anchors"),
        (curves, "read_curve_constraints"),
        (target, "read_target"),
    ):
        original = getattr(module, name)

        def counted(*args, _original=original, _name=name, **kwargs):
            counts[_name] = counts.get(_name, 0) + 1
            return _original(*args, **kwargs)

        monkeypatch.setattr(module, name, counted)
    return counts


@pytest.mark.parametrize("hold_plane", ["NONE", "X"])
def test_one_wrap_reads_the_layout_and_the_target_once(monkeypatch, hold_plane):
    plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    counts = _count_reads(monkeypatch)
    assert bpy.ops.springwrap.wrap(hold_plane=hold_plane) == {"FINISHED"}
    assert counts == ONE_WRAP_READS


ONE_WRAP_READS = {
    "read_layout": 1,
    "read_layout_topology": 1,
    "read_positions": 1,
    "read_rest": 1,
    "read": 1,  # the shape keys (none here)
    "read_anchors": 1,
    "read_curve_constraints": 1,
    "read_target": 1,
}
"""The reads of one wrap of a layout: each once (the positions inside ``read_layout``)."""


@pytest.mark.parametrize("with_shape_keys", [False, True])
def test_a_half_s_wrap_reads_once_and_says_its_midline_drift_from_what_it_wrote(monkeypatch, capfd, with_shape_keys):
    """A half wrapped without Hold on Plane: the midline is found from the topology the wrap read, its drift
    measured on the positions the wrap wrote (the number said is the layout's as it now is), the rest shape read
    once, the result written without reading the mesh back (the shape keys carried from the keys read at the
    start)."""
    from bpy_helpers import head_scene, midline_drift

    _target, layout = head_scene()
    midline = np.flatnonzero(np.array([vertex.co[0] for vertex in layout.data.vertices]) == 0.0)
    if with_shape_keys:
        layout.shape_key_add(name="Basis")
        layout.shape_key_add(name="Key 1")
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    counts = _count_reads(monkeypatch)
    capfd.readouterr()
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    said = capfd.readouterr().out
    assert counts == ONE_WRAP_READS
    drift = midline_drift(layout, midline)
    assert drift > 0.0
    said_drift = f"({midline.size} vertices: a half's midline?); the wrap moved it up to {drift:.3g} off the plane"
    assert said_drift in said, said
    assert layout.data.attributes.get("springwrap_rest") is not None  # the template's shape stored at the first write
    if with_shape_keys:
        basis = np.array([point.co[:] for point in layout.data.shape_keys.key_blocks["Basis"].data])
        assert np.array_equal(basis, np.array([vertex.co[:] for vertex in layout.data.vertices]))


def test_live_frames_read_nothing_again(monkeypatch):
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    loop = _threaded_loop(layout)
    counts = _count_reads(monkeypatch)
    _frames(loop, 3)
    loop.cancel()
    assert counts == {}


@pytest.mark.parametrize("operator", ["snap", "project", "detach"])
def test_a_snap_reads_the_layout_and_the_target_once(monkeypatch, operator):
    """The snap's checks, its solve and its read-out share one read; the storage check uses what it wrote."""
    plane_scene()
    counts = _count_reads(monkeypatch)
    assert getattr(bpy.ops.springwrap, operator)() == {"FINISHED"}
    assert counts.get("read_layout") == 1 and counts.get("read_target") == 1
    assert counts.get("read_layout_topology", 0) <= 1  # the read-out's faces (none read by a detach)
