"""Large targets: how long an operation takes to start on a 5M-triangle target, and the memory of a wrap on it.

    .venv/bin/python benchmarks/large_target.py [--triangles N] [--quads N] [--iterations N] [--json PATH]

Runs in a **fresh subprocess** (this script with ``--worker``), with glibc's ``MALLOC_MMAP_THRESHOLD_``
fixed as ``performance.py`` does, so the resident set follows what is allocated and freed. In it: the
add-on enabled in the ``bpy`` module, the deterministic noise-displaced torus of ``_noisy_torus`` as the
target object (~``--triangles``) and a quad layout over another displaced torus (~``--quads``). Then:

- **start**: ``springwrap.snap(mode='SURFACE')`` three times; for each, the time from the operator call
  to its first call into the kernel's queries (``CentredMesh.closest_points``), i.e. what the operator
  spends before the kernel starts working (checks, and reading, hashing, building the target when its
  cache cannot be reused); and the read paths the cache took (``blender.target.target_reads``).
- **memory**: the resident set once the scene is built (the "scene"), and its peak (``VmHWM``, reset with
  ``/proc/self/clear_refs``) over the first operation (target read and built: the face tree) and over
  ``springwrap.wrap(max_iterations=K)`` after it, in bytes per target triangle above the scene; the
  resident set kept after each. The peak of the read alone (numpy arrays, hashing) is measured with
  ``tracemalloc`` (numpy reports its buffers to it).

Prints a summary and writes ``out/bench/large_target.json``. A step of ``make bench`` (a 5M-triangle
target takes a few minutes and ~2 GB; ``QUICK=1``: 1M triangles); ``benchmarks/report.py`` makes its table in
``docs/benchmarks.md`` (*Large targets*).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_JSON = REPOSITORY_ROOT / "out" / "bench" / "large_target.json"
SEED = 1
LAYOUT_SEED = 2


def worker(triangles: int, quads: int, iterations: int) -> dict:
    """In the worker process: the scene, three snaps (start times), then a wrap (memory)."""
    import bpy  # noqa: I001 - bpy first, then the add-on
    import addon_utils

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _worker
    from _noisy_torus import noisy_torus, torus_layout

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        raise RuntimeError("addon_utils.enable('springwrap') failed: run `make setup` first")
    from springwrap.blender import target as target_data
    from springwrap.core import target as core_target

    vertices, faces = noisy_torus(triangles, seed=SEED)
    layout_vertices, layout_quads = torus_layout(quads, seed=LAYOUT_SEED)
    target = _worker.mesh_object(bpy, "Target", vertices, faces)
    layout = _worker.mesh_object(bpy, "Layout", layout_vertices, layout_quads)
    triangle_count = len(faces)
    del vertices, faces
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    bpy.ops.springwrap.detach()  # the layout's attributes exist before the scene is measured
    target_data.clear_target_cache()

    first_query = []
    closest_points = core_target.CentredMesh.closest_points

    def timed_closest_points(self, points, **options):
        if not first_query:
            first_query.append(time.perf_counter())
        return closest_points(self, points, **options)

    core_target.CentredMesh.closest_points = timed_closest_points
    scene_kilobytes = _worker.status_kilobytes("VmRSS")
    result = {"triangles": triangle_count, "layout_vertices": len(layout_vertices), "snaps": []}

    def per_triangle(kilobytes: float) -> float:
        return kilobytes * 1024.0 / triangle_count

    target_reads = getattr(target_data, "target_reads", dict)  # absent before the cache counted its reads
    for run in range(3):
        _worker.reset_peak()
        reads_before = target_reads()
        first_query.clear()
        start = time.perf_counter()
        if bpy.ops.springwrap.snap(mode="SURFACE") != {"FINISHED"}:
            raise RuntimeError("springwrap.snap failed")
        seconds = time.perf_counter() - start
        reads_after = target_reads()
        result["snaps"].append(
            {
                "run": run + 1,
                "start_seconds": first_query[0] - start,
                "seconds": seconds,
                "reads": {path: reads_after[path] - reads_before[path] for path in reads_after},
                "peak_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmHWM") - scene_kilobytes),
                "kept_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmRSS") - scene_kilobytes),
            }
        )
    _worker.reset_peak()
    start = time.perf_counter()
    if bpy.ops.springwrap.wrap(max_iterations=iterations, tolerance=1e-12) != {"FINISHED"}:
        raise RuntimeError("springwrap.wrap failed")
    result["wrap"] = {
        "iterations": iterations,
        "seconds": time.perf_counter() - start,
        "peak_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmHWM") - scene_kilobytes),
        "kept_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmRSS") - scene_kilobytes),
    }
    result["read"] = _python_read_peak(bpy, target_data, layout, triangle_count)
    result["scene_megabytes"] = scene_kilobytes / 1024.0
    return result


def _python_read_peak(bpy, target_data, layout, triangle_count) -> dict:
    """The numpy side of one uncached read (the kernel's build excluded): peak bytes per triangle, and time."""
    import tracemalloc

    from springwrap.core import target as core_target

    target_data.clear_target_cache()
    built = []
    make_target = core_target.make_target

    def measured_make_target(*arguments, **options):
        built.append((tracemalloc.get_traced_memory()[1], time.perf_counter()))
        return make_target(*arguments, **options)

    target_data.make_target = measured_make_target
    try:
        tracemalloc.start()
        start = time.perf_counter()
        target_data.read_target(bpy.context.evaluated_depsgraph_get(), layout)
        tracemalloc.stop()
    finally:
        target_data.make_target = make_target
    peak, reached = built[0]
    return {"peak_bytes_per_triangle": peak / triangle_count, "seconds_to_build": reached - start}


def measure(triangles: int, quads: int, iterations: int) -> dict:
    """Run the worker in a fresh process."""
    environment = dict(os.environ)
    environment.setdefault("MALLOC_MMAP_THRESHOLD_", "131072")
    process = subprocess.run(
        [sys.executable, __file__, "--worker", str(triangles), str(quads), str(iterations)],
        capture_output=True,
        text=True,
        env=environment,
    )
    lines = [line for line in process.stdout.splitlines() if line.startswith("RESULT ")]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"worker failed ({process.returncode}):\n{process.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :])


def describe(result: dict) -> str:
    lines = [f"target {result['triangles']:,} triangles, layout {result['layout_vertices']:,} vertices"]
    for snap in result["snaps"]:
        lines.append(
            f"  snap {snap['run']}: starts after {snap['start_seconds']:.3f} s (total {snap['seconds']:.2f} s), "
            f"reads {snap['reads']}, peak {snap['peak_bytes_per_triangle']:.0f} B/triangle, "
            f"kept {snap['kept_bytes_per_triangle']:.0f}"
        )
    wrap = result["wrap"]
    lines.append(
        f"  wrap ({wrap['iterations']} iterations, {wrap['seconds']:.1f} s): peak "
        f"{wrap['peak_bytes_per_triangle']:.0f} B/triangle above the scene, kept {wrap['kept_bytes_per_triangle']:.0f}"
    )
    read = result["read"]
    lines.append(
        f"  read (numpy, tracemalloc): peak {read['peak_bytes_per_triangle']:.0f} B/triangle, "
        f"{read['seconds_to_build']:.2f} s (traced) to the kernel's build"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--triangles", type=int, default=5_000_000)
    parser.add_argument("--quads", type=int, default=4_000)
    parser.add_argument("--iterations", type=int, default=20)
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    parser.add_argument("--worker", nargs=3, type=int, metavar=("TRIANGLES", "QUADS", "ITERATIONS"))
    arguments = parser.parse_args(argv)
    if arguments.worker:
        print("RESULT " + json.dumps(worker(*arguments.worker)))
        return 0
    result = measure(arguments.triangles, arguments.quads, arguments.iterations)
    print(describe(result))
    arguments.json.parent.mkdir(parents=True, exist_ok=True)
    arguments.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
