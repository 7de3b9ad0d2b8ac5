"""How fast a batch retargets a library: meshes per minute, worker start-up and memory; not a test.

A library of ``--meshes`` noisy tori (``_noisy_torus.noisy_torus``, ``--triangles`` each, every one with
another displacement) is written as OBJ files, with a quad layout over a torus (``--layout-quads``) as the
template. ``blender_scripts/retarget.py --batch`` then retargets the layout onto the whole library with
each executor (local worker processes; Ray actors on a Ray instance the script starts, when ray is
installed) and 1 and 2 workers, each run in a fresh output folder; its ``summary.json`` gives each
worker's start-up (process or actor created -> bpy imported and the add-on enabled), its peak resident
memory and the time spent handing meshes over (``dispatch_seconds``), and each mesh's time in its worker.

Also measured, without Blender: the scheduler's own cost per mesh (``run_tasks`` with stand-in workers
that answer at once), for 10,000 meshes on 200 workers.

Run: ``.venv/bin/python benchmarks/batch_throughput.py [--quick] [--json out/bench/batch_throughput.json]``.
``benchmarks/report.py --batch`` turns the JSON into the page's *Batch on a cluster* section.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import io
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY / "benchmarks"))
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))
import _machine  # noqa: E402
from _noisy_torus import noisy_torus, torus_layout  # noqa: E402

import retarget_batch  # noqa: E402  (no bpy)

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
SCHEDULER_MESHES, SCHEDULER_WORKERS = 10_000, 200


def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Vertices and faces (triangles or quads, 0-based) as OBJ text."""
    with open(path, "w") as file:
        np.savetxt(file, vertices, fmt="v %.6f %.6f %.6f")
        np.savetxt(file, faces.astype(np.int64) + 1, fmt="f" + " %d" * faces.shape[1])


def make_library(folder: Path, meshes: int, triangles: int, layout_quads: int) -> Path:
    """``folder/library/torus_NN.obj`` (one displacement each) and ``folder/layout.obj``; the template's path."""
    library = folder / "library"
    library.mkdir(parents=True)
    for index in range(meshes):
        write_obj(library / f"torus_{index:02d}.obj", *noisy_torus(triangles, seed=100 + index))
    template = folder / "layout.obj"
    write_obj(template, *torus_layout(layout_quads, seed=2))
    return template


def run_batch(template: Path, library: Path, output: Path, executor: str, jobs: int) -> dict:
    """One batch run; its numbers (from summary.json and the clock)."""
    start = time.perf_counter()
    process = subprocess.run(
        [
            sys.executable,
            str(RETARGET),
            "--template",
            str(template),
            "--batch",
            str(library),
            "--output-dir",
            str(output),
            "--executor",
            executor,
            "--jobs",
            str(jobs),
            "--anchors-spacing",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=3600,
    )
    wall = time.perf_counter() - start
    if process.returncode != 0:
        raise RuntimeError(f"{executor} x {jobs}: exit {process.returncode}: {process.stderr[-2000:]}")
    summary = json.loads((output / "summary.json").read_text())
    workers = [worker for worker in summary["workers"] if worker["worker"] is not None]
    meshes = summary["meshes"]
    mesh_seconds = [entry["seconds"] for entry in meshes]
    input_bytes = sum(Path(entry["target"]).stat().st_size for entry in meshes) / len(meshes)
    output_bytes = sum(path.stat().st_size for path in output.iterdir() if path.name != "summary.json") / len(meshes)
    dispatch = sum(worker["dispatch_seconds"] for worker in workers) / len(meshes)
    # Steady state: each worker serves one mesh per (mesh time + hand-over time); the workers add up.
    steady = 60.0 * len(workers) / (float(np.mean(mesh_seconds)) + dispatch)
    return {
        "executor": executor,
        "jobs": jobs,
        "meshes": len(meshes),
        "ok": summary["ok"],
        "process_seconds": round(wall, 2),
        "batch_seconds": summary["seconds"],
        "meshes_per_minute": round(60.0 * len(meshes) / wall, 1),
        "steady_meshes_per_minute": round(steady, 1),
        "mesh_seconds_mean": round(float(np.mean(mesh_seconds)), 3),
        "dispatch_seconds_per_mesh": round(dispatch, 4),
        "worker_start_seconds": [worker["start_seconds"] for worker in workers],
        "worker_import_seconds": [worker["import_seconds"] for worker in workers],
        "worker_peak_memory_mb": [worker["peak_memory_mb"] for worker in workers],
        "worker_meshes": [worker["meshes"] for worker in workers],
        "input_mb_per_mesh": round(input_bytes / 2**20, 2),
        "output_mb_per_mesh": round(output_bytes / 2**20, 2),
    }


class _InstantWorker:
    """A stand-in worker that answers at once: what is left is the scheduler's own cost."""

    def ready(self) -> concurrent.futures.Future:
        return _settled({"worker": "stand-in", "import_seconds": 0.0, "peak_memory_mb": 0.0})

    def submit(self, task: dict) -> concurrent.futures.Future:
        return _settled(
            {
                "entry": {"target": task["target"], "status": "ok", "seconds": 0.0},
                "peak_memory_mb": 0.0,
                "task_seconds": 0.0,
            }
        )

    def stop(self, now: bool = False) -> None:
        pass


class _InstantExecutor:
    name = "stand-in"

    def start_worker(self) -> _InstantWorker:
        return _InstantWorker()


def _settled(value) -> concurrent.futures.Future:
    future = concurrent.futures.Future()
    future.set_result(value)
    return future


def scheduler_cost() -> dict:
    """Seconds of ``run_tasks`` for SCHEDULER_MESHES meshes on SCHEDULER_WORKERS stand-in workers."""
    tasks = [{"target": f"mesh_{index}.obj"} for index in range(SCHEDULER_MESHES)]
    start = time.perf_counter()
    outcome = retarget_batch.run_tasks(
        _InstantExecutor(), tasks, SCHEDULER_WORKERS, retarget_batch.Progress(len(tasks), stream=io.StringIO())
    )
    seconds = time.perf_counter() - start
    assert all(entry["status"] == "ok" for entry in outcome.entries)
    return {
        "meshes": SCHEDULER_MESHES,
        "workers": SCHEDULER_WORKERS,
        "seconds": round(seconds, 3),
        "milliseconds_per_mesh": round(1000 * seconds / SCHEDULER_MESHES, 4),
    }


def machine_description() -> dict:
    cpu_model = _machine.cpu_model()
    memory_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return {
        "cpu": cpu_model,
        "cpu_count": os.cpu_count(),
        "memory_gib": round(memory_gib, 1),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "load_average": [round(value, 2) for value in os.getloadavg()],
    }


def versions() -> dict:
    from benchmarks.retarget.run import git_commit

    found = {"git_commit": git_commit()}
    for name in ("bpy", "ray", "numpy"):
        try:
            from importlib.metadata import version

            found[name] = version(name)
        except Exception:  # noqa: BLE001 - not installed
            found[name] = None
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batch_throughput.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 meshes of 50,000 triangles")
    parser.add_argument("--meshes", type=int, help="meshes in the library (default 24; quick 6)")
    parser.add_argument("--triangles", type=int, help="triangles per mesh (default 200,000; quick 50,000)")
    parser.add_argument("--layout-quads", type=int, default=13_000, help="quads of the template (default 13,000)")
    parser.add_argument("--executors", nargs="+", default=["local", "ray"], choices=("local", "ray"))
    parser.add_argument("--json", type=Path, help="write the numbers here")
    arguments = parser.parse_args(argv)
    meshes = arguments.meshes or (6 if arguments.quick else 24)
    triangles = arguments.triangles or (50_000 if arguments.quick else 200_000)
    executors = [name for name in arguments.executors if name != "ray" or _has_ray()]
    sys.path.insert(0, str(REPOSITORY))
    result = {
        "machine": machine_description(),
        "versions": versions(),
        "library": {"meshes": meshes, "triangles": triangles, "layout_quads": arguments.layout_quads},
        "runs": [],
        "scheduler": scheduler_cost(),
    }
    print(
        f"scheduler: {result['scheduler']['milliseconds_per_mesh']} ms per mesh "
        f"({SCHEDULER_MESHES} meshes, {SCHEDULER_WORKERS} stand-in workers)",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="springwrap-batch-bench-") as folder:
        template = make_library(Path(folder), meshes, triangles, arguments.layout_quads)
        for executor in executors:
            for jobs in (1, 2):
                run = run_batch(
                    template, Path(folder) / "library", Path(folder) / f"out-{executor}-{jobs}", executor, jobs
                )
                result["runs"].append(run)
                print(
                    f"{executor} x {jobs}: {run['meshes_per_minute']} meshes/min all-in "
                    f"({run['steady_meshes_per_minute']} steady), {run['mesh_seconds_mean']} s a mesh, start-up "
                    f"{run['worker_start_seconds']} s, peak {run['worker_peak_memory_mb']} MB",
                    flush=True,
                )
    result["load_average_end"] = [round(value, 2) for value in os.getloadavg()]
    result["finished_utc"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    if arguments.json:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {arguments.json}")
    return 0


def _has_ray() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        print("batch_throughput: no ray here: the Ray runs are left out", file=sys.stderr)
        return False
    return True


if __name__ == "__main__":
    sys.exit(main())
