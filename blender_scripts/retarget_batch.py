"""The batch of ``retarget.py --batch``: pools of long-lived workers, one scheduler, progress on stderr.

Every worker imports ``bpy`` and enables the add-on once (``BatchWorker``), then serves many meshes
with the one task function it is given (``retarget.py`` gives ``retarget_task``; this module does not import
it). Two executors provide the workers:

- ``LocalExecutor`` (``--executor local``, the default): worker processes started by a command it is given
  (``retarget.py --batch-worker``, in this same Python or Blender binary), each reading one JSON task a line on
  its stdin (``serve``, given the task function by that script);
- ``RayExecutor`` (``--executor ray``): Ray actors, on a Ray instance started here or on a cluster
  (``--address``); this folder travels to every node as the job's working directory, and each actor imports the
  task function by its name there (``module:function``).

The scheduler (``run_tasks``) is the same for both. A worker that dies (an importer abort, the out-of-memory
killer) or raises an error other than the scripts' own ``headless.ScriptError`` is stopped and replaced, and its
mesh retried once, on the replacement; a mesh that fails so twice counts as failed, and the batch goes on.
Ctrl-C (or SIGTERM) stops the batch at the loop's next turn and every worker at once; the meshes left
are returned as not run.

A resume (``--resume``) keeps a mesh's outputs only when its report carries the fingerprint of the run asked for
(``inputs_fingerprint``: the template, anchors and target files' contents and every setting); outputs made
from other inputs or settings are made again.

The summary's quality check (``quality_outliers``) flags the meshes whose read-out numbers stand out from the
rest of the batch (``OUTLIER_RULE``).

This module imports neither ``bpy`` nor ``retarget``: a worker's task function (which does) is given to it.
"""

import collections
import concurrent.futures
import dataclasses
import hashlib
import importlib
import json
import math
import os
import resource
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path

PROTOCOL_PREFIX = "springwrap-batch-worker: "  # a local worker's replies on stdout; any other line is ignored
ABORT_VARIABLE = "SPRINGWRAP_BATCH_ABORT"  # testing aid: see BatchWorker.run
POLL_SECONDS = 0.5
STOP_SECONDS = 10
RAY_MISSING = (
    "--executor ray needs the ray package in the Python that runs retarget.py (pip install -r requirements-ray.txt)"
)


def file_digest(path: "str | Path | None") -> str | None:
    """The SHA-256 of a file's bytes (hex), None for no file."""
    if path is None:
        return None
    with open(path, "rb") as stream:
        return hashlib.file_digest(stream, "sha256").hexdigest()


def inputs_fingerprint(settings: dict, shared_digests: dict, target_digest: str) -> str:
    """The fingerprint of one mesh's retarget (hex): its settings (every option of the run, the template's and
    the anchors' paths among them), the template's and anchors' contents (``shared_digests``) and the target's.
    A result whose report carries another fingerprint was made from other inputs or settings."""
    text = json.dumps(
        {"settings": settings, "files": shared_digests, "target": target_digest}, sort_keys=True, default=str
    )
    return hashlib.sha256(text.encode()).hexdigest()


class WorkerFault(Exception):
    """A worker stopped serving its mesh: its process died (``died``), or the task raised an unexpected error."""

    def __init__(self, message: str, died: bool) -> None:
        super().__init__(message)
        self.died = died


def peak_memory_mb() -> float:
    """This process's peak resident memory so far, in MiB (Linux ``ru_maxrss`` is in KiB)."""
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


def describe_error(error: BaseException) -> str:
    """``Type: message`` on one line."""
    message = " ".join(str(error).split())
    return f"{type(error).__name__}: {message}" if message else type(error).__name__


# ---------------------------------------------------------------- the worker


class BatchWorker:
    """One worker's state: ``bpy`` imported and the add-on enabled once, then any number of meshes (``run``),
    each by ``task`` (a task dict -> its summary entry; ``retarget.retarget_task``). ``started``: the
    ``time.perf_counter()`` from which the worker's start-up is counted (default: now), so that importing
    ``bpy`` before the worker is made counts too."""

    def __init__(self, task: Callable[[dict], dict], started: float | None = None) -> None:
        start = time.perf_counter() if started is None else started
        import headless

        headless.enable_addon()
        self._task = task
        self.identity = f"{socket.gethostname()}:{os.getpid()}"
        self.import_seconds = round(time.perf_counter() - start, 3)

    def describe(self) -> dict:
        """Who this worker is, what importing bpy and enabling the add-on cost, its memory so far."""
        return {"worker": self.identity, "import_seconds": self.import_seconds, "peak_memory_mb": peak_memory_mb()}

    def run(self, task: dict) -> dict:
        """Retarget one mesh: ``{"entry": the summary entry, "peak_memory_mb": this worker's peak so far,
        "task_seconds": the task's time in the worker}``.

        Testing aid: with ``SPRINGWRAP_BATCH_ABORT=NAME`` in its environment, the worker aborts (as an
        importer crash would) when given the mesh file NAME; with ``NAME:MARKER``, only while the file MARKER
        does not exist (it is created first), so that the retry on a fresh worker succeeds; several are
        separated by commas.
        """
        for wanted in filter(None, os.environ.get(ABORT_VARIABLE, "").split(",")):
            name, _, marker = wanted.partition(":")
            if Path(task["target"]).name == name and not (marker and Path(marker).exists()):
                if marker:
                    Path(marker).touch()
                os.abort()
        start = time.perf_counter()
        entry = self._task(task)
        return {
            "entry": entry | {"worker": self.identity},
            "peak_memory_mb": peak_memory_mb(),
            "task_seconds": time.perf_counter() - start,
        }


class EntryPointWorker(BatchWorker):
    """A :class:`BatchWorker` whose task function is named ``module:function`` (a Ray actor: the function is
    imported where the actor runs, from the job's working directory)."""

    def __init__(self, entry_point: str) -> None:
        start = time.perf_counter()
        module, _, function = entry_point.partition(":")
        super().__init__(getattr(importlib.import_module(module), function), started=start)


def serve(task: Callable[[dict], dict]) -> int:
    """A local worker's loop (``retarget.py --batch-worker``): one JSON task a line on stdin, one reply each,
    each by ``task`` (see :class:`BatchWorker`).

    Replies are ``PROTOCOL_PREFIX`` + JSON on the process's original stdout: ``{"ready": describe()}`` first,
    then ``{"result": run(task)}`` or ``{"fault": "..."}`` per task. Everything else that is printed (Blender's
    and the importers' messages) is sent to stderr. Ends when stdin is closed.
    """
    replies = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
    sys.stdout.flush()
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())

    def send(message: dict) -> None:
        replies.write(PROTOCOL_PREFIX + json.dumps(message) + "\n")
        replies.flush()

    try:
        worker = BatchWorker(task)
    except Exception as error:  # noqa: BLE001 - a worker that cannot start says why
        traceback.print_exc()
        send({"fault": describe_error(error)})
        return 1
    send({"ready": worker.describe()})
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            send({"result": worker.run(json.loads(line))})
        except Exception as error:  # noqa: BLE001 - reported; the coordinator replaces this worker
            traceback.print_exc()
            send({"fault": describe_error(error)})
    return 0


# ---------------------------------------------------------------- the local executor


class LocalWorker:
    """A worker process (``command``) and the one thread that talks to it; its stderr goes to ``log_path``."""

    def __init__(self, command: list[str], log_path: Path) -> None:
        self._log_path = log_path
        with open(log_path, "wb") as log:
            # Its own session: a Ctrl-C in the terminal reaches the coordinator alone, which stops the workers.
            self.process = subprocess.Popen(
                command,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=log,
                text=True,
                bufsize=1,
                start_new_session=True,
            )
        self._thread = concurrent.futures.ThreadPoolExecutor(max_workers=1)

    def ready(self) -> concurrent.futures.Future:
        """Resolves to the worker's ``describe()`` once it has imported bpy and enabled the add-on."""
        return self._thread.submit(self._receive)

    def submit(self, task: dict) -> concurrent.futures.Future:
        """Resolves to ``run(task)``'s result, or raises WorkerFault."""
        return self._thread.submit(self._exchange, task)

    def _exchange(self, task: dict) -> dict:
        try:
            self.process.stdin.write(json.dumps(task) + "\n")
            self.process.stdin.flush()
        except OSError:
            raise self._death() from None
        return self._receive()

    def _receive(self) -> dict:
        for line in self.process.stdout:
            if line.startswith(PROTOCOL_PREFIX):
                message = json.loads(line[len(PROTOCOL_PREFIX) :])
                if "fault" in message:
                    raise WorkerFault(message["fault"], died=False)
                return message["ready"] if "ready" in message else message["result"]
        raise self._death()

    def _death(self) -> WorkerFault:
        code = self.process.wait()
        how = (
            f"signal {signal.Signals(-code).name}"
            if code < 0 and -code in signal.valid_signals()
            else f"exit code {code}"
        )
        try:
            lines = [line.strip() for line in self._log_path.read_text(errors="replace").splitlines() if line.strip()]
        except OSError:
            lines = []
        return WorkerFault(f"the worker process died ({how})" + (f": {lines[-1]}" if lines else ""), died=True)

    def stop(self, now: bool = False) -> None:
        """End the process: at once (``now``), or by closing its stdin and waiting a little."""
        try:
            self.process.stdin.close()
        except OSError:
            pass
        if not now:
            try:
                self.process.wait(timeout=STOP_SECONDS)
            except subprocess.TimeoutExpired:
                pass
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._thread.shutdown(wait=False)


class LocalExecutor:
    """Worker processes on this machine, each started with ``command`` (``retarget.py --batch-worker``)."""

    name = "local"

    def __init__(self, command: list[str]) -> None:
        self._command = command
        self._logs = tempfile.TemporaryDirectory(prefix="springwrap-batch-")
        self._started = 0

    def default_jobs(self) -> int:
        """Workers when --jobs is not given: one."""
        return 1

    def start_worker(self) -> LocalWorker:
        self._started += 1
        return LocalWorker(self._command, Path(self._logs.name) / f"worker-{self._started}.log")

    def close(self) -> None:
        self._logs.cleanup()


# ---------------------------------------------------------------- the Ray executor


def import_ray():
    """The ``ray`` module, or ImportError with the message saying how to install it."""
    try:
        import ray
    except ImportError:
        raise ImportError(RAY_MISSING) from None
    return ray


def check_reachable(address: str, seconds: float = 10.0) -> None:
    """ConnectionError when the head at ``HOST:PORT`` does not accept a connection (Ray itself would go on
    retrying for minutes); other forms (``auto``, ``ray://...``) are left to Ray."""
    host, separator, port = address.rpartition(":")
    if not separator or "://" in address or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=seconds).close()
    except OSError as error:
        raise ConnectionError(f"no Ray head answers at {address}: {error.strerror or error}") from None


class RayWorker:
    """A Ray actor running EntryPointWorker; its calls' results as concurrent futures, Ray's errors as WorkerFault."""

    def __init__(self, ray, actor) -> None:
        self._ray = ray
        self.actor = actor
        self.identity: str | None = None  # host:pid, once ready

    def ready(self) -> concurrent.futures.Future:
        future = self._translated(self.actor.describe.remote())
        future.add_done_callback(
            lambda done: setattr(self, "identity", None if done.exception() else done.result()["worker"])
        )
        return future

    def submit(self, task: dict) -> concurrent.futures.Future:
        return self._translated(self.actor.run.remote(task))

    def _translated(self, reference) -> concurrent.futures.Future:
        exceptions = self._ray.exceptions
        result = concurrent.futures.Future()

        def settle(source: concurrent.futures.Future) -> None:
            try:
                result.set_result(source.result())
            except exceptions.RayTaskError as error:  # the task raised: its exception's last line
                lines = [line.strip() for line in str(error).splitlines() if line.strip()]
                result.set_exception(WorkerFault(lines[-1] if lines else type(error).__name__, died=False))
            except (exceptions.RayActorError, exceptions.RayError) as error:  # the actor's process died
                lines = [line.strip() for line in str(error).splitlines() if line.strip()]
                detail = next(
                    (line.partition("Worker exit detail: ")[2] for line in lines if "Worker exit detail: " in line), ""
                )
                message = f"the Ray worker died: {lines[0] if lines else type(error).__name__}"
                detail = detail.strip().split(". ")[0]  # Ray goes on with a paragraph of possible causes
                result.set_exception(WorkerFault(message + (f" ({detail})" if detail else ""), died=True))
            except concurrent.futures.CancelledError:
                result.set_exception(WorkerFault("the Ray call was cancelled", died=True))

        reference.future().add_done_callback(settle)
        return result

    def stop(self, now: bool = False) -> None:
        """Kill the actor (its CPU goes back to the cluster). Ray kills it a moment later: when stopping
        ``now`` (Ctrl-C) on this machine, wait (up to STOP_SECONDS) until its process is gone, so that nothing
        it was writing appears after the batch has cleaned up its half-written files."""
        try:
            self._ray.kill(self.actor, no_restart=True)
        except Exception:  # noqa: BLE001 - already gone
            pass
        host, _, pid = (self.identity or "").rpartition(":")
        if not now or host != socket.gethostname() or not pid.isdigit():
            return
        deadline = time.monotonic() + STOP_SECONDS
        while time.monotonic() < deadline and _running(int(pid)):
            time.sleep(0.05)


def _running(pid: int) -> bool:
    """Whether process ``pid`` of this machine still runs (a zombie, dead but not yet reaped, does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


class RayExecutor:
    """Ray actors, one CPU each: on the cluster at ``address``, or on a Ray instance started here; each runs the
    task function ``entry_point`` names (``module:function``, importable from ``scripts_folder``)."""

    name = "ray"

    def __init__(self, address: str | None, jobs: int | None, scripts_folder: Path, entry_point: str) -> None:
        import logging

        ray = import_ray()
        self._ray = ray
        if address is not None:
            check_reachable(address)
        # No address: always a new instance here ("local"), never a cluster that `ray start` left recorded
        # in /tmp/ray. The scripts go to every node as the job's working directory; bpy, the add-on and
        # the kernel wheel must be installed there. Workers' own output stays in Ray's logs.
        options = {"num_cpus": jobs} if address is None else {}
        ray.init(
            address=address or "local",
            runtime_env={"working_dir": str(scripts_folder), "excludes": ["__pycache__"]},
            log_to_driver=False,
            include_dashboard=False,
            logging_level=logging.WARNING,
            **options,
        )
        self._actor_class = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(EntryPointWorker)
        self._entry_point = entry_point

    def default_jobs(self) -> int:
        """Workers when --jobs is not given: one per CPU of the cluster."""
        return max(1, int(self._ray.cluster_resources().get("CPU", 1)))

    def start_worker(self) -> RayWorker:
        return RayWorker(self._ray, self._actor_class.remote(self._entry_point))

    def close(self) -> None:
        self._ray.shutdown()


# ---------------------------------------------------------------- progress


class Progress:
    """Finished meshes on stderr: in a terminal, a tqdm bar with an ETA (failures and retries printed above
    it); otherwise (a log, a pipe) no bar, one plain line per finished mesh."""

    def __init__(self, total: int, already_done: int = 0, stream=None) -> None:
        self.stream = stream or sys.stderr
        self.total, self.done = total, already_done
        self.bar = None
        if self.stream.isatty():
            try:
                from tqdm import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self.bar = tqdm(total=total, initial=already_done, unit="mesh", file=self.stream, dynamic_ncols=True)

    def say(self, line: str) -> None:
        if self.bar is not None:
            self.bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def finished(self, entry: dict) -> None:
        """One mesh done (ok or failed)."""
        self.done += 1
        ok = entry["status"] == "ok"
        line = (
            f"[{self.done}/{self.total}] {Path(entry['target']).name}: "
            f"{'ok' if ok else 'FAILED: ' + entry.get('error', '?')} ({entry.get('seconds', 0):.1f} s)"
        )
        if self.bar is None or not ok:
            self.say(line)
        if self.bar is not None:
            self.bar.update(1)

    def retrying(self, target: str, fault: WorkerFault) -> None:
        self.say(f"{Path(target).name}: {fault}; retrying on a fresh worker")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


# ---------------------------------------------------------------- the scheduler


@dataclasses.dataclass
class _Slot:
    """A worker of the pool: its handle, when it was started, its record for the summary, its state."""

    handle: object
    started: float
    record: dict
    reserved: tuple[int, int] | None = None  # (task index, attempt) kept for this fresh worker
    ready: bool = False
    busy: bool = False
    submitted: float = 0.0


@dataclasses.dataclass
class BatchOutcome:
    """What ``run_tasks`` did: an entry per task (in order), a record per worker started, how it ended."""

    entries: list[dict]
    workers: list[dict]
    interrupted: bool = False
    stopped: str | None = None  # why the batch stopped early (no worker could start), else None


def run_tasks(executor, tasks: list[dict], jobs: int, progress: Progress) -> BatchOutcome:
    """Run every task on ``jobs`` workers of ``executor``, retrying a mesh once on a fresh worker when its
    worker faults; each entry is ``retarget_task``'s (with ``attempts`` and ``worker``), a failure, or not run."""
    entries: list[dict | None] = [None] * len(tasks)
    remaining = len(tasks)
    pending = collections.deque((index, 1) for index in range(len(tasks)))
    slots: list[_Slot] = []
    records: list[dict] = []
    futures: dict[concurrent.futures.Future, tuple[_Slot, int | None, int]] = {}
    outcome = BatchOutcome(entries, records)
    start_fault = None

    def start_worker(reserved: tuple[int, int] | None = None) -> None:
        record = {
            "worker": None,
            "start_seconds": None,
            "import_seconds": None,
            "meshes": 0,
            "dispatch_seconds": 0.0,
            "peak_memory_mb": None,
            "fault": None,
        }
        records.append(record)
        slot = _Slot(executor.start_worker(), time.perf_counter(), record, reserved)
        slots.append(slot)
        futures[slot.handle.ready()] = (slot, None, 0)

    def retire(slot: _Slot, fault: WorkerFault) -> None:
        slot.record["fault"] = str(fault)
        slots.remove(slot)
        slot.handle.stop(now=True)

    stop_requested = threading.Event()
    previous_handlers = _stop_on_signals(stop_requested)
    try:
        for _ in range(min(jobs, len(tasks))):
            start_worker()
        while remaining and not stop_requested.is_set():
            for slot in slots:
                if slot.ready and not slot.busy and (slot.reserved or pending):
                    index, attempt = slot.reserved or pending.popleft()
                    slot.reserved, slot.busy, slot.submitted = None, True, time.perf_counter()
                    futures[slot.handle.submit(tasks[index])] = (slot, index, attempt)
            if not futures:
                outcome.stopped = f"no worker could start: {start_fault}"
                break
            done, _ = concurrent.futures.wait(
                list(futures), timeout=POLL_SECONDS, return_when=concurrent.futures.FIRST_COMPLETED
            )
            for future in done:
                slot, index, attempt = futures.pop(future)
                try:
                    result = future.result()
                except WorkerFault as fault:
                    retire(slot, fault)
                    if index is None:  # it never started: not replaced; work kept for it goes back
                        start_fault = fault
                        if slot.reserved:
                            pending.appendleft(slot.reserved)
                    elif attempt == 1:
                        progress.retrying(tasks[index]["target"], fault)
                        start_worker(reserved=(index, 2))
                    else:
                        entries[index] = {
                            "target": tasks[index]["target"],
                            "status": "failed",
                            "error": f"{fault} (on two workers)",
                            "attempts": attempt,
                        }
                        remaining -= 1
                        progress.finished(entries[index])
                        if pending:
                            start_worker()
                    continue
                if index is None:
                    slot.ready = True
                    slot.record.update(
                        worker=result["worker"],
                        import_seconds=result["import_seconds"],
                        start_seconds=round(time.perf_counter() - slot.started, 3),
                        peak_memory_mb=result["peak_memory_mb"],
                    )
                else:
                    slot.busy = False
                    # Time between handing the mesh over and having its entry back, beyond the task itself.
                    overhead = time.perf_counter() - slot.submitted - result.get("task_seconds", 0.0)
                    slot.record["dispatch_seconds"] = round(slot.record["dispatch_seconds"] + max(0.0, overhead), 4)
                    slot.record["meshes"] += 1
                    slot.record["peak_memory_mb"] = result["peak_memory_mb"]
                    entries[index] = result["entry"] | {"attempts": attempt}
                    remaining -= 1
                    progress.finished(entries[index])
    except KeyboardInterrupt:  # raised by other code (the handlers above only set the flag)
        stop_requested.set()
    finally:
        for number, handler in previous_handlers.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)
        outcome.interrupted = stop_requested.is_set()
        for slot in list(slots):
            slot.handle.stop(now=outcome.interrupted)
        # Let the calls still out settle (their workers are gone) before the executor closes.
        concurrent.futures.wait(list(futures), timeout=STOP_SECONDS)
        progress.close()
    for index, entry in enumerate(entries):
        if entry is None:
            entries[index] = {"target": tasks[index]["target"], "status": "not run"}
    return outcome


def _stop_on_signals(stop_requested: threading.Event) -> dict:
    """Ctrl-C (SIGINT) and SIGTERM (a job cancelled, a pod stopped) set ``stop_requested``, which the
    scheduler's loop looks at every turn (at most POLL_SECONDS apart). Not a KeyboardInterrupt raised
    wherever the loop is: that could leave a lock of the futures' machinery held, and Ray's shutdown
    waiting on it for ever. Also inside a Blender binary, whose own SIGINT handler only flags a break.
    Returns the handlers replaced (None: not installed from Python)."""

    def request_stop(_signal_number, _frame):
        stop_requested.set()

    return {number: signal.signal(number, request_stop) for number in (signal.SIGINT, signal.SIGTERM)}


# ---------------------------------------------------------------- the batch's quality read-out

OUTLIER_Z = 3.5
"""A mesh stands out when one of its metrics' robust z-scores passes this (Iglewicz and Hoaglin's cut-off)."""
OUTLIER_METRICS = {
    # metric of the report's quality block: (which way is worse, the spread's floor: ("count", units),
    # ("relative", fraction of the batch's median) or ("distance", fraction of the batch's median and of its
    # median off-surface threshold: distances at the storage's rounding are all alike))
    "distance_p50": (1, ("distance", 0.01)),
    "distance_p95": (1, ("distance", 0.01)),
    "distance_max": (1, ("distance", 0.01)),
    "stretch_p5": (-1, ("relative", 0.01)),
    "stretch_p95": (1, ("relative", 0.01)),
    "stretch_max": (1, ("relative", 0.01)),
    "flipped": (1, ("count", 1.0)),
    "off_surface": (1, ("count", 1.0)),
}
"""The metrics :func:`quality_outliers` judges."""
OUTLIER_RULE = (
    "a mesh stands out when, for one of the metrics "
    + ", ".join(OUTLIER_METRICS)
    + ", its robust z-score (value - batch median) / (1.4826 x median absolute deviation), signed so that "
    "positive is worse (lower for stretch_p5, higher for the others), is above 3.5; the spread is taken at least "
    "1 for counts, 1 % of the median for the others and, for distances, 1 % of the median off-surface threshold; "
    "batches of fewer than 3 meshes flag nothing"
)
"""The rule, as the summary states it."""


def quality_outliers(rows: dict) -> dict:
    """The batch rule (:data:`OUTLIER_RULE`): ``rows`` maps a mesh to its report's quality block; the result maps
    each mesh that stands out to ``{metric: {"value", "median", "z"}}``.

    For each metric over the meshes that have a finite value of it, a mesh's robust z-score is
    ``(value - median) / (1.4826 * MAD)``, signed so that positive is worse; the spread is never taken below a
    floor (one element for counts, 1 % of the median for the others, and for distances also 1 % of the batch's
    median off-surface threshold), so that a batch of equal numbers flags nothing but a count that jumps from a
    few to many, and distances all at the storage's rounding (1e-7) flag nothing.
    """
    flagged: dict = {}
    thresholds = [
        float(row["off_surface_threshold"])
        for row in rows.values()
        if isinstance(row, dict)
        and isinstance(row.get("off_surface_threshold"), (int, float))
        and math.isfinite(float(row["off_surface_threshold"]))
    ]
    threshold = statistics.median(thresholds) if thresholds else 0.0
    for metric, (direction, (floor_kind, floor)) in OUTLIER_METRICS.items():
        values = {
            name: float(row[metric])
            for name, row in rows.items()
            if isinstance(row, dict) and isinstance(row.get(metric), (int, float)) and math.isfinite(float(row[metric]))
        }
        if len(values) < 3:
            continue
        median = statistics.median(values.values())
        spread = 1.4826 * statistics.median(abs(value - median) for value in values.values())
        least = floor if floor_kind == "count" else floor * abs(median)
        if floor_kind == "distance":
            least = max(least, floor * threshold)
        spread = max(spread, least, sys.float_info.min)
        for name, value in values.items():
            score = direction * (value - median) / spread
            if score > OUTLIER_Z:
                flagged.setdefault(name, {})[metric] = {"value": value, "median": median, "z": round(score, 2)}
    return flagged
