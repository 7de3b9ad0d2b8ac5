"""The live wrap's worker thread without Blender or the kernel: ``core.wrap_run.SolveWorker`` steps, publishes the
newest snapshot to the main thread, stops between two steps and hands its error over."""

import threading

import pytest

from helpers import core_module

wrap_run = core_module("wrap_run")


class _Solve:
    """A stand-in solve: each step counts one iteration (the thread that ran it is recorded); done at ``limit``."""

    def __init__(self, limit=None, fail_at=None):
        self.iterations, self.limit, self.fail_at = 0, limit, fail_at
        self.threads = set()
        self.proceed = threading.Semaphore(0)  # steps wait for the test to let them run

    def step(self, seconds):
        assert seconds == 0.01
        self.proceed.acquire()
        self.threads.add(threading.get_ident())
        self.iterations += 1
        if self.iterations == self.fail_at:
            raise RuntimeError("simulated failure")

    def snapshot(self):
        return self.iterations

    def done(self):
        return self.limit is not None and self.iterations >= self.limit


def _wait_for(worker, serial):
    while worker._serial < serial and worker.running:
        threading.Event().wait(0.001)


def test_the_worker_solves_in_its_own_thread_and_publishes_the_newest_snapshot():
    solve = _Solve(limit=5)
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    assert worker.take() is None  # nothing solved yet
    solve.proceed.release(2)
    _wait_for(worker, 2)
    assert worker.take() == 2  # the newest of the two, once
    assert worker.take() is None
    solve.proceed.release(3)
    _wait_for(worker, 5)
    worker.stop()
    assert not worker.running and worker.error is None
    assert worker.take() == 5 and solve.iterations == 5  # done: it stopped by itself
    assert solve.threads and threading.get_ident() not in solve.threads


def test_stop_waits_for_the_step_in_progress_and_runs_no_other():
    solve = _Solve()
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    solve.proceed.release(1)
    _wait_for(worker, 1)
    solve.proceed.release(100)  # the next step may start; stop lets it end, then nothing more
    worker.stop()
    assert not worker.running
    assert solve.iterations in (1, 2)


def test_an_error_in_the_worker_is_kept_for_the_main_thread():
    solve = _Solve(fail_at=2)
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    solve.proceed.release(5)
    worker._thread.join()
    assert not worker.running
    with pytest.raises(RuntimeError, match="simulated failure"):
        raise worker.error
    assert worker.take() == 1  # what it solved before the failure


def test_submitted_edits_run_in_the_worker_between_two_steps_and_revive_a_done_solve():
    solve = _Solve(limit=2)
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    edits = []

    def edit():
        edits.append((threading.get_ident(), solve.iterations))
        solve.limit = 4  # an edit may leave more to solve

    assert worker.submit(edit)
    solve.proceed.release(4)
    _wait_for(worker, 4)
    worker.stop()
    assert len(edits) == 1 and edits[0][0] != threading.get_ident()  # applied by the worker's thread
    assert edits[0][1] in (0, 1, 2) and solve.iterations == 4  # between steps, and the solve went on to 4
    assert not worker.submit(edit)  # stopped: the caller applies it itself
    assert worker.pending() == []


def test_edits_left_when_the_worker_stops_are_handed_back_in_order():
    solve = _Solve()
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    solve.proceed.release(1)
    _wait_for(worker, 1)  # the worker now waits inside its second step
    first, second = (lambda: None), (lambda: None)
    assert worker.submit(first) and worker.submit(second)
    worker._stop.set()  # asked to stop while the step runs: it applies nothing after it
    solve.proceed.release(1)
    worker.stop()
    assert worker.pending() == [first, second]


def test_edits_of_one_key_coalesce_the_newest_wins_in_the_first_ones_place():
    solve = _Solve()
    worker = wrap_run.SolveWorker(solve.step, solve.snapshot, solve.done, 0.01)
    solve.proceed.release(1)
    _wait_for(worker, 1)  # the worker now waits inside its second step: nothing submitted is applied yet
    moves = [(lambda: None) for _ in range(50)]  # a drag's mouse moves, faster than the steps
    other = lambda: None  # noqa: E731
    assert worker.submit(moves[0], key="anchors") and worker.submit(other)
    assert all(worker.submit(move, key="anchors") for move in moves[1:])
    worker._stop.set()
    solve.proceed.release(1)
    worker.stop()
    assert worker.pending() == [moves[-1], other]  # one edit per key, where the first one was


class _Interrupted(Exception):
    """Stands in for the kernel's CancelledError."""


def test_an_interrupt_cuts_the_step_short_and_ends_the_thread_quietly():
    flag = threading.Event()

    def step(seconds):
        flag.wait()  # a long step, until interrupted
        raise _Interrupted("wrap step cancelled")

    worker = wrap_run.SolveWorker(step, lambda: None, lambda: False, 0.01, flag.set, _Interrupted)
    seconds = worker.stop(interrupt=True)
    assert not worker.running and worker.interrupted and worker.error is None
    assert seconds < 5.0


def test_a_failure_that_is_not_the_interrupt_is_kept():
    def step(seconds):
        raise RuntimeError("simulated failure")

    worker = wrap_run.SolveWorker(step, lambda: None, lambda: False, 0.01, lambda: None, _Interrupted)
    worker._thread.join()
    worker.stop(interrupt=True)
    assert isinstance(worker.error, RuntimeError) and not worker.interrupted
