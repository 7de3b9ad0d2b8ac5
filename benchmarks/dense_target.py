"""Dense scans: the kernel's target build, its memory and the body's wrap on targets of up to 20 million triangles.

    .venv/bin/python benchmarks/dense_target.py [--sizes 1250000 5000000 20000000] [--no-wrap] [--json PATH]

The target is the retarget benchmark's ``heavy`` body (MakeHuman with the heavy morph, placed elsewhere),
voxel-remeshed by Blender to about ``BASE_TRIANGLES`` and then split into four by its edges' midpoints as often
as a size needs (1.25M, 5M, 20M triangles: the same surface, denser), as a scan is dense. Each size runs in a
**fresh subprocess** (this script with ``--worker``), with glibc's ``MALLOC_MMAP_THRESHOLD_`` fixed as
``large_target.py`` does, so that the resident set follows what is allocated and freed. In it:

- **build**: ``springwrap_kernel.TargetMesh(vertices, triangles)`` (validation and the face tree), then
  ``prepare_all()`` (the closest-point tree, the vertex tree, adjacency and normals: what a wrap queries), each
  timed (wall clock, and the process's processor time over all its threads: on a busy machine the wall clock
  says more about the others); the process's peak resident set over both (``VmHWM``, reset first) above what it held before, per
  triangle, and what the mesh keeps once built. Aims: the build at most 0.3 s per million triangles, at most
  200 B per triangle.
- **wrap** (unless ``--no-wrap``): the MakeHuman quad body (13,380 vertices) aligned by its 24 landmarks and
  wrapped onto the dense target, a Blender mesh object made first, through the add-on's operators as
  ``wrap_speed.measure_body`` runs them (detach, 24 ``anchor_add``, ``springwrap.wrap``; the detach reads the
  target from Blender once and builds its own kernel mesh, the others reuse it: ``target_reads``): wall clock and
  processor time from the first operator to the wrap's end, the wrap's iterations and error, and the peak resident
  set over them above the scene (the dense Blender mesh already in it), per triangle.

Prints one line per size and writes ``out/bench/dense_target.json``; ``benchmarks/report.py`` makes its table in
``docs/benchmarks.md`` (*Dense targets*). The 20M size needs about 10 GB at its peak.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
DEFAULT_JSON = REPOSITORY / "out" / "bench" / "dense_target.json"
SIZES = (1_250_000, 5_000_000, 20_000_000)
BASE_TRIANGLES = 1_250_000
"""The voxel remesh aims at this many triangles; larger sizes are midpoint splits of it."""
BUILD_AIM_SECONDS_PER_MILLION = 0.3
BYTES_PER_TRIANGLE_AIM = 200.0


def split_by_midpoints(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle split into four by its edges' midpoints (shared between the two triangles of an edge): the
    same surface with four times the triangles. float32 (V', 3), uint32 (4T, 3)."""
    count = len(vertices)
    a, b, c = (triangles[:, index].astype(np.int64) for index in range(3))
    starts = np.concatenate([a, b, c])
    ends = np.concatenate([b, c, a])
    keys = np.minimum(starts, ends) * count + np.maximum(starts, ends)
    edges, edge_of = np.unique(keys, return_inverse=True)
    midpoints = (vertices[edges // count].astype(np.float64) + vertices[edges % count]) * 0.5
    middle = (edge_of.reshape(3, -1) + count).astype(np.uint32)
    ab, bc, ca = middle
    a, b, c = (triangles[:, index].astype(np.uint32) for index in range(3))
    split = np.stack(
        [
            np.stack([a, ab, ca], axis=1),
            np.stack([ab, b, bc], axis=1),
            np.stack([ca, bc, c], axis=1),
            np.stack([ab, bc, ca], axis=1),
        ],
        axis=1,
    ).reshape(-1, 3)
    return np.concatenate([vertices, midpoints.astype(np.float32)]), np.ascontiguousarray(split)


def dense_body(triangles: int):
    """(case, vertices, triangles): the body remeshed to ``BASE_TRIANGLES`` (fewer when ``triangles`` is smaller)
    and split until it has about ``triangles``."""
    from benchmarks.wrap_speed import body_case

    splits = 0
    while BASE_TRIANGLES * 4 ** (splits + 1) <= triangles * 1.5:
        splits += 1
    case, vertices, faces, _voxel = body_case(max(1, round(triangles / 4**splits)))
    vertices, faces = np.asarray(vertices, dtype=np.float32), np.asarray(faces, dtype=np.uint32)
    for _ in range(splits):
        vertices, faces = split_by_midpoints(vertices, faces)
    return case, vertices, faces


def worker(triangles: int, wrap: bool) -> dict:
    """In the worker process: the dense body, the kernel's build of it, then the wrap onto it."""
    import bpy  # noqa: I001 - bpy first, then the add-on
    import addon_utils

    sys.path.insert(0, str(REPOSITORY))
    sys.path.insert(0, str(REPOSITORY / "benchmarks"))
    import _worker

    import springwrap_kernel

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        raise RuntimeError("addon_utils.enable('springwrap') failed: run `make setup` first")
    start = time.perf_counter()
    case, vertices, faces = dense_body(triangles)
    count = len(faces)
    result = {"triangles": count, "vertices": len(vertices), "make_seconds": time.perf_counter() - start}

    def per_triangle(kilobytes: float) -> float:
        return kilobytes * 1024.0 / count

    gc.collect()
    before = _worker.status_kilobytes("VmRSS")
    _worker.reset_peak()
    start, start_cpu = time.perf_counter(), _worker.cpu_seconds()
    mesh = springwrap_kernel.TargetMesh(vertices, faces)
    built, built_cpu = time.perf_counter(), _worker.cpu_seconds()
    mesh.prepare_all()
    prepared, prepared_cpu = time.perf_counter(), _worker.cpu_seconds()
    result["build"] = {
        "seconds": built - start,
        "prepare_seconds": prepared - built,
        "cpu_seconds": built_cpu - start_cpu,
        "prepare_cpu_seconds": prepared_cpu - built_cpu,
        "seconds_per_million": (built - start) / count * 1e6,
        "all_seconds_per_million": (prepared - start) / count * 1e6,
        "peak_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmHWM") - before),
        "kept_bytes_per_triangle": per_triangle(_worker.status_kilobytes("VmRSS") - before),
    }
    del mesh
    gc.collect()
    if wrap:
        result["wrap"] = measure_wrap(case, vertices, faces, per_triangle)
    result["load_average"] = round(os.getloadavg()[0], 2)
    return result


def measure_wrap(case, vertices: np.ndarray, faces: np.ndarray, per_triangle) -> dict:
    """The body wrapped onto the dense target through the operators, as ``wrap_speed.measure_body`` runs them
    (detach, 24 ``anchor_add``, ``springwrap.wrap``), the target object made first: its time, processor time,
    iterations and error, the peak resident set over it above the scene (the dense Blender mesh in it), and how
    often the operators read, hashed or built the target."""
    import bpy

    import _worker

    from benchmarks.retarget import baselines, metrics, springwrap_methods
    from benchmarks.wrap_speed import aligned_template
    from springwrap.blender import target as blender_target

    aligned, landmark_vertices, anchors = aligned_template(case)
    baselines.clear_scene()
    target = baselines.mesh_object("Target", vertices, faces)
    bpy.context.view_layer.update()
    blender_target.clear_target_cache()
    gc.collect()
    scene = _worker.status_kilobytes("VmRSS")
    _worker.reset_peak()
    start, start_cpu = time.perf_counter(), _worker.cpu_seconds()
    positions, _notes, report = springwrap_methods.springwrap_wrap(
        aligned, case.layout_quads, target, landmark_vertices, anchors
    )
    seconds, cpu = time.perf_counter() - start, _worker.cpu_seconds() - start_cpu
    peak = per_triangle(_worker.status_kilobytes("VmHWM") - scene)
    error = metrics.vertex_errors(positions, case.true_positions) / case.diagonal * 100.0
    return {
        "seconds": seconds,
        "cpu_seconds": cpu,
        "solve_seconds": report.seconds,
        "iterations": report.iterations,
        "converged": report.converged,
        "error_percent_mean": float(error[~case.in_cavity].mean()),
        "peak_bytes_per_triangle": peak,
        "target_reads": blender_target.target_reads(),
    }


def measure(triangles: int, wrap: bool) -> dict:
    """Run the worker for one size in a fresh process."""
    environment = dict(os.environ)
    environment.setdefault("MALLOC_MMAP_THRESHOLD_", "131072")
    command = [sys.executable, __file__, "--worker", str(triangles)] + ([] if wrap else ["--no-wrap"])
    process = subprocess.run(command, capture_output=True, text=True, env=environment)
    lines = [line for line in process.stdout.splitlines() if line.startswith("RESULT ")]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"worker failed ({process.returncode}):\n{process.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :])


def describe(result: dict) -> str:
    build = result["build"]
    line = (
        f"{result['triangles']:>11,} triangles: TargetMesh {build['seconds']:.2f} s "
        f"({build['seconds_per_million']:.3f} s/M; {build['cpu_seconds']:.2f} s CPU), prepare_all "
        f"{build['prepare_seconds']:.2f} s ({build['prepare_cpu_seconds']:.2f} s CPU), "
        f"peak {build['peak_bytes_per_triangle']:.0f} B/triangle, kept {build['kept_bytes_per_triangle']:.0f}"
    )
    if "wrap" in result:
        wrap = result["wrap"]
        line += (
            f"; wrap {wrap['seconds']:.1f} s ({wrap['cpu_seconds']:.1f} s CPU, {wrap['iterations']} iterations, "
            f"error {wrap['error_percent_mean']:.3f} %), peak "
            f"{wrap['peak_bytes_per_triangle']:.0f} B/triangle above the scene"
        )
    return line + f" (load {result['load_average']})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), help="target triangle counts")
    parser.add_argument("--no-wrap", action="store_true", help="only the kernel's build, not the body's wrap")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    parser.add_argument("--worker", type=int, metavar="TRIANGLES", help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.worker:
        print("RESULT " + json.dumps(worker(arguments.worker, not arguments.no_wrap)))
        return 0
    sys.path.insert(0, str(REPOSITORY))
    from benchmarks import _machine

    machine = {"cpu": _machine.cpu_model(), "cpu_count": os.cpu_count(), "load_average": os.getloadavg()[0]}
    report = {"machine": machine, "sizes": []}
    for size in arguments.sizes:
        result = measure(size, not arguments.no_wrap)
        print(describe(result), flush=True)
        report["sizes"].append(result)
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
