"""The batch scheduler (``run_tasks`` of blender_scripts/retarget_batch.py) with a stand-in executor.

No Blender and no processes: stand-in workers answer at once, die on the meshes they are told to
(``WorkerFault``), or send this process the SIGINT a Ctrl-C would. What is checked: a mesh whose worker
faults is retried once, on the replacement worker and nowhere else; a second fault fails it; a worker
that cannot start is not replaced; a Ctrl-C stops every worker at once and leaves the rest not run.
The end-to-end versions, with real workers, are in test_retarget_cli.py.
"""

import concurrent.futures
import io
import os
import signal

import retarget_batch


def settled(value=None, error=None) -> concurrent.futures.Future:
    future = concurrent.futures.Future()
    if error is not None:
        future.set_exception(error)
    else:
        future.set_result(value)
    return future


class StandInWorker:
    """Answers at once; asks its executor what each mesh does to it."""

    def __init__(self, executor: "StandInExecutor", number: int) -> None:
        self.executor, self.number = executor, number
        self.served: list[str] = []
        self.stopped_now: bool | None = None

    def ready(self) -> concurrent.futures.Future:
        if self.number in self.executor.cannot_start:
            return settled(error=retarget_batch.WorkerFault("no bpy here", died=True))
        return settled({"worker": f"stand-in:{self.number}", "import_seconds": 0.1, "peak_memory_mb": 100.0})

    def submit(self, task: dict) -> concurrent.futures.Future:
        name = task["target"]
        self.served.append(name)
        if name == self.executor.interrupt_on:
            os.kill(os.getpid(), signal.SIGINT)
        if self.executor.faults.get(name, 0) > 0:
            self.executor.faults[name] -= 1
            return settled(error=retarget_batch.WorkerFault(f"worker {self.number} died", died=name != "odd"))
        entry = {"target": name, "status": "ok", "seconds": 0.0, "worker": f"stand-in:{self.number}"}
        return settled({"entry": entry, "peak_memory_mb": 100.0 + len(self.served)})

    def stop(self, now: bool = False) -> None:
        self.stopped_now = now


class StandInExecutor:
    name = "stand-in"

    def __init__(
        self,
        faults: dict[str, int] | None = None,
        cannot_start: set[int] = frozenset(),
        interrupt_on: str | None = None,
    ) -> None:
        self.faults = dict(faults or {})
        self.cannot_start, self.interrupt_on = cannot_start, interrupt_on
        self.workers: list[StandInWorker] = []

    def start_worker(self) -> StandInWorker:
        worker = StandInWorker(self, len(self.workers) + 1)
        self.workers.append(worker)
        return worker


def run(executor: StandInExecutor, names: str, jobs: int = 2) -> tuple[retarget_batch.BatchOutcome, str]:
    stream = io.StringIO()  # not a terminal: plain lines
    tasks = [{"target": name} for name in names]
    outcome = retarget_batch.run_tasks(executor, tasks, jobs, retarget_batch.Progress(len(tasks), stream=stream))
    return outcome, stream.getvalue()


def by_name(outcome: retarget_batch.BatchOutcome) -> dict[str, dict]:
    return {entry["target"]: entry for entry in outcome.entries}


def test_a_mesh_whose_worker_dies_is_retried_once_on_the_fresh_replacement():
    executor = StandInExecutor(faults={"b": 1})
    outcome, printed = run(executor, "abcdef")
    entries = by_name(outcome)
    assert all(entry["status"] == "ok" for entry in outcome.entries)
    assert entries["b"]["attempts"] == 2 and all(entries[name]["attempts"] == 1 for name in "acdef")
    [dead] = [worker for worker in executor.workers if worker.served[-1:] == ["b"] and worker.number < 3]
    replacement = executor.workers[2]  # the third started: after the death
    assert replacement.served[0] == "b" and entries["b"]["worker"] == "stand-in:3"
    assert [record["fault"] is not None for record in outcome.workers] == [
        worker is dead for worker in executor.workers
    ]
    assert f"b: worker {dead.number} died; retrying on a fresh worker" in printed
    assert not outcome.interrupted and outcome.stopped is None


def test_a_mesh_that_faults_twice_fails_and_the_others_are_done():
    executor = StandInExecutor(faults={"b": 2, "odd": 1})  # "odd" raises (not a death): retried the same way
    outcome, printed = run(executor, ["a", "b", "odd", "c"])
    entries = by_name(outcome)
    assert entries["b"]["status"] == "failed" and entries["b"]["attempts"] == 2
    assert "died" in entries["b"]["error"] and "(on two workers)" in entries["b"]["error"]
    assert entries["odd"]["status"] == "ok" and entries["odd"]["attempts"] == 2
    assert entries["a"]["status"] == entries["c"]["status"] == "ok"
    assert sum(record["fault"] is not None for record in outcome.workers) == 3
    assert printed.count("retrying on a fresh worker") == 2 and "FAILED: worker" in printed


def test_a_worker_that_cannot_start_is_not_replaced_and_none_stops_the_batch():
    some = StandInExecutor(cannot_start={1})
    outcome, _printed = run(some, "abc")
    assert all(entry["status"] == "ok" for entry in outcome.entries) and len(some.workers) == 2
    assert [record["fault"] for record in outcome.workers] == ["no bpy here", None]

    none = StandInExecutor(cannot_start={1, 2})
    outcome, _printed = run(none, "abc")
    assert [entry["status"] for entry in outcome.entries] == ["not run"] * 3
    assert outcome.stopped == "no worker could start: no bpy here" and len(none.workers) == 2


def test_ctrl_c_stops_every_worker_at_once_and_leaves_the_rest_not_run():
    executor = StandInExecutor(interrupt_on="c")  # Ctrl-C while c is on its way: c, already done, counts
    before = signal.getsignal(signal.SIGINT)  # None inside a Blender binary: its handler is not Python's
    outcome, _printed = run(executor, "abcde", jobs=1)
    assert outcome.interrupted
    assert [entry["status"] for entry in outcome.entries] == ["ok", "ok", "ok", "not run", "not run"]
    assert [worker.stopped_now for worker in executor.workers] == [True]
    assert signal.getsignal(signal.SIGINT) == (signal.SIG_DFL if before is None else before)  # handed back
