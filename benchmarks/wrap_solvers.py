"""The wrap's two solvers side by side, through the kernel alone (no Blender operator in the loop).

For each retargeting case (``benchmarks/retarget/cases.py``): the template aligned to the anchors
(Umeyama, as the retarget benchmark's ``aligned template``), the anchors as face-points at the
closest target point to their truth, then a ``springwrap_kernel.WrapSolver`` with
``solver="SPRINGS"`` (the paper's force iteration) and ``solver="ENERGY"`` (one energy, local–global
steps, no face turned over). Per solver: mean / p95 / max error (% of the truth's diagonal), flipped
quads and how many were added over the aligned template, vertices off the surface where the surface
exists (farther than 0.1 % of the diagonal), iterations and seconds.

    .venv/bin/python benchmarks/wrap_solvers.py --cases heavy sphere-ellipsoid --json out/bench/wrap_solvers.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.retarget import baselines, cases, data, metrics  # noqa: E402

SOLVERS = ("SPRINGS", "ENERGY")
OFF_SURFACE_PERCENT = 0.1


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["sphere-ellipsoid", "heavy"], help="case names")
    parser.add_argument("--anchors", type=int, default=24, help="anchors per case (default 24)")
    parser.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    parser.add_argument("--max-iterations", type=int, default=2000, help="iteration limit per solver")
    parser.add_argument("--json", type=Path, help="write every number here")
    return parser.parse_args(argv)


def wrap_case(case, anchor_count: int, solver: str, max_iterations: int) -> dict:
    """Wrap the aligned template of ``case`` with one solver; its metrics."""
    import springwrap_kernel as kernel

    marks = case.landmarks(anchor_count)
    anchors = case.true_positions[marks.vertices]
    aligned = baselines.apply_matrix(baselines.umeyama(case.layout_vertices[marks.vertices], anchors),
                                     case.layout_vertices).astype(np.float32)
    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    quads = np.ascontiguousarray(case.layout_quads, dtype=np.uint32)
    structure = kernel.LayoutStructure(len(aligned), quads.ravel(), np.full(len(quads), 4, dtype=np.uint32))
    hits = target.closest_points(np.ascontiguousarray(anchors, dtype=np.float32))
    count = len(aligned)
    start = time.perf_counter()
    solver_object = kernel.WrapSolver(
        target, structure, np.zeros(count, np.int32), np.full(count, -1, np.int32),
        np.zeros((count, 3), np.float32), np.ascontiguousarray(aligned),
        anchor_vertices=np.ascontiguousarray(marks.vertices, dtype=np.uint32),
        anchor_triangles=hits.triangles, anchor_barycentrics=hits.barycentrics,
        anchor_positions=hits.positions, solver=solver,
    )
    report = solver_object.step(max_iterations)
    seconds = time.perf_counter() - start
    positions = solver_object.positions()
    measured = metrics.evaluate(positions, case.true_positions, case.layout_quads, target, case.over_hole,
                                case.in_cavity, marks.vertices)
    aligned_flips = int(metrics.flipped_quads(aligned, case.true_positions, case.layout_quads).sum())
    on_surface = ~case.over_hole & ~case.in_cavity
    off = metrics.surface_distances(positions, target) * 100.0 / measured.diagonal > OFF_SURFACE_PERCENT
    return {
        "case": case.spec.name,
        "solver": solver,
        "mean": measured.error_percent.mean,
        "p95": measured.error_percent.p95,
        "max": measured.error_percent.max,
        "flipped": measured.flipped_quads,
        "flips_added": measured.flipped_quads - aligned_flips,
        "off_surface": int((off & on_surface).sum()),
        "space_points": report.space_points,
        "iterations": report.iterations,
        "converged": report.converged,
        "seconds": seconds,
    }


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    import bpy  # noqa: F401  (cases are built with Blender's remesher)

    cache = data.cache_folder()
    rows = []
    print(f"{'case':<22} {'solver':<8} {'mean %':>8} {'p95 %':>8} {'max %':>8} {'flips':>6} {'added':>6} "
          f"{'off':>6} {'space':>6} {'iter':>6} {'s':>7}")
    for spec in cases.case_specs(arguments.cases):
        case, _ = cases.get_case(spec, cache)
        for solver in arguments.solvers:
            row = wrap_case(case, min(arguments.anchors, len(case.landmark_names)), solver, arguments.max_iterations)
            rows.append(row)
            print(f"{row['case']:<22} {solver:<8} {row['mean']:8.3f} {row['p95']:8.3f} {row['max']:8.3f} "
                  f"{row['flipped']:6d} {row['flips_added']:6d} {row['off_surface']:6d} {row['space_points']:6d} "
                  f"{row['iterations']:6d} {row['seconds']:7.2f}", flush=True)
    if arguments.json:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps({"benchmark": "wrap_solvers", "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
