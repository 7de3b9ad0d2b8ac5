"""The wrap's two solvers side by side (and trimesh's non-rigid ICP), through the kernel alone.

For each retargeting case (``benchmarks/retarget/cases.py``): the template aligned to the anchors
(Umeyama, as the retarget benchmark's ``aligned template``), the anchors as face-points at the
closest target point to their truth, then a ``springwrap_kernel.WrapSolver`` with
``WrapSettings(solver="SPRINGS")`` (the paper's force iteration) and ``WrapSettings(solver="ENERGY")``
(one energy, local–global steps, no face turned over), the kernel's defaults otherwise. Per solver: mean / p95 / max error (% of the truth's diagonal), flipped
quads and how many were added over the aligned template, vertices off the surface where the surface
exists (farther than 0.1 % of the diagonal), iterations and seconds. ``--nricp`` adds trimesh's
``nricp_amberg`` on the same aligned template and anchors in the same run (``benchmarks/requirements.txt``).
``--markdown`` writes the table as a page (``docs/wrap-solvers.md`` in ``make bench``).

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
BODY_CASES = ("heavy", "heavy-holes", "heavy-noise", "heavy-noise-strong", "old-male", "old-male-holes", "young-female",
              "head-nose", "expression", "heavy-posed")
ALL_CASES = ("sphere-ellipsoid", "sphere-ellipsoid-holes", "sphere-bumps", *BODY_CASES)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(ALL_CASES), help="case names (default: all but the mirror)")
    parser.add_argument("--anchors", type=int, default=24, help="anchors per case (default 24)")
    parser.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    parser.add_argument("--max-iterations", type=int, default=2000, help="iteration limit per solver")
    parser.add_argument("--nricp", action="store_true", help="also run trimesh's nricp_amberg (slow: ~20 s a body)")
    parser.add_argument("--json", type=Path, help="write every number here")
    parser.add_argument("--markdown", type=Path, help="write the table as a markdown page here")
    return parser.parse_args(argv)


def prepared(case, anchor_count: int):
    """(landmark vertices, their true positions, the aligned template) of ``case``."""
    marks = case.landmarks(anchor_count)
    anchors = case.true_positions[marks.vertices]
    aligned = baselines.apply_matrix(baselines.umeyama(case.layout_vertices[marks.vertices], anchors),
                                     case.layout_vertices).astype(np.float32)
    return marks.vertices, anchors, aligned


def measure(case, method: str, positions: np.ndarray, aligned: np.ndarray, landmark_vertices, target, seconds: float,
            space_points: int, iterations: int, converged: bool) -> dict:
    """One row: the metrics of ``positions`` on ``case``."""
    measured = metrics.evaluate(positions, case.true_positions, case.layout_quads, target, case.over_hole,
                                case.in_cavity, landmark_vertices)
    aligned_flips = int(metrics.flipped_quads(aligned, case.true_positions, case.layout_quads).sum())
    on_surface = ~case.over_hole & ~case.in_cavity
    off = metrics.surface_distances(positions, target) * 100.0 / measured.diagonal > OFF_SURFACE_PERCENT
    return {
        "case": case.spec.name,
        "solver": method,
        "mean": measured.error_percent.mean,
        "p95": measured.error_percent.p95,
        "max": measured.error_percent.max,
        "flipped": measured.flipped_quads,
        "flips_added": measured.flipped_quads - aligned_flips,
        "off_surface": int((off & on_surface).sum()),
        "space_points": space_points,
        "iterations": iterations,
        "converged": converged,
        "seconds": seconds,
    }


def wrap_case(case, anchor_count: int, solver: str, max_iterations: int) -> dict:
    """Wrap the aligned template of ``case`` with one solver; its metrics."""
    import springwrap_kernel as kernel

    landmark_vertices, anchors, aligned = prepared(case, anchor_count)
    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    quads = np.ascontiguousarray(case.layout_quads, dtype=np.uint32)
    structure = kernel.LayoutStructure(len(aligned), quads.ravel(), np.full(len(quads), 4, dtype=np.uint32))
    hits = target.closest_points(np.ascontiguousarray(anchors, dtype=np.float32))
    count = len(aligned)
    start = time.perf_counter()
    solver_object = kernel.WrapSolver(
        target, structure, np.zeros(count, np.int32), np.full(count, -1, np.int32),
        np.zeros((count, 3), np.float32), np.ascontiguousarray(aligned),
        anchor_vertices=np.ascontiguousarray(landmark_vertices, dtype=np.uint32),
        anchor_triangles=hits.triangles, anchor_barycentrics=hits.barycentrics,
        anchor_positions=hits.positions, settings=kernel.WrapSettings(solver=solver),
    )
    report = solver_object.step(max_iterations)
    seconds = time.perf_counter() - start
    return measure(case, solver, solver_object.positions(), aligned, landmark_vertices, target, seconds,
                   report.space_points, report.iterations, report.converged)


def nricp_case(case, anchor_count: int) -> dict:
    """trimesh's nricp_amberg on the same aligned template and anchors; its metrics."""
    import springwrap_kernel as kernel

    landmark_vertices, anchors, aligned = prepared(case, anchor_count)
    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    start = time.perf_counter()
    positions, _notes = baselines.nricp_amberg(aligned.astype(np.float64), case.layout_quads, case.target_vertices,
                                               landmark_vertices, anchors)
    seconds = time.perf_counter() - start
    return measure(case, "nricp", positions, aligned, landmark_vertices, target, seconds, len(positions), 0, True)


def markdown(rows: list[dict], provenance: str = "") -> str:
    """The rows as a generated markdown page; ``provenance`` (the commit, the load) is said under the title."""
    lines = [
        "# The wrap's two solvers",
        "",
        "<!-- Generated by benchmarks/wrap_solvers.py (`make bench`): do not edit by hand. -->",
        "",
        "`SPRINGS` is the paper's force iteration, `ENERGY` one energy minimised by local-global steps with a sparse",
        "Cholesky (see [architecture](architecture.md#the-energy-wrap)), `nricp` trimesh's `nricp_amberg`; all start",
        "from the same template aligned to the same 24 anchors. Errors in % of the truth's bounding-box diagonal;",
        "*added*: flipped quads (against the truth) beyond the aligned template's; *off*: vertices farther than",
        f"{OFF_SURFACE_PERCENT} % of the diagonal from the target where it has surface; *space*: space-points at the end",
        "(for nricp, every vertex is free).",
        "",
        *([provenance, ""] if provenance else []),
        "| case | solver | mean | p95 | max | flipped | added | off | space | iterations | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(f"| {row['case']} | {row['solver']} | {row['mean']:.3f} | {row['p95']:.3f} | {row['max']:.3f} | "
                     f"{row['flipped']} | {row['flips_added']} | {row['off_surface']} | {row['space_points']} | "
                     f"{row['iterations']} | {row['seconds']:.2f} |")
    return "\n".join(lines) + "\n"


def provenance() -> str:
    """The commit and the machine's load now, in one line."""
    import os
    import subprocess

    try:
        commit = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True,
                                check=True, cwd=Path(__file__).resolve().parents[1]).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg()) if hasattr(os, "getloadavg") else "unknown"
    return (f"Run at commit `{commit}` on {os.cpu_count()} CPUs, load average (1, 5, 15 min) {load} at the end: "
            "the machine was shared, so times are upper bounds.")


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    import bpy  # noqa: F401  (cases are built with Blender's remesher)

    cache = data.cache_folder()
    rows = []
    print(f"{'case':<22} {'solver':<8} {'mean %':>8} {'p95 %':>8} {'max %':>8} {'flips':>6} {'added':>6} "
          f"{'off':>6} {'space':>6} {'iter':>6} {'s':>7}")
    for spec in cases.case_specs(arguments.cases):
        case, _ = cases.get_case(spec, cache)
        anchor_count = min(arguments.anchors, len(case.landmark_names))
        methods = [*arguments.solvers, *(["nricp"] if arguments.nricp else [])]
        for solver in methods:
            if solver == "nricp":
                row = nricp_case(case, anchor_count)
            else:
                row = wrap_case(case, anchor_count, solver, arguments.max_iterations)
            rows.append(row)
            print(f"{row['case']:<22} {solver:<8} {row['mean']:8.3f} {row['p95']:8.3f} {row['max']:8.3f} "
                  f"{row['flipped']:6d} {row['flips_added']:6d} {row['off_surface']:6d} {row['space_points']:6d} "
                  f"{row['iterations']:6d} {row['seconds']:7.2f}", flush=True)
    if arguments.json:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps({"benchmark": "wrap_solvers", "rows": rows}, indent=1))
    if arguments.markdown:
        arguments.markdown.parent.mkdir(parents=True, exist_ok=True)
        arguments.markdown.write_text(markdown(rows, provenance()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
