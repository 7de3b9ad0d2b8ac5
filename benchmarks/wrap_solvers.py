"""The wrap's accuracy beside trimesh's non-rigid ICP, through the kernel alone.

For each retargeting case (``benchmarks/retarget/cases.py``): the template aligned to the anchors
(Umeyama, as the retarget benchmark's ``aligned template``), the anchors as face-points at the
closest target point to their truth, then a ``springwrap_kernel.WrapSolver`` with the kernel's default
``WrapSettings()`` (one energy, local–global steps, no face turned over). Per solver (``ENERGY``, the wrap): mean / p95 / max error (% of the truth's diagonal), flipped
quads and how many were added over the aligned template, vertices off the surface where the surface
exists (farther than 0.1 % of the diagonal), iterations and seconds. ``--nricp`` adds trimesh's
``nricp_amberg`` on the same aligned template and anchors in the same run (``benchmarks/requirements.txt``).
``--markdown`` writes the table as a page (``docs/wrap-solvers.md`` in ``make bench``).

``--scans`` adds real scans without a known answer (``benchmarks/retarget/scans.py``: the range-scanned
bunny, CGAL's elephant with holes), in a second table: the aligned template's and each solver's
distance to the scan where it has surface, quads turned over against the template and against the
scan, stretch (quad area and edge length over the template's), iterations and seconds. A page is
written by sections: a section whose cases were not run (``--cases`` with no name, or no
``--scans``) is kept as the existing page has it.

    .venv/bin/python benchmarks/wrap_solvers.py --cases heavy sphere-ellipsoid --json out/bench/wrap_solvers.json
    .venv/bin/python benchmarks/wrap_solvers.py --cases --scans --markdown docs/wrap-solvers.md   # the scans alone
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.retarget import baselines, cases, data, metrics, scans

SOLVERS = ("ENERGY",)
OFF_SURFACE_PERCENT = 0.1
BODY_CASES = (
    "heavy",
    "heavy-holes",
    "heavy-noise",
    "heavy-noise-strong",
    "old-male",
    "old-male-holes",
    "young-female",
    "head-nose",
    "expression",
    "heavy-posed",
)
ALL_CASES = ("sphere-ellipsoid", "sphere-ellipsoid-holes", "sphere-bumps", *BODY_CASES)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        nargs="*",
        default=list(ALL_CASES),
        help="case names (default: all but the mirror; none with `--cases` alone)",
    )
    parser.add_argument(
        "--scans",
        nargs="*",
        metavar="SCAN",
        help="also the scans without a known answer: those named, or all with `--scans` alone "
        f"({', '.join(spec.name for spec in scans.SCAN_CASES)})",
    )
    parser.add_argument("--anchors", type=int, default=24, help="anchors per case (default 24)")
    parser.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    parser.add_argument(
        "--max-iterations", type=int, default=None, help="iteration limit per solver (default: the wrap's own)"
    )
    parser.add_argument("--nricp", action="store_true", help="also run trimesh's nricp_amberg (slow: ~20 s a body)")
    parser.add_argument("--json", type=Path, help="write every number here")
    parser.add_argument("--markdown", type=Path, help="write the table as a markdown page here")
    arguments = parser.parse_args(argv)
    if arguments.max_iterations is None:
        import bpy  # noqa: F401  (Blender's modules, then the add-on enabled the scripts' way)

        from benchmarks.retarget.run import enable_addon

        enable_addon()
        from springwrap.core import defaults

        arguments.max_iterations = defaults.MAX_ITERATIONS
    return arguments


def prepared(case, anchor_count: int):
    """(landmark vertices, their true positions, the aligned template) of ``case``."""
    marks = case.landmarks(anchor_count)
    anchors = case.true_positions[marks.vertices]
    aligned = baselines.apply_matrix(
        baselines.umeyama(case.layout_vertices[marks.vertices], anchors), case.layout_vertices
    ).astype(np.float32)
    return marks.vertices, anchors, aligned


def measure(
    case,
    method: str,
    positions: np.ndarray,
    aligned: np.ndarray,
    landmark_vertices,
    target,
    seconds: float,
    space_points: int,
    iterations: int,
    converged: bool,
) -> dict:
    """One row: the metrics of ``positions`` on ``case``."""
    measured = metrics.evaluate(
        positions, case.true_positions, case.layout_quads, target, case.over_hole, case.in_cavity, landmark_vertices
    )
    aligned_flips = int(metrics.flipped_quads(aligned, case.true_positions, case.layout_quads).sum())
    on_surface = ~case.over_hole & ~case.in_cavity
    off = metrics.surface_distances(positions, target) * 100.0 / measured.diagonal > OFF_SURFACE_PERCENT
    normals = smoothed_target_normals(case)
    folded, truth_folded = (
        folded_on_surface(case, target, points, measured.diagonal, normals)
        for points in (positions, case.true_positions)
    )
    return {
        "case": case.spec.name,
        "solver": method,
        "mean": measured.error_percent.mean,
        "p95": measured.error_percent.p95,
        "max": measured.error_percent.max,
        "flipped": measured.flipped_quads,
        "flips_added": measured.flipped_quads - aligned_flips,
        "folded": folded,
        "truth_folded": truth_folded,
        "off_surface": int((off & on_surface).sum()),
        "space_points": space_points,
        "iterations": iterations,
        "converged": converged,
        "seconds": seconds,
    }


def smoothed_target_normals(case, rounds: int = 16) -> np.ndarray:
    """(V, 3) unit vertex normals of the case's target (area-weighted), averaged ``rounds`` times over each
    vertex's triangles: a noisy target's single triangles face anywhere, its surface does not."""
    from scipy import sparse

    vertices = np.asarray(case.target_vertices, dtype=np.float64)
    triangles = np.asarray(case.target_triangles, dtype=np.int64)
    face_normals = np.cross(
        vertices[triangles[:, 1]] - vertices[triangles[:, 0]], vertices[triangles[:, 2]] - vertices[triangles[:, 0]]
    )
    rows = triangles.ravel()
    columns = np.repeat(np.arange(len(triangles)), 3)
    incidence = sparse.csr_matrix((np.ones(len(rows)), (rows, columns)), shape=(len(vertices), len(triangles)))
    normals = incidence @ face_normals
    averaging = incidence @ incidence.T
    for _ in range(rounds):
        normals = averaging @ (normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30))
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)


def folded_on_surface(case, target, positions: np.ndarray, diagonal: float, normals: np.ndarray) -> int:
    """Quads of ``positions`` facing against the target's smoothed normal (``normals``, per target vertex)
    under their centre, where the centre is within ``OFF_SURFACE_PERCENT`` of the target and not on a
    hole's rim: folds an artist sees on the surface, whatever the truth says (the truth itself faces
    against a remeshed target where the remesh merged its parts)."""
    flipped, _over, distances = metrics.target_facing_flips(
        positions, case.layout_quads, target, case.target_vertices, case.target_triangles, normals
    )
    return int((flipped & (distances <= OFF_SURFACE_PERCENT * diagonal / 100.0)).sum())


def wrap(
    target,
    quads: np.ndarray,
    aligned: np.ndarray,
    anchor_vertices: np.ndarray,
    anchor_positions: np.ndarray,
    solver: str,
    max_iterations: int,
):
    """One kernel wrap of ``aligned`` onto ``target`` with face-point anchors at the target's closest
    points to ``anchor_positions``: (positions, the step's report, seconds)."""
    import springwrap_kernel as kernel

    quads = np.ascontiguousarray(quads, dtype=np.uint32)
    structure = kernel.LayoutStructure(len(aligned), quads.ravel(), np.full(len(quads), 4, dtype=np.uint32))
    hits = target.closest_points(np.ascontiguousarray(anchor_positions, dtype=np.float32))
    count = len(aligned)
    start = time.perf_counter()
    solver_object = kernel.WrapSolver(
        target,
        structure,
        np.zeros(count, np.int32),
        np.full(count, -1, np.int32),
        np.zeros((count, 3), np.float32),
        np.ascontiguousarray(aligned, dtype=np.float32),
        anchor_vertices=np.ascontiguousarray(anchor_vertices, dtype=np.uint32),
        anchor_triangles=hits.triangles,
        anchor_barycentrics=hits.barycentrics,
        anchor_positions=hits.positions,
        settings=kernel.WrapSettings(),
    )
    report = solver_object.step(max_iterations)
    return solver_object.positions(), report, time.perf_counter() - start


def wrap_case(case, anchor_count: int, solver: str, max_iterations: int) -> dict:
    """Wrap the aligned template of ``case`` with one solver; its metrics."""
    import springwrap_kernel as kernel

    landmark_vertices, anchors, aligned = prepared(case, anchor_count)
    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    positions, report, seconds = wrap(
        target, case.layout_quads, aligned, landmark_vertices, anchors, solver, max_iterations
    )
    return measure(
        case,
        solver,
        positions,
        aligned,
        landmark_vertices,
        target,
        seconds,
        report.space_points,
        report.iterations,
        report.converged,
    )


def nricp_case(case, anchor_count: int) -> dict:
    """trimesh's nricp_amberg on the same aligned template and anchors; its metrics."""
    import springwrap_kernel as kernel

    landmark_vertices, anchors, aligned = prepared(case, anchor_count)
    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    start = time.perf_counter()
    positions, _notes = baselines.nricp_amberg(
        aligned.astype(np.float64), case.layout_quads, case.target_vertices, landmark_vertices, anchors
    )
    seconds = time.perf_counter() - start
    return measure(case, "nricp", positions, aligned, landmark_vertices, target, seconds, len(positions), 0, True)


# ---------------------------------------------------------------- scans (no known answer)


def aligned_scan_template(case) -> np.ndarray:
    """(N, 3) float32: the scan case's template moved onto its anchors by a similarity (Umeyama)."""
    matrix = baselines.umeyama(case.template_vertices[case.anchor_vertices], case.anchor_positions)
    return baselines.apply_matrix(matrix, case.template_vertices).astype(np.float32)


def scan_row(
    case,
    method: str,
    positions: np.ndarray,
    aligned: np.ndarray,
    target,
    seconds: float,
    space_points: int,
    iterations: int,
    converged: bool,
) -> dict:
    """One row of the scans' table: :func:`metrics.scan_metrics` of ``positions`` and the run's counts."""
    measured = metrics.scan_metrics(
        positions, aligned, case.template_quads, target, case.target_vertices, case.target_triangles
    )
    return {
        "case": case.spec.name,
        "solver": method,
        **measured.row(),
        "space_points": space_points,
        "iterations": iterations,
        "converged": converged,
        "seconds": seconds,
    }


def scan_rows(case, solvers: list[str], max_iterations: int, nricp: bool = False) -> list[dict]:
    """The aligned template's row, then one per solver (and nricp), on a scan case."""
    import springwrap_kernel as kernel

    target = kernel.TargetMesh(case.target_vertices, case.target_triangles)
    aligned = aligned_scan_template(case)
    rows = [scan_row(case, "template", aligned, aligned, target, 0.0, len(aligned), 0, True)]
    for solver in solvers:
        positions, report, seconds = wrap(
            target, case.template_quads, aligned, case.anchor_vertices, case.anchor_positions, solver, max_iterations
        )
        rows.append(
            scan_row(
                case,
                solver,
                positions,
                aligned,
                target,
                seconds,
                report.space_points,
                report.iterations,
                report.converged,
            )
        )
    if nricp:
        start = time.perf_counter()
        positions, _notes = baselines.nricp_amberg(
            aligned.astype(np.float64),
            case.template_quads,
            case.target_vertices,
            case.anchor_vertices,
            case.anchor_positions,
        )
        rows.append(
            scan_row(case, "nricp", positions, aligned, target, time.perf_counter() - start, len(positions), 0, True)
        )
    return rows


def scan_case_line(case) -> str:
    """A bullet saying what a scan case is made of (for the page)."""
    info = case.info
    return (
        f"- **{case.spec.name}**: {case.spec.description}. Scan: {info['target_triangles']:,} triangles, "
        f"{info['target_boundary_edges']:,} rim edges; template: {info['template_quads']:,} quads (voxel "
        f"{case.spec.voxel_fraction * 100:.2f} % of the diagonal), smoothed {case.spec.smooth_iterations} times, "
        f"pushed out by {case.spec.inflate_fraction * 100:g} % of the diagonal; its remeshed (unmoved) vertices "
        "were "
        f"{info['remeshed_to_scan_mean_percent']:.3f} % from the scan on average, the moved ones "
        f"{info['moved_to_scan_mean_percent']:.2f} %."
    )


# ---------------------------------------------------------------- the page

PAGE_TITLE = "# The wrap beside non-rigid ICP"
GENERATED = "<!-- Generated by benchmarks/wrap_solvers.py (`make bench`): do not edit by hand. -->"
SECTION = re.compile(r"^<!-- section: ([a-z-]+) -->$", re.MULTILINE)


def page_sections(page: str) -> dict[str, str]:
    """The sections of a page written by :func:`markdown` (name -> text, marker excluded). A page from
    before the sections (no marker) is one ``bodies`` section: everything after the generated note."""
    _head, found, body = page.partition(GENERATED)
    if not found:
        return {}
    markers = list(SECTION.finditer(body))
    sections = {}
    leading = body[: markers[0].start()] if markers else body
    if leading.strip():
        sections["bodies"] = leading.strip("\n")
    for index, marker in enumerate(markers):
        end = markers[index + 1].start() if index + 1 < len(markers) else len(body)
        sections[marker.group(1)] = body[marker.end() : end].strip("\n")
    return sections


def body_section(rows: list[dict], provenance: str = "") -> str:
    """The body cases' table, with what it measures and ``provenance`` (the commit, the load)."""
    lines = [
        "`ENERGY` is the wrap: one energy minimised by local-global steps with a sparse",
        "Cholesky (see [architecture](architecture.md#the-energy-wrap)); `nricp` trimesh's `nricp_amberg`; all start",
        "from the same template aligned to the same 24 anchors. Errors in % of the truth's bounding-box diagonal;",
        "*added*: flipped quads (against the truth) beyond the aligned template's; *folded*: quads facing against",
        f"the target's smoothed normal under their centre, the centre within {OFF_SURFACE_PERCENT} % of the diagonal of it (folds on",
        "the surface, whatever the truth says; in brackets the truth's own, where the remesh merged its parts); *off*:",
        "vertices farther than",
        f"{OFF_SURFACE_PERCENT} % of the diagonal from the target where it has surface; *space*: space-points at the end",
        "(for nricp, every vertex is free).",
        "",
        *([provenance, ""] if provenance else []),
        "| case | solver | mean | p95 | max | flipped | added | folded | off | space | iterations | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row['case']} | {row['solver']} | {row['mean']:.3f} | {row['p95']:.3f} | {row['max']:.3f} | "
            f"{row['flipped']} | {row['flips_added']} | {row['folded']} ({row['truth_folded']}) | "
            f"{row['off_surface']} | {row['space_points']} | "
            f"{row['iterations']} | {row['seconds']:.2f} |"
        )
    return "\n".join(lines)


def scan_section(rows: list[dict], provenance: str = "", case_lines: list[str] = ()) -> str:
    """The scans' table (no known answer: no error columns), with what it measures and ``provenance``."""
    lines = [
        "## Scanned surfaces (no known answer)",
        "",
        "Real range scans with holes, and a quad template of the same object that is not on them (built",
        "headless in Blender by `benchmarks/retarget/scans.py`, nothing committed): no truth, so no error. The",
        "template is aligned to 24 anchors (farthest-point samples, each paired with the scan point closest to",
        "its remeshed position: where a user would click) by a similarity, then wrapped with them; *template*",
        "is that aligned start.",
        "",
        *case_lines,
        *([""] if case_lines else []),
        "Distances to the scan in % of its bounding-box diagonal, over the vertices whose closest scan point is",
        "not on a hole's rim (those over a hole are left out); *off*: how many of them are farther than",
        f"{metrics.OFF_SURFACE_PERCENT} %. Flipped quads: *vs template* turned more than 90° from the aligned",
        "template's quad; *vs scan* facing against the scan's triangle under the quad centre's closest point",
        "(centres over the surface), *on scan* those of them whose centre is within "
        f"{metrics.OFF_SURFACE_PERCENT} % of the scan",
        "(a centre floating farther off can face the far side of a thin part). Stretch over the aligned template:",
        "quad area ratio (5th, 50th, 95th percentile), edge length ratio (5th, 95th), and *out*: quads / edges",
        f"whose ratio is below 1/{metrics.STRETCH_LIMIT:g} or above {metrics.STRETCH_LIMIT:g}. *space*: space-points "
        "at the end.",
        "",
        *([provenance, ""] if provenance else []),
        "| case | solver | mean | p95 | max | off | vs template | vs scan | on scan | area p5 | area p50 | area p95 "
        "| edge p5 | edge p95 | out | space | iterations | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row['case']} | {row['solver']} | {row['distance_mean']:.3f} | {row['distance_p95']:.3f} | "
            f"{row['distance_max']:.3f} | {row['off_surface']} | {row['flipped_vs_template']} | "
            f"{row['flipped_vs_target']} | {row['flipped_vs_target_on_surface']} | {row['area_p5']:.2f} | "
            f"{row['area_median']:.2f} | {row['area_p95']:.2f} | {row['edge_p5']:.2f} | {row['edge_p95']:.2f} | "
            f"{row['area_below'] + row['area_above']} / {row['edge_below'] + row['edge_above']} | "
            f"{row['space_points']} | {row['iterations']} | {row['seconds']:.2f} |"
        )
    return "\n".join(lines)


def markdown(
    rows: list[dict],
    provenance: str = "",
    scan_rows: list[dict] = (),
    scan_provenance: str = "",
    scan_case_lines: list[str] = (),
    existing: str = "",
) -> str:
    """The generated page: the body cases' section from ``rows`` and the scans' from ``scan_rows``; a
    section with no rows is taken from ``existing`` (the page as it was) when it has one, else left out.
    ``provenance`` (the commit, the load) is said under each regenerated section's text."""
    kept = page_sections(existing)
    sections = {}
    if rows:
        sections["bodies"] = body_section(rows, provenance)
    elif "bodies" in kept:
        sections["bodies"] = kept["bodies"]
    if scan_rows:
        sections["scans"] = scan_section(scan_rows, scan_provenance or provenance, list(scan_case_lines))
    elif "scans" in kept:
        sections["scans"] = kept["scans"]
    lines = [PAGE_TITLE, "", GENERATED]
    for name, text in sections.items():
        lines += ["", f"<!-- section: {name} -->", "", text]
    return "\n".join(lines) + "\n"


def provenance() -> str:
    """The commit and the machine's load now, in one line."""
    import os
    import subprocess

    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parents[1],
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg()) if hasattr(os, "getloadavg") else "unknown"
    return (
        f"Run at commit `{commit}` on {os.cpu_count()} CPUs, load average (1, 5, 15 min) {load} at the end: "
        "the machine was shared, so times are upper bounds."
    )


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    import bpy  # noqa: F401  (cases are built with Blender's remesher)

    cache = data.cache_folder()
    rows = []
    body_specs = cases.case_specs(arguments.cases) if arguments.cases else []
    if body_specs:
        print(
            f"{'case':<22} {'solver':<8} {'mean %':>8} {'p95 %':>8} {'max %':>8} {'flips':>6} {'added':>6} "
            f"{'folded':>6} {'off':>6} {'space':>6} {'iter':>6} {'s':>7}"
        )
    for spec in body_specs:
        case, _ = cases.get_case(spec, cache)
        anchor_count = min(arguments.anchors, len(case.landmark_names))
        methods = [*arguments.solvers, *(["nricp"] if arguments.nricp else [])]
        for solver in methods:
            if solver == "nricp":
                row = nricp_case(case, anchor_count)
            else:
                row = wrap_case(case, anchor_count, solver, arguments.max_iterations)
            rows.append(row)
            print(
                f"{row['case']:<22} {solver:<8} {row['mean']:8.3f} {row['p95']:8.3f} {row['max']:8.3f} "
                f"{row['flipped']:6d} {row['flips_added']:6d} {row['folded']:6d} {row['off_surface']:6d} {row['space_points']:6d} "
                f"{row['iterations']:6d} {row['seconds']:7.2f}",
                flush=True,
            )
    body_provenance = provenance() if rows else ""
    found_scans, case_lines = [], []
    if arguments.scans is not None:
        print(
            f"{'scan':<16} {'solver':<8} {'mean %':>7} {'p95 %':>7} {'max %':>7} {'off':>5} {'flipT':>5} "
            f"{'flipS':>5} {'onS':>5} {'area p5/50/95':>15} {'edge p5/95':>10} {'out':>7} {'space':>6} {'iter':>5} "
            f"{'s':>6}"
        )
    for spec in scans.scan_specs(arguments.scans) if arguments.scans is not None else []:
        case, _ = scans.get_scan(spec, cache)
        anchor_count = min(arguments.anchors, len(case.anchor_vertices))
        # The anchors are farthest-point samples: their first k are a spread of k.
        case.anchor_vertices = case.anchor_vertices[:anchor_count]
        case.anchor_positions = case.anchor_positions[:anchor_count]
        case_lines.append(scan_case_line(case))
        for row in scan_rows(case, arguments.solvers, arguments.max_iterations, arguments.nricp):
            found_scans.append(row)
            print(
                f"{row['case']:<16} {row['solver']:<8} {row['distance_mean']:7.3f} {row['distance_p95']:7.3f} "
                f"{row['distance_max']:7.3f} {row['off_surface']:5d} {row['flipped_vs_template']:5d} "
                f"{row['flipped_vs_target']:5d} {row['flipped_vs_target_on_surface']:5d} "
                f"{row['area_p5']:5.2f}/{row['area_median']:4.2f}/{row['area_p95']:4.2f} "
                f"{row['edge_p5']:4.2f}/{row['edge_p95']:4.2f} "
                f"{row['area_below'] + row['area_above']:3d}/{row['edge_below'] + row['edge_above']:<3d} "
                f"{row['space_points']:6d} {row['iterations']:5d} {row['seconds']:6.2f}",
                flush=True,
            )
    if arguments.json:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(
            json.dumps({"benchmark": "wrap_solvers", "rows": rows, "scan_rows": found_scans}, indent=1)
        )
    if arguments.markdown:
        arguments.markdown.parent.mkdir(parents=True, exist_ok=True)
        existing = arguments.markdown.read_text() if arguments.markdown.is_file() else ""
        arguments.markdown.write_text(
            markdown(rows, body_provenance, found_scans, provenance() if found_scans else "", case_lines, existing)
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
