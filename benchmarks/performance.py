"""Performance sweep: how the kernel's BVH build, snap and the add-on's wrap grow with target and layout size.

    .venv/bin/python benchmarks/performance.py [--quick] [--json PATH]

Every measurement runs in a **fresh subprocess** (this script with ``--worker``), so each size's
peak resident memory is its own and one size's freed-but-kept memory cannot hide in the next.
Geometry is the deterministic noise-displaced torus of ``_noisy_torus`` (target) and a quad grid
over a differently displaced torus (layout); nothing is downloaded.

- ``target`` sweep (``springwrap_kernel`` only, no Blender): ``TargetMesh(vertices, triangles)``
  build (the face tree) for ~10k .. ~5M triangles; ``prepare_all()`` (vertex tree, adjacency,
  normals); ``closest_points`` of a fixed set of 100k query points in random order (best of
  3); memory per triangle: the growth of the resident set from before the build to after it
  (kept) and of its peak during the build, over the triangle count (the workers run with glibc's
  ``MALLOC_MMAP_THRESHOLD_`` fixed, so freed temporaries do not hide the kernel's allocations). Then, in the same worker,
  Blender's Shrinkwrap modifier (``NEAREST_SURFACEPOINT``) on the same 100k points: its first
  evaluation, which builds Blender's BVH of the target and answers the queries.
- ``layout`` sweep: ``closest_points`` of ~1k .. ~4M query points (random order) on one 1M-triangle
  target (best of 3, one run above 1M points); points per second.
- ``wrap`` sweep: the add-on's operators as a user runs them on a quad-grid layout of ~1k .. ~1M
  vertices over a 100k-triangle target: ``springwrap.detach``, ``springwrap.snap``, then
  ``springwrap.wrap(max_iterations=K, tolerance=1e-12)`` (K fixed so every size does the same
  work; the tolerance keeps it from stopping early); the wrap's own report gives iterations and
  seconds, so iterations per second and vertex-iterations per second.
- ``threads``: ``closest_points`` of 1M random points on the 1M target with ``RAYON_NUM_THREADS``
  1 and the machine's CPU count.

Prints one line per measurement and writes everything to ``out/bench/performance.json`` (the
docs generator, ``benchmarks/report.py``, reads it). Other work on the machine skews times: the
load average before and after each worker is recorded with it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _machine
import _worker

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_JSON = REPOSITORY_ROOT / "out" / "bench" / "performance.json"
SEED = 1
LAYOUT_SEED = 2
QUERY_POINTS = 100_000
WRAP_TARGET_TRIANGLES = 100_000
LAYOUT_TARGET_TRIANGLES = 1_000_000
WRAP_ITERATIONS = 20

FULL = {
    "target": [10_000, 30_000, 100_000, 300_000, 1_000_000, 3_000_000, 5_000_000],
    "layout": [1_000, 10_000, 100_000, 1_000_000, 4_000_000],
    "wrap": [1_000, 4_000, 16_000, 64_000, 256_000, 1_000_000],
    "threads": [1_000_000],
}
QUICK = {
    "target": [10_000, 100_000, 1_000_000],
    "layout": [1_000, 10_000, 100_000, 1_000_000],
    "wrap": [1_000, 4_000, 16_000, 64_000],
    "threads": [],
}


# ---------------------------------------------------------------- in the worker


def _best(function, repeat: int):
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result


def _random_queries(count: int):
    import numpy as np
    from _noisy_torus import query_points

    points = query_points(count, seed=SEED)
    return np.ascontiguousarray(points[np.random.default_rng(SEED).permutation(count)])


def worker_target(triangles: int) -> dict:
    """Build, prepare, query and memory of a kernel TargetMesh of ~``triangles``; then Shrinkwrap on it."""
    from _noisy_torus import noisy_torus

    import springwrap_kernel

    vertices, faces = noisy_torus(triangles, seed=SEED)
    queries = _random_queries(QUERY_POINTS)
    rss_before = _worker.status_kilobytes("VmRSS")
    _worker.reset_peak()
    start = time.perf_counter()
    mesh = springwrap_kernel.TargetMesh(vertices, faces)
    build_seconds = time.perf_counter() - start
    peak_build = _worker.status_kilobytes("VmHWM")
    rss_built = _worker.status_kilobytes("VmRSS")
    start = time.perf_counter()
    mesh.prepare_all()
    prepare_seconds = time.perf_counter() - start
    rss_prepared = _worker.status_kilobytes("VmRSS")
    mesh.closest_points(queries[:64])  # the thread pool starts outside the timing
    query_seconds, hits = _best(lambda mesh=mesh: mesh.closest_points(queries), 3)
    if (hits.triangles < 0).any():
        raise RuntimeError("closest_points missed")
    count = len(faces)
    result = {
        "triangles": count,
        "vertices": len(vertices),
        "build_seconds": build_seconds,
        "prepare_all_seconds": prepare_seconds,
        "queries": len(queries),
        "query_seconds": query_seconds,
        "queries_per_second": len(queries) / query_seconds,
        "bytes_per_triangle_face_tree": (rss_built - rss_before) * 1024.0 / count,
        "bytes_per_triangle_peak_build": (peak_build - rss_before) * 1024.0 / count,
        "bytes_per_triangle_all": (rss_prepared - rss_before) * 1024.0 / count,
        "input_bytes_per_triangle": (vertices.nbytes + faces.nbytes) / count,
    }
    del mesh
    result.update(_shrinkwrap_first_evaluation(vertices, faces, queries))
    return result


def _shrinkwrap_first_evaluation(vertices, faces, queries) -> dict:
    """Blender's Shrinkwrap (NEAREST_SURFACEPOINT) on the query points: first evaluation (BVH build + queries)."""
    import bpy

    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    target = _worker.mesh_object(bpy, "Target", vertices, faces)
    cloud = _worker.mesh_object(bpy, "Points", queries)
    modifier = cloud.modifiers.new("Shrinkwrap", "SHRINKWRAP")
    modifier.wrap_method = "NEAREST_SURFACEPOINT"
    modifier.target = target
    modifier.show_viewport = False
    bpy.context.evaluated_depsgraph_get()
    modifier.show_viewport = True
    start = time.perf_counter()
    evaluated = cloud.evaluated_get(bpy.context.evaluated_depsgraph_get())
    positions = np.empty(len(queries) * 3, dtype=np.float32)
    evaluated.data.vertices.foreach_get("co", positions)
    seconds = time.perf_counter() - start
    if np.allclose(positions.reshape(-1, 3), queries):
        raise RuntimeError("the Shrinkwrap modifier did not move the points")
    return {"shrinkwrap_first_evaluation_seconds": seconds}


def worker_layout(points: int) -> dict:
    """closest_points of ~``points`` random-order queries on the 1M-triangle target."""
    from _noisy_torus import noisy_torus

    import springwrap_kernel

    vertices, faces = noisy_torus(LAYOUT_TARGET_TRIANGLES, seed=SEED)
    queries = _random_queries(points)
    mesh = springwrap_kernel.TargetMesh(vertices, faces)
    mesh.closest_points(queries[:64])
    seconds, hits = _best(lambda: mesh.closest_points(queries), 3 if points <= 1_000_000 else 1)
    if (hits.triangles < 0).any():
        raise RuntimeError("closest_points missed")
    return {
        "points": points,
        "target_triangles": len(faces),
        "query_seconds": seconds,
        "queries_per_second": points / seconds,
        "threads": os.environ.get("RAYON_NUM_THREADS", str(os.cpu_count())),
    }


def worker_wrap(quads: int) -> dict:
    """detach, snap, wrap (fixed iterations) through the add-on's operators on a ~``quads`` quad grid."""
    import bpy  # noqa: I001 - bpy first, then the add-on
    import addon_utils

    sys.path.insert(0, str(REPOSITORY_ROOT))
    from _noisy_torus import noisy_torus, torus_layout

    from benchmarks.retarget.springwrap_methods import captured_stdout, parse_wrap_report

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        raise RuntimeError("addon_utils.enable('springwrap') failed: run `make setup` first")
    vertices, faces = noisy_torus(WRAP_TARGET_TRIANGLES, seed=SEED)
    layout_vertices, layout_quads = torus_layout(quads, seed=LAYOUT_SEED)
    target = _worker.mesh_object(bpy, "Target", vertices, faces)
    layout = _worker.mesh_object(bpy, "Layout", layout_vertices, layout_quads)
    layout.springwrap.target = target
    bpy.context.view_layer.update()
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    times = {}
    for name, operator, properties in (
        ("detach", bpy.ops.springwrap.detach, {}),
        ("snap", bpy.ops.springwrap.snap, {"mode": "SURFACE"}),
        ("wrap", bpy.ops.springwrap.wrap, {"max_iterations": WRAP_ITERATIONS, "tolerance": 1e-12}),
    ):
        start = time.perf_counter()
        with captured_stdout() as output:
            result = operator(**properties)
        times[name] = time.perf_counter() - start
        if result != {"FINISHED"}:
            raise RuntimeError(f"springwrap.{name} returned {result}: {output[0][-300:]}")
    report = parse_wrap_report(output[0])
    return {
        "layout_vertices": len(layout_vertices),
        "layout_quads": len(layout_quads),
        "target_triangles": len(faces),
        "detach_seconds": times["detach"],
        "snap_seconds": times["snap"],
        "wrap_seconds": times["wrap"],
        "wrap_iterations": report.iterations,
        "wrap_report_seconds": report.seconds,
        "iterations_per_second": report.iterations / times["wrap"],
        "vertex_iterations_per_second": report.iterations * len(layout_vertices) / times["wrap"],
    }


WORKERS = {"target": worker_target, "layout": worker_layout, "wrap": worker_wrap, "threads": worker_layout}


def run_worker(kind: str, size: int) -> dict:
    """In the worker process: measure, then add the process's peak resident set."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    result = WORKERS[kind](size)
    result["process_peak_megabytes"] = _worker.status_kilobytes("VmHWM") / 1024.0
    return result


# ---------------------------------------------------------------- the sweep


def machine_description() -> dict:
    """CPU, cores, versions, commit."""
    cpu = _machine.cpu_model()
    versions = subprocess.run(
        [
            sys.executable,
            "-c",
            "import bpy, numpy, springwrap_kernel as k; "
            "print(bpy.app.version_string); print(numpy.__version__); print(k.__version__)",
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\n")
    sys.path.insert(0, str(REPOSITORY_ROOT))
    from benchmarks.retarget.run import kernel_build  # the workers load the same installed module

    commit = (
        subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"], cwd=REPOSITORY_ROOT, capture_output=True, text=True
        ).stdout.strip()
        or "unknown"
    )
    if subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPOSITORY_ROOT, capture_output=True, text=True
    ).stdout.strip():
        commit += "+dirty"  # tracked files changed since the commit (the installed kernel wheel may differ too)
    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "bpy": versions[0],
        "numpy": versions[1],
        "springwrap_kernel": versions[2],
        "kernel_build": kernel_build(),
        "git_commit": commit,
        "load_average": list(os.getloadavg()),
    }


def measure(kind: str, size: int, threads: int | None = None) -> dict:
    """Run one worker in a fresh process; its result with the load average around it."""
    environment = dict(os.environ)
    # A fixed mmap threshold (glibc): big blocks are always mapped and given back when freed. Left
    # dynamic, freeing the geometry's numpy temporaries raises the threshold and the kernel's arrays
    # then reuse the freed heap, so the resident-set growth under-counts them (39 B/triangle at
    # 100k, 186 at 1M in one try).
    environment.setdefault("MALLOC_MMAP_THRESHOLD_", "131072")
    if threads is not None:
        environment["RAYON_NUM_THREADS"] = str(threads)
    load_before = os.getloadavg()[0]
    start = time.perf_counter()
    process = subprocess.run(
        [sys.executable, __file__, "--worker", kind, str(size)], capture_output=True, text=True, env=environment
    )
    lines = [line for line in process.stdout.splitlines() if line.startswith("RESULT ")]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"worker {kind} {size} failed ({process.returncode}):\n{process.stderr[-2000:]}")
    result = json.loads(lines[-1][len("RESULT ") :])
    result.update(
        kind=kind,
        requested=size,
        worker_seconds=time.perf_counter() - start,
        load_average_before=load_before,
        load_average_after=os.getloadavg()[0],
    )
    return result


def describe(result: dict) -> str:
    """One progress line."""
    kind = result["kind"]
    if kind == "target":
        return (
            f"target {result['triangles']:>9,} triangles: build {result['build_seconds']:.3f} s, "
            f"prepare_all {result['prepare_all_seconds']:.3f} s, {result['queries_per_second']:,.0f} snaps/s, "
            f"{result['bytes_per_triangle_face_tree']:.0f} B/triangle (face tree), "
            f"{result['bytes_per_triangle_all']:.0f} B/triangle (all), "
            f"Shrinkwrap first evaluation {result['shrinkwrap_first_evaluation_seconds']:.3f} s"
        )
    if kind in ("layout", "threads"):
        return (
            f"{kind} {result['points']:>9,} points on {result['target_triangles']:,} triangles, "
            f"{result['threads']} threads: {result['query_seconds']:.3f} s, "
            f"{result['queries_per_second']:,.0f} snaps/s"
        )
    return (
        f"wrap {result['layout_vertices']:>9,} vertices: detach {result['detach_seconds']:.2f} s, snap "
        f"{result['snap_seconds']:.2f} s, wrap {result['wrap_iterations']} iterations {result['wrap_seconds']:.2f} s "
        f"({result['iterations_per_second']:.1f} it/s, {result['vertex_iterations_per_second']:,.0f} vertex-it/s)"
    )


def sweep(quick: bool) -> dict:
    """Every measurement of the sweep, each in its own process."""
    sizes = QUICK if quick else FULL
    results: dict[str, list[dict]] = {"target": [], "layout": [], "wrap": [], "threads": []}
    for kind in ("target", "layout", "wrap"):
        for size in sizes[kind]:
            result = measure(kind, size)
            results[kind].append(result)
            print(
                f"  {describe(result)}  [{result['worker_seconds']:.1f} s, load {result['load_average_before']:.2f}]",
                flush=True,
            )
    for size in sizes["threads"]:
        for threads in sorted({1, os.cpu_count() or 1}):
            result = measure("threads", size, threads)
            results["threads"].append(result)
            print(
                f"  {describe(result)}  [{result['worker_seconds']:.1f} s, load {result['load_average_before']:.2f}]",
                flush=True,
            )
    return results


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--worker"]:
        result = run_worker(argv[1], int(argv[2]))
        print("RESULT " + json.dumps(result), flush=True)
        return 0
    parser = argparse.ArgumentParser(prog="performance.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the small subset (about a minute)")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"where to write ({DEFAULT_JSON})")
    arguments = parser.parse_args(argv)
    machine = machine_description()
    print(
        f"performance sweep ({'quick' if arguments.quick else 'full'}): {machine['cpu']}, {machine['cpu_count']} CPUs, "
        f"load average {os.getloadavg()[0]:.2f}",
        flush=True,
    )
    start = time.perf_counter()
    try:
        results = sweep(arguments.quick)
    except RuntimeError as error:
        print(f"performance.py: {error}", file=sys.stderr)
        return 1
    output = {
        "benchmark": "performance",
        "quick": arguments.quick,
        "machine": machine,
        "finished_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "parameters": {
            "query_points": QUERY_POINTS,
            "layout_target_triangles": LAYOUT_TARGET_TRIANGLES,
            "wrap_target_triangles": WRAP_TARGET_TRIANGLES,
            "wrap_iterations": WRAP_ITERATIONS,
        },
        "seconds": time.perf_counter() - start,
        "results": results,
    }
    arguments.json.parent.mkdir(parents=True, exist_ok=True)
    arguments.json.write_text(json.dumps(output, indent=1) + "\n")
    print(f"wrote {arguments.json} ({output['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
