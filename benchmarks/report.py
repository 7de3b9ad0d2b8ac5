"""Write ``docs/benchmarks.md`` from the benchmarks' JSON output: every number in it comes from a run.

    .venv/bin/python benchmarks/report.py [--retarget out/bench/retarget.json]
        [--performance out/bench/performance.json] [--snap out/bench/snap_throughput.json]
        [--batch out/bench/batch_throughput.json] [--output docs/benchmarks.md]

Reads the retargeting benchmark (``benchmarks.retarget.run``), the performance sweep
(``benchmarks/performance.py``), the snap throughput comparison (``benchmarks/snap_throughput.py
--json``) and the batch throughput (``benchmarks/batch_throughput.py --json``); a missing file leaves its section out and says so. Figures are expected under
``docs/img/`` (``benchmarks/figures.py``) and linked when present. No ``bpy``, no kernel: the
functions here take the parsed JSON and return Markdown, and are unit-tested on made-up inputs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
OUT = REPOSITORY_ROOT / "out" / "bench"
DOCS = REPOSITORY_ROOT / "docs"

SPRINGWRAP_METHODS = (
    "Springwrap snap",
    "Springwrap wrap",
    "Springwrap wrap local",
    "Springwrap wrap global",
    "Springwrap snap+wrap",
    "Springwrap project+wrap",
    "Springwrap align",
    "Springwrap align+wrap",
    "Springwrap wrap+mirror",
    "Springwrap armature",
    "Springwrap armature+wrap",
)
BASELINE_METHODS = ("aligned template", "Shrinkwrap nearest", "Shrinkwrap project", "trimesh nricp_amberg")


# ---------------------------------------------------------------- formatting


def number(value, digits: int = 3) -> str:
    """A float with ``digits`` decimals, ``-`` for None / NaN, ``inf`` for infinities."""
    if value is None:
        return "-"
    value = float(value)
    if math.isnan(value):
        return "-"
    if math.isinf(value):
        return "inf"
    return f"{value:.{digits}f}"


def table(header: list[str], rows: list[list[str]], align: str | None = None) -> list[str]:
    """Markdown table lines; ``align`` is one character per column (``l`` or ``r``)."""
    align = align or "l" + "r" * (len(header) - 1)
    rule = ["---:" if character == "r" else ":---" for character in align]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(rule) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return lines


def is_body(record: dict) -> bool:
    """A body case (model units are metres) rather than a synthetic one."""
    return record.get("spec", {}).get("source") == "anny"


# ---------------------------------------------------------------- retarget


def case_rows(record: dict) -> list[list[str]]:
    """One row per method of a case: errors (% and mm), surface, holes, quality, time, memory, status."""
    body = is_body(record)
    rows = []
    for method, entry in record["methods"].items():
        metrics = entry.get("metrics")
        notes = "; ".join(entry.get("notes") or [])
        if metrics is not None and metrics.get("nonfinite_vertices"):
            notes = f"**{metrics['nonfinite_vertices']} vertices non-finite (NaN)**" + (f"; {notes}" if notes else "")
        status = entry["status"] if entry["status"] != "ok" else ""
        comment = " — ".join(part for part in (status, notes) if part)
        if metrics is None:
            rows.append([method] + ["-"] * 12 + [number(entry.get("seconds"), 2), "-", comment])
            continue
        millimetres = [
            number(metrics[f"error_{field}"] * 1000.0, 1) if body else "-" for field in ("mean", "p95", "max")
        ]
        rows.append(
            [
                method,
                number(metrics["error_percent_mean"]),
                number(metrics["error_percent_p95"]),
                number(metrics["error_percent_max"], 2),
                *millimetres,
                number(metrics["surface_distance_percent_mean"], 4),
                number(metrics["error_over_holes_percent_mean"]),
                str(metrics["flipped_quads"]),
                str(metrics["degenerate_quads"]),
                number(metrics["angle_distortion_degrees"], 2),
                number(metrics["anchor_error_percent"]),
                number(entry.get("seconds"), 2),
                number(entry.get("peak_megabytes"), 0),
                comment,
            ]
        )
    return rows


CASE_HEADER = [
    "method",
    "mean %",
    "p95 %",
    "max %",
    "mean mm",
    "p95 mm",
    "max mm",
    "surface %",
    "holes %",
    "flipped",
    "degenerate",
    "angle °",
    "anchors %",
    "time s",
    "MB",
    "status / notes",
]


def ordered_methods(records: list[dict]) -> list[str]:
    """Every method of the records: the baselines, then Springwrap's, then any other, in first-seen order."""
    seen = list(dict.fromkeys(method for record in records for method in record["methods"]))
    known = [method for method in BASELINE_METHODS + SPRINGWRAP_METHODS if method in seen]
    return known + [method for method in seen if method not in known]


def mean_over_cases(records: list[dict], method: str, field: str) -> tuple[float, int]:
    """The mean of ``field`` over the cases where ``method`` produced metrics, and how many there were."""
    values = [
        record["methods"][method]["metrics"][field]
        for record in records
        if record["methods"].get(method, {}).get("metrics") is not None
    ]
    return (sum(values) / len(values), len(values)) if values else (float("nan"), 0)


def best_method(record: dict, field: str = "error_percent_mean", exclude: tuple[str, ...] = ()) -> str | None:
    """The method with the smallest ``field`` on a case (among those with metrics), or None."""
    scored = [
        (entry["metrics"][field], method)
        for method, entry in record["methods"].items()
        if entry.get("metrics") is not None and method not in exclude
    ]
    return min(scored)[1] if scored else None


def headline(retarget: dict) -> list[str]:
    """The summary: per method, mean and p95 error averaged over the body cases, how often it is best, times."""
    records = retarget["cases"]
    body = [record for record in records if is_body(record)] or records
    methods = ordered_methods(body)
    wins = {method: 0 for method in methods}
    for record in body:
        best = best_method(record, exclude=("aligned template",))
        if best is not None:
            wins[best] += 1
    rows = []
    for method in methods:
        mean, count = mean_over_cases(body, method, "error_percent_mean")
        p95, _ = mean_over_cases(body, method, "error_percent_p95")
        flipped, _ = mean_over_cases(body, method, "flipped_quads")
        seconds = [
            record["methods"][method]["seconds"]
            for record in body
            if record["methods"].get(method, {}).get("metrics") is not None
        ]
        statuses = sorted(
            {
                record["methods"][method]["status"].split(":")[0]
                for record in body
                if method in record["methods"] and record["methods"][method].get("metrics") is None
            }
        )
        nonfinite = sum(
            1 for record in body if (record["methods"].get(method, {}).get("metrics") or {}).get("nonfinite_vertices")
        )
        if nonfinite:
            statuses.append(f"non-finite vertices on {nonfinite}")
        case_means = sorted(
            record["methods"][method]["metrics"]["error_percent_mean"]
            for record in body
            if record["methods"].get(method, {}).get("metrics") is not None
        )
        median = (
            (
                case_means[len(case_means) // 2]
                if len(case_means) % 2
                else sum(case_means[len(case_means) // 2 - 1 : len(case_means) // 2 + 1]) / 2
            )
            if case_means
            else None
        )
        rows.append(
            [
                method,
                f"{count} / {len(body)}",
                number(mean),
                number(median),
                number(p95),
                number(flipped, 0),
                number(sum(seconds) / len(seconds), 2) if seconds else "-",
                str(wins[method]) if method != "aligned template" else "(reference)",
                ", ".join(statuses),
            ]
        )
    kind = "body" if any(is_body(record) for record in records) else "all"
    diagonals = [
        entry["metrics"]["diagonal"]
        for record in body
        for entry in record["methods"].values()
        if entry.get("metrics") is not None
    ]
    scale = (
        f" (1 % is {number(sum(diagonals) / len(diagonals) * 10.0, 1)} mm on the body)"
        if diagonals and kind == "body"
        else ""
    )
    lines = [
        f"Averaged over the {len(body)} {kind} cases of this run ({retarget['arguments'].get('anchors')} anchors); "
        f"errors in % of the truth's bounding-box diagonal{scale}:",
        "",
    ]
    lines += table(
        [
            "method",
            "cases with a result",
            "mean error %",
            "median of the cases' means %",
            "p95 error %",
            "flipped quads",
            "time s",
            "best on (cases)",
            "other outcomes",
        ],
        rows,
        "lrrrrrrrl",
    )
    springwrap = [method for method in methods if method in SPRINGWRAP_METHODS]
    baselines = [method for method in methods if method in BASELINE_METHODS and method != "aligned template"]
    scored = {method: mean_over_cases(body, method, "error_percent_mean")[0] for method in methods}
    finite = {method: value for method, value in scored.items() if not math.isnan(value)}
    if finite:
        best = min(finite, key=finite.get)
        lines += ["", f"Lowest mean error over these cases: **{best}** ({number(finite[best])} %)."]
    for method in springwrap:
        if method not in finite:
            continue
        comparisons = [f"{other} {number(finite[other])} %" for other in baselines if other in finite]
        verdict = (
            "better than"
            if all(finite[method] < finite[other] for other in baselines if other in finite)
            else "not better than every baseline:"
        )
        lines.append(f"- {method}: {number(finite[method])} % mean error, {verdict} " + ", ".join(comparisons) + ".")
    lines += outcome_notes(records)
    lines += [
        "",
        "Mean error per case (% of the diagonal; the lowest of each row in bold, the aligned template "
        "left out of the contest):",
        "",
    ] + error_matrix(records)
    return lines


def outcome_notes(records: list[dict]) -> list[str]:
    """What else happened: refusals and failures (with the message and the cases), non-finite results,
    wraps that stopped at the iteration limit."""
    messages: dict[tuple[str, str], list[str]] = {}
    nonfinite: dict[str, list[str]] = {}
    wraps: dict[str, list[bool]] = {}
    for record in records:
        for method, entry in record["methods"].items():
            if entry["status"] != "ok":
                # the message without vertex numbers, so one cause on several cases reads once
                kind, _, message = entry["status"].partition(": ")
                generic = " ".join("N" if word.isdigit() else word for word in message.split(" "))
                messages.setdefault((method, f"{kind}: {generic}"), []).append(record["case"])
            count = (entry.get("metrics") or {}).get("nonfinite_vertices")
            if count:
                nonfinite.setdefault(method, []).append(f"{record['case']} ({count} of {record['layout_vertices']:,})")
            details = entry.get("details") or {}
            if "converged" in details:
                wraps.setdefault(method, []).append(bool(details["converged"]))
    lines = []
    for (method, message), case_names in messages.items():
        lines.append(f"- {method}, {len(case_names)} case(s) ({', '.join(case_names)}): {message}")
    for method, cases_text in nonfinite.items():
        lines.append(f"- {method} wrote non-finite (NaN) vertex positions on {', '.join(cases_text)}.")
    for method, converged in wraps.items():
        lines.append(
            f"- {method} converged on {sum(converged)} of {len(converged)} cases "
            "(the others stopped at the iteration limit)."
        )
    return ["", "Outcomes to note (all cases):", ""] + lines if lines else []


def error_matrix(records: list[dict]) -> list[str]:
    """A case x method table of mean errors, the best retargeting method of each case in bold."""
    methods = ordered_methods(records)
    rows = []
    for record in records:
        best = best_method(record, exclude=("aligned template",))
        row = [record["case"]]
        for method in methods:
            entry = record["methods"].get(method)
            if entry is None:
                row.append("")
            elif entry.get("metrics") is None:
                row.append(entry["status"].split(":")[0])
            else:
                text = number(entry["metrics"]["error_percent_mean"])
                row.append(f"**{text}**" if method == best else text)
        rows.append(row)
    return table(["case"] + methods, rows)


def retarget_section(retarget: dict, image_folder: Path, image_prefix: str) -> list[str]:
    """The per-case tables and the figures of the retargeting benchmark."""
    arguments = retarget["arguments"]
    lines = ["## Accuracy: retargeting with a known answer", ""]
    lines.append(
        f"Run: {'`--quick` (' if arguments.get('quick') else 'all cases ('}{len(retarget['cases'])} cases), "
        f"{arguments.get('anchors')} anchors, {number(retarget.get('seconds'), 0)} s in all"
        + (
            f", wrap capped at {arguments['wrap_max_iterations']} iterations"
            if arguments.get("wrap_max_iterations")
            else ", the wrap at its default iteration limit"
        )
        + "."
    )
    lines += [
        "",
        "Columns: error to the true position (mean, 95th percentile, max) in % of the truth's bounding-box "
        "diagonal and in mm (body cases); *surface*: mean distance to the target surface where it exists (%); "
        "*holes*: mean error of the vertices over holes (%); *flipped* / *degenerate*: quads whose normal "
        "turned against the true one / whose area fell under 1 % of the true area; *angle*: mean |corner angle "
        "− true corner angle|; *anchors*: mean error at the anchored landmarks (%); *time*: wall time of the "
        "method (for Springwrap, every operator call); *MB*: growth of the process's peak resident memory "
        "(methods share one process, so later ones often read 0).",
        "",
    ]
    bars = image_folder / "errors-per-method.png"
    if bars.exists():
        lines += [f"![mean and p95 error per method and case]({image_prefix}/{bars.name})", ""]
    for record in retarget["cases"]:
        spec = record.get("spec", {})
        lines += [f"### {record['case']}", ""]
        description = spec.get("description") or ""
        lines.append(
            f"{description} Layout {record['layout_vertices']:,} vertices / {record['layout_quads']:,} quads; "
            f"target {record['target_triangles']:,} triangles; {record['over_hole']} vertices over holes, "
            f"{record['in_cavity']} in cavities.".strip()
        )
        lines.append("")
        lines += table(CASE_HEADER, case_rows(record), "l" + "r" * 14 + "l")
        heatmap = image_folder / f"heatmap-{record['case']}.png"
        if heatmap.exists():
            lines += ["", f"![error heat-map, {record['case']}]({image_prefix}/{heatmap.name})"]
        lines.append("")
    return lines


# ---------------------------------------------------------------- performance


def snap_section(snap: dict) -> list[str]:
    """The snap throughput comparison (``benchmarks/snap_throughput.py --json``)."""
    sizes = snap["sizes"]
    lines = [
        "### Snap throughput: kernel vs Shrinkwrap vs mathutils BVHTree",
        "",
        f"Target: noisy torus, {sizes['target_triangles']:,} triangles; {sizes['points']:,} query points within "
        f"{sizes['query_offset']} of the surface, asked in mesh order (*coherent*) and shuffled (*random*). "
        f"Load average at the start: {snap['machine'].get('load_average')}.",
        "",
    ]
    rows = []
    for row in snap["results"]:
        note = f"extrapolated from {row['measured_queries']:,}" if row.get("extrapolated") else ""
        rows.append(
            [
                row["method"],
                row["order"],
                f"{row['queries']:,}",
                number(row["seconds"]),
                f"{row['queries_per_second']:,.0f}",
                number(row["build_seconds"]),
                note,
            ]
        )
    lines += table(["method", "order", "queries", "seconds", "queries/s", "build s", "note"], rows, "llrrrrl")
    operator = snap.get("operator")
    if operator:
        lines += [
            "",
            f"Through the operator: `springwrap.snap` on a {operator['layout_vertices']:,}-vertex quad layout takes "
            f"{number(operator['seconds'])} s, of which the quality read-out (distance, stretch, flipped faces; "
            f"measured and written) {number(operator['readout_seconds'])} s "
            f"({100.0 * operator['readout_share']:.0f} %)"
            + (
                f"; in processor time (all threads; what other work on the machine skews least) "
                f"{number(operator['readout_cpu_seconds'])} of {number(operator['cpu_seconds'])} s "
                f"({100.0 * operator['readout_cpu_share']:.0f} %)"
                if "readout_cpu_share" in operator
                else ""
            )
            + f"; Shrinkwrap on the same layout {number(operator['shrinkwrap_seconds'])} s.",
        ]
        steps = operator.get("separate_steps")
        if steps:
            lines[-1] += (
                f" The read-out is one kernel call (world positions, distances, stretch and flips in Rust); the same "
                f"snaps with the read-out in separate steps (world copies in numpy, then the kernel's stretch and flips "
                f"and its distances), alternating with them: {number(steps['seconds'])} s, of which the read-out "
                f"{number(steps['readout_seconds'])} s ({100.0 * steps['readout_share']:.0f} %; processor time "
                f"{number(steps['readout_cpu_seconds'])} of {number(steps['cpu_seconds'])} s, "
                f"{100.0 * steps['readout_cpu_share']:.0f} %)."
            )
    failed = [check["name"] for check in snap.get("checks", []) if not check.get("passed")]
    lines += [
        "",
        "Checks (kernel against Shrinkwrap, mathutils BVHTree and KDTree, random against coherent order): "
        + ("all passed." if not failed else "FAILED: " + "; ".join(failed)),
        "",
    ]
    return lines


def pair_tool_section(pair: dict) -> list[str]:
    """The pair tool on the body (``benchmarks/pair_tool.py --json``): a drag's and a hover's mouse moves per second,
    and the Live re-settle after each edit (the session's build, its first frame, the edited vertex half way,
    convergence, the solving alone), edit by edit and their medians."""
    load = pair.get("load_average")
    load_text = ", ".join(number(value, 2) for value in load) if isinstance(load, list) else number(load, 2)
    end = pair.get("load_average_end")
    end_text = ", ".join(number(value, 2) for value in end) if isinstance(end, list) else number(end, 2)
    drag, hover = pair["drag"], pair["hover"]
    lines = [
        "### Pair tool",
        "",
        f"The MakeHuman body ({pair['layout_vertices']:,} vertices) over a {pair['target_triangles']:,}-triangle "
        "voxel-remeshed body, wrapped once, then edited as the pair tool edits it, without a window "
        "(`.venv/bin/python benchmarks/pair_tool.py`): a pair's target end dragged in "
        f"{drag['moves']} mouse moves (a ray cast and the anchor written each: {number(drag['moves_per_second'], 0)} "
        f"moves/s, {drag['placed']} placed), hovering the same path ({number(hover['moves_per_second'], 0)} moves/s), "
        "and after each edit the Live re-settle from the layout as it is (seconds from the edit; *solving*: the "
        "kernel's share). Load average at the start "
        f"{load_text}, at the end {end_text}. Redraws per second while dragging need a window: the GUI lane "
        "(`make test-gui`) reports them.",
        "",
    ]
    rows = [
        [
            str(row["edit"] + 1),
            number(row["vertex_moved_m"] * 1000.0, 1),
            number(row["build_seconds"]),
            number(row["first_frame_seconds"]),
            number(row["half_way_seconds"]),
            number(row["total_seconds"]),
            number(row["solve_seconds"]),
            str(row["iterations"]),
            "yes" if row["converged"] else "no",
        ]
        for row in pair["settle"]
    ]
    rows.append(["median", "", *(number(pair[f"settle_median_{name}"]) for name in SETTLE_COLUMNS), "", ""])
    header = ["edit", "vertex moved mm", "build s", "first frame s", "half way s", "converged s", "solving s"]
    lines += table(header + ["iterations", "converged"], rows, "lrrrrrrrl") + [""]
    live = pair.get("live_drag")
    if live:
        lines += [
            f"A drag during a Live re-settle ({live['moves']} mouse moves, 60 a second, each handed to the running "
            "solver): from a mouse move to the first frame written that was solved with it (or a later move; the "
            f"redraw not counted), median {number(live['median_seconds'] * 1000.0, 0)} ms, 90th percentile "
            f"{number(live['p90_seconds'] * 1000.0, 0)} ms, at most {number(live['max_seconds'] * 1000.0, 0)} ms "
            f"({live['answered']} moves answered).",
            "",
        ]
    return lines


SETTLE_COLUMNS = ("build_seconds", "first_frame_seconds", "half_way_seconds", "total_seconds", "solve_seconds")
"""The Live re-settle's times, in the pair tool table's order."""


def performance_section(performance: dict, image_folder: Path, image_prefix: str) -> list[str]:
    """Scaling with target and layout size, wrap speed, memory per triangle, threads."""
    results = performance["results"]
    parameters = performance["parameters"]
    lines = [
        f"### Scaling ({'quick subset' if performance.get('quick') else 'full sweep'}, "
        f"{number(performance.get('seconds'), 0)} s, each size in a fresh process)",
        "",
    ]
    scaling = image_folder / "scaling.png"
    if scaling.exists():
        lines += [f"![time against target and layout size, log-log]({image_prefix}/{scaling.name})", ""]
    if results.get("target"):
        lines += [
            f"**Target size** (kernel `TargetMesh` build, `prepare_all()`, snap of {parameters['query_points']:,} "
            "random points; Blender's Shrinkwrap on the same points, first evaluation = its BVH build + the "
            "queries; memory = growth of the resident set over the triangle count):",
            "",
        ]
        rows = [
            [
                f"{row['triangles']:,}",
                number(row["build_seconds"]),
                number(row["prepare_all_seconds"]),
                number(row["query_seconds"]),
                f"{row['queries_per_second']:,.0f}",
                number(row["shrinkwrap_first_evaluation_seconds"]),
                number(row["bytes_per_triangle_face_tree"], 0),
                number(row["bytes_per_triangle_peak_build"], 0),
                number(row["bytes_per_triangle_all"], 0),
                number(row["process_peak_megabytes"], 0),
                number(row["load_average_before"], 2),
            ]
            for row in results["target"]
        ]
        lines += table(
            [
                "triangles",
                "build s",
                "prepare_all s",
                "snap s",
                "snaps/s",
                "Shrinkwrap s",
                "B/tri face tree",
                "B/tri build peak",
                "B/tri all trees",
                "process peak MB",
                "load",
            ],
            rows,
        )
        lines.append("")
    if results.get("layout"):
        lines += [
            f"**Layout size** (kernel `closest_points`, random order, on {parameters['layout_target_triangles']:,} "
            "triangles):",
            "",
        ]
        rows = [
            [
                f"{row['points']:,}",
                number(row["query_seconds"]),
                f"{row['queries_per_second']:,.0f}",
                number(row["process_peak_megabytes"], 0),
                number(row["load_average_before"], 2),
            ]
            for row in results["layout"]
        ]
        lines += table(["points", "seconds", "snaps/s", "process peak MB", "load"], rows)
        lines.append("")
    if results.get("wrap"):
        lines += [
            f"**Wrap** (the add-on's operators on a torus quad grid over {parameters['wrap_target_triangles']:,} "
            f"triangles: detach, snap, then `springwrap.wrap(max_iterations={parameters['wrap_iterations']}, "
            "tolerance=1e-12)`; the wrap's time includes building its solver and writing the mesh):",
            "",
        ]
        rows = [
            [
                f"{row['layout_vertices']:,}",
                number(row["detach_seconds"], 2),
                number(row["snap_seconds"], 2),
                str(row["wrap_iterations"]),
                number(row["wrap_seconds"], 2),
                number(row["iterations_per_second"], 1),
                f"{row['vertex_iterations_per_second']:,.0f}",
                number(row["process_peak_megabytes"], 0),
                number(row["load_average_before"], 2),
            ]
            for row in results["wrap"]
        ]
        lines += table(
            [
                "layout vertices",
                "detach s",
                "snap s",
                "iterations",
                "wrap s",
                "iterations/s",
                "vertex-iterations/s",
                "process peak MB",
                "load",
            ],
            rows,
        )
        lines.append("")
    if results.get("threads"):
        lines += ["**Threads** (`RAYON_NUM_THREADS`, closest_points of random points):", ""]
        rows = [
            [
                row["threads"],
                f"{row['points']:,}",
                f"{row['target_triangles']:,}",
                number(row["query_seconds"]),
                f"{row['queries_per_second']:,.0f}",
                number(row["load_average_before"], 2),
            ]
            for row in results["threads"]
        ]
        lines += table(["threads", "points", "triangles", "seconds", "snaps/s", "load"], rows)
        lines.append("")
    return lines


def wrap_speed_lines(retarget: dict) -> list[str]:
    """The wrap's iterations and speed on the retarget cases (from the wrap's own report)."""
    rows = []
    for record in retarget["cases"]:
        for method, entry in record["methods"].items():
            details = entry.get("details") or {}
            if "iterations" in details:
                rows.append(
                    [
                        record["case"],
                        method,
                        str(details["iterations"]),
                        "yes" if details["converged"] else "no (limit)",
                        number(details["wrap_seconds"], 2),
                        number(details["iterations_per_second"], 0),
                        number(entry["seconds"], 2),
                    ]
                )
    if not rows:
        return []
    return (
        [
            "### Wrap on the retarget cases",
            "",
            "Iterations and time as the wrap operator reported them; *total* adds detach, snap or project and the "
            "anchor_add calls.",
            "",
        ]
        + table(["case", "method", "iterations", "converged", "wrap s", "iterations/s", "total s"], rows, "llrlrrr")
        + [""]
    )


def wrap_aims_section(speed: dict) -> list[str]:
    """The wrap's speed aims against ``benchmarks/wrap_speed.py``'s measurements."""
    lines = [
        "### Wrap speed against its aims",
        "",
        "From `benchmarks/wrap_speed.py` (the body through the add-on's operators, the modal wrap's "
        "frames, and a 2048 x 2048 spring through the kernel).",
        "",
    ]
    rows = []
    body = speed.get("body")
    if body:
        wrap = body["wrap"]
        rows.append(
            [
                f"MakeHuman body ({body['layout_quads']} quads) onto {body['target_triangles']} triangles, "
                f"{body['anchors']} anchors: whole wrap",
                "0.5 s",
                f"{number(wrap['wrap_seconds'], 2)} s ({wrap['iterations']} iterations, "
                f"{'converged' if wrap['converged'] else 'not converged'}; operators "
                f"{number(body['operators_seconds'], 2)} s; error mean {number(body['error_percent_mean'])} %, "
                f"p95 {number(body['error_percent_p95'])} %)",
            ]
        )
    live = speed.get("live")
    if live:
        shown = live.get("redraws_per_second", live["frames_per_second"])
        rows.append(
            [
                "live wrap on the body: redraws per second",
                "30",
                f"{number(shown, 1)} ({number(live['frames_per_second'], 1)} with new positions, "
                f"{number(live['iterations_per_second'], 0)} iterations/s)",
            ]
        )
        cancel = live.get("cancel")
        if cancel:
            cancelled = [item for item in cancel["cancels"] if item.get("running")]
            restored = "put back bit for bit" if all(item.get("restored") for item in cancelled) else "NOT put back"
            rows.append(
                [
                    "live wrap on the body: Esc answered",
                    "0.2 s",
                    f"{number(cancel['worst_seconds'], 3)} s ({len(cancelled)} presses while it ran, the layout "
                    f"{restored})",
                ]
            )
    large = speed.get("large")
    if large:
        rows.append(
            [
                f"{large['spring_points']}-point spring onto {large['target_triangles']} triangles",
                "30 s",
                f"{number(large['seconds'], 1)} s for {large['iterations']} iterations "
                f"({'converged' if large['converged'] else 'cap reached'}), "
                f"{number(large['seconds_per_iteration'] * 1000, 0)} ms each, after a "
                f"{number(large['setup_seconds'], 1)} s set-up",
            ]
        )
    if not rows:
        return []
    machine = speed.get("machine", {})
    load = speed.get("load_average_end")
    load_text = ", ".join(number(value, 2) for value in load) if load else "?"
    return (
        lines
        + table(["measurement", "aim", "measured"], rows, "lll")
        + [
            "",
            f"Run {speed.get('started_utc', '?')}: {machine.get('cpu', '?')}, {machine.get('cores', '?')} cores, "
            f"Python {machine.get('python', '?')}, bpy {machine.get('bpy', '?')}; load average at the end {load_text}.",
            "",
        ]
    )


# ---------------------------------------------------------------- batch on a cluster

PROJECTED_MESHES, PROJECTED_NODES = 10_000, 100
# An assumption, not a measurement: what one shared file system (a single NFS server on a 10 Gb/s link)
# carries at best. The projection says how much the batch would ask of it.
SHARED_STORAGE_MB_PER_SECOND = 1_000


def _batch_run(batch: dict, executor: str, jobs: int) -> dict | None:
    return next((run for run in batch.get("runs", []) if run["executor"] == executor and run["jobs"] == jobs), None)


def batch_section(batch: dict) -> list[str]:
    """The *Batch on a cluster* section: the measured runs (``benchmarks/batch_throughput.py``) and, from them,
    a projection of PROJECTED_MESHES meshes on PROJECTED_NODES nodes like the one measured, with what limits it."""
    library, machine = batch["library"], batch["machine"]
    load = ", ".join(number(value, 2) for value in machine.get("load_average", []))
    if batch.get("load_average_end"):
        load += "; at the end " + ", ".join(number(value, 2) for value in batch["load_average_end"])
    lines = [
        "## Batch on a cluster",
        "",
        f"`retarget.py --batch` on a library of {library['meshes']} noisy tori of "
        f"{library['triangles']:,} triangles each (every one displaced differently), the template a "
        f"{library['layout_quads']:,}-quad layout, automatic anchors; each executor with 1 and 2 workers, "
        f"each run in a fresh output folder (`.venv/bin/python benchmarks/batch_throughput.py --json "
        f"out/bench/batch_throughput.json`). Machine: {machine.get('cpu', '?')}, {machine.get('cpu_count', '?')} "
        f"CPUs, {machine.get('memory_gib', '?')} GiB; ray {batch.get('versions', {}).get('ray', '?')}, commit "
        f"`{batch.get('versions', {}).get('git_commit', '?')}`; finished {batch.get('finished_utc', '?')}; "
        f"load average (1, 5, 15 min) at the start {load} (other work shared the 2 CPUs: the runs vary by "
        f"a fifth or more from one to the next).",
        "",
        "*All-in* counts the whole command (Python, Ray's start when there is one, every worker's start-up, "
        "the meshes, the summary); *steady* is what the workers sustain once started: workers / (mean time "
        "of a mesh in its worker + its hand-over). *Start-up* runs from starting a worker's process (or "
        "creating its actor) to the worker having imported bpy and enabled the add-on; *peak MB* is each "
        "worker's peak resident memory (a Ray worker's includes Ray's own client).",
        "",
    ]
    rows = []
    for run in batch.get("runs", []):
        rows.append(
            [
                run["executor"],
                str(run["jobs"]),
                str(run["meshes"]),
                number(run["process_seconds"], 1),
                number(run["meshes_per_minute"], 1),
                number(run["steady_meshes_per_minute"], 1),
                number(run["mesh_seconds_mean"], 2),
                number(1000 * run["dispatch_seconds_per_mesh"], 1),
                ", ".join(number(value, 2) for value in run["worker_start_seconds"]),
                ", ".join(number(value, 0) for value in run["worker_peak_memory_mb"]),
            ]
        )
    lines += table(
        [
            "executor",
            "workers",
            "meshes",
            "all-in s",
            "meshes/min all-in",
            "meshes/min steady",
            "s per mesh",
            "hand-over ms per mesh",
            "worker start-up s",
            "peak MB per worker",
        ],
        rows,
        "llrrrrrrrr",
    )
    scheduler = batch.get("scheduler")
    if scheduler:
        lines += [
            "",
            f"The scheduler itself (`run_tasks`, the same for both executors, with stand-in workers that "
            f"answer at once) costs {number(scheduler['milliseconds_per_mesh'], 3)} ms per mesh: "
            f"{scheduler['meshes']:,} meshes on {scheduler['workers']} workers in "
            f"{number(scheduler['seconds'], 2)} s.",
        ]
    lines += [""]
    node = _batch_run(batch, "ray", 2) or _batch_run(batch, "local", 2)
    if node is None:
        return lines
    workers_per_node = node["jobs"]
    node_rate = node["steady_meshes_per_minute"]
    cluster_rate = PROJECTED_NODES * node_rate  # meshes per minute
    compute_minutes = PROJECTED_MESHES / cluster_rate
    fixed_seconds = max(0.0, node["process_seconds"] - 60.0 * node["meshes"] / node_rate)
    megabytes = node["input_mb_per_mesh"] + node["output_mb_per_mesh"]
    storage_rate = cluster_rate / 60.0 * megabytes  # MB/s the whole cluster reads and writes
    storage_minutes = PROJECTED_MESHES * megabytes / SHARED_STORAGE_MB_PER_SECOND / 60.0
    peak = max(node["worker_peak_memory_mb"])
    memory_mb = 1024 * float(machine.get("memory_gib") or 0)
    workers_by_memory = int(0.9 * memory_mb // peak) if peak else 0
    coordinator_rate = 60_000.0 / scheduler["milliseconds_per_mesh"] if scheduler else math.inf
    limits = {
        "the CPUs (the workers' own work)": compute_minutes,
        "the shared storage": storage_minutes,
        "the coordinator's scheduling": PROJECTED_MESHES / coordinator_rate,
    }
    limit = max(limits, key=limits.get)
    total_minutes = max(limits.values()) + fixed_seconds / 60.0
    lines += [
        f"### Projection: {PROJECTED_MESHES:,} meshes on {PROJECTED_NODES} nodes",
        "",
        f"From the {node['executor']} run with {workers_per_node} workers: {PROJECTED_NODES} nodes like this one "
        f"({machine.get('cpu_count', '?')} CPUs, {machine.get('memory_gib', '?')} GiB), {workers_per_node} "
        f"workers each ({PROJECTED_NODES * workers_per_node} in all), the library and the outputs on one shared "
        f"file system. Meshes of another size scale these numbers with their time per mesh.",
        "",
        f"- **Compute**: a node sustains {number(node_rate, 1)} meshes/min, the cluster "
        f"{cluster_rate:,.0f}; {PROJECTED_MESHES:,} meshes take **{number(compute_minutes, 1)} min** of "
        f"work, plus a fixed {number(fixed_seconds, 0)} s (start-up and shutdown, as measured here; workers "
        f"start in parallel, one per CPU).",
        f"- **Shared storage**: each mesh reads {number(node['input_mb_per_mesh'], 1)} MB and writes "
        f"{number(node['output_mb_per_mesh'], 1)} MB (the .blend is most of it), so the cluster asks "
        f"{storage_rate:,.0f} MB/s of the file system. At {SHARED_STORAGE_MB_PER_SECOND:,} MB/s (one NFS "
        f"server on 10 Gb/s: an assumption, not measured) moving the library's "
        f"{PROJECTED_MESHES * megabytes / 1024:,.0f} GB takes {number(storage_minutes, 1)} min"
        + (
            " - longer than the compute: **the storage is the bottleneck**, and more nodes would not help."
            if storage_minutes > compute_minutes
            else "."
        ),
        f"- **Worker memory**: {number(peak, 0)} MB at peak per worker, so a node of "
        f"{machine.get('memory_gib', '?')} GiB holds {workers_by_memory} workers by memory (a tenth kept for the "
        f"system) against "
        f"{machine.get('cpu_count', '?')} by CPU: "
        + (
            "memory is not what limits a node at this mesh size; meshes of millions of triangles raise the peak "
            "(see *Scaling* above) and then it can be."
            if workers_by_memory >= workers_per_node
            else "**memory limits a node**: use fewer workers (`--jobs`) than CPUs."
        ),
        f"- **Scheduling**: the coordinator spends {number(scheduler['milliseconds_per_mesh'], 3)} ms per mesh "
        f"(it could hand out {coordinator_rate:,.0f} meshes/min, against the {cluster_rate:,.0f} the cluster "
        f"asks for), and each mesh's hand-over through Ray took {number(1000 * node['dispatch_seconds_per_mesh'], 1)} "
        f"ms here, against {number(node['mesh_seconds_mean'], 2)} s of work: scheduling is not the limit."
        if scheduler
        else "- **Scheduling**: not measured.",
        "",
        f"So about **{number(total_minutes, 0)} min** for the {PROJECTED_MESHES:,} meshes, limited by "
        f"{limit}. What this leaves out: nodes' network and disk (the hand-over here is on one machine), "
        f"stragglers at the end of the batch, and meshes that need retries.",
        "",
    ]
    return lines


# ---------------------------------------------------------------- the document


# ---------------------------------------------------------------- after the wrap


def cage_fit_section(rows: list[dict]) -> list[str]:
    """The subdivision cage fit (``benchmarks/cage_fit.py --json``): the level-L surface's distance to the
    target before and after ``springwrap.fit_subdivision``, and its time."""
    lines = [
        "### Subdivision cage fit",
        "",
        "`springwrap.fit_subdivision` on MakeHuman's quads snapped onto the body (the cage a perfect wrap "
        "leaves): the distance of Blender's Subdivision Surface of the cage to the target before and after "
        "the fit, in % of the body's bounding-box diagonal (`.venv/bin/python benchmarks/cage_fit.py`).",
        "",
    ]
    body = []
    for row in rows:
        before, after = row["before"], row["after"]
        body.append(
            [
                row["case"],
                str(row["levels"]),
                str(row["anchors"]),
                f"{row['cage_vertices']:,}",
                f"{row['surface_points']:,}",
                f"{number(before['mean_percent'], 3)} / {number(before['p95_percent'], 3)} / "
                f"{number(before['max_percent'], 3)}",
                f"{number(after['mean_percent'], 3)} / {number(after['p95_percent'], 3)} / "
                f"{number(after['max_percent'], 3)}",
                number(before["max"] / after["max"], 1) if after["max"] > 0 else "inf",
                number(row["seconds"], 2),
            ]
        )
    header = ["case", "level", "anchors", "cage vertices", "surface points"]
    header += ["before: mean / p95 / max %", "after: mean / p95 / max %", "max falls ×", "seconds"]
    return lines + table(header, body, "lrrrrrrrr") + [""]


def quality_section(results: dict) -> list[str]:
    """The quality read-out (``benchmarks/quality_readout.py --json``): what it costs and what it says."""
    lines = [
        "### Quality read-out",
        "",
        "What the read-out (written by snap, project, the wrap and the mirror) costs and what it says after a "
        "wrap, without a known answer: on the demo, and on the MakeHuman body wrapped onto the benchmark's "
        "bodies from 24 landmark anchors (`.venv/bin/python benchmarks/quality_readout.py`). Distances are in "
        "world units (metres on the body); *off surface* counts the vertices farther than the threshold "
        "(0.1 % of the layout's size); on the body the truth is known, so the faces the read-out finds turned "
        "over are set against those turned over against the true layout.",
        "",
    ]
    body = []
    for name, result in results.items():
        if not isinstance(result, dict) or "quality" not in result:
            continue
        quality = result["quality"]
        truth = result.get("flipped_against_truth")
        body.append(
            [
                name,
                f"{quality['vertices']:,}",
                number(result.get("wrap_seconds"), 2),
                number(1000 * result["measure_seconds"], 0) if "measure_seconds" in result else "-",
                f"{quality['distance_p50']:.2g} / {quality['distance_p95']:.2g} / {quality['distance_max']:.2g}",
                f"{number(quality['stretch_p5'], 2)} / {number(quality['stretch_p50'], 2)} / "
                f"{number(quality['stretch_p95'], 2)}",
                str(quality["flipped"]) + ("" if truth is None else f" ({truth} against the truth)"),
                f"{quality['off_surface']:,}",
            ]
        )
    header = ["case", "vertices", "wrap s", "read-out ms", "distance p50 / p95 / max"]
    header += ["stretch p5 / p50 / p95", "faces flipped", "off surface"]
    return lines + table(header, body, "lrrrrrrr") + [""]


def dense_target_section(result: dict) -> list[str]:
    """Dense targets (``benchmarks/dense_target.py --json``): the kernel's build of a body target up to 20M
    triangles, its memory per triangle, and the body's wrap onto it, against their aims."""
    lines = [
        "### Dense targets",
        "",
        "The `heavy` body voxel-remeshed to about 1.25M triangles and split by its edges' midpoints to 5M and 20M "
        "(the same surface, as dense as a scan), each size in a fresh process "
        "(`.venv/bin/python benchmarks/dense_target.py`). *Build*: `TargetMesh(...)` (validation, the face tree); "
        "*prepare*: `prepare_all()` (the closest-point and vertex trees, adjacency, normals); wall clock and the "
        "process's processor time over its threads (*CPU s*: what a busy machine skews least); *peak* and *kept*: "
        "the process's resident set over both, above what it held before, per triangle. *Wrap*: the MakeHuman "
        "quad body (13,380 vertices, 24 landmark anchors) wrapped onto the dense mesh as a Blender object through "
        "the operators (detach, `anchor_add`, `wrap`: the first reads the target from Blender once and builds its "
        "own kernel mesh, the others reuse it), wall clock and processor time from the first operator to the "
        "wrap's end, the wrap's iterations, and the peak resident set over them above the scene (the dense "
        "Blender mesh already in it). "
        f"Aims: build at most {BUILD_AIM:.1f} s per million triangles, at most {MEMORY_AIM:.0f} B per triangle. "
        f"Load average at the start: {result['machine'].get('load_average', 0):.1f} on "
        f"{result['machine'].get('cpu_count')} CPUs.",
        "",
    ]
    rows = []
    for size in result["sizes"]:
        build, wrap = size["build"], size.get("wrap", {})
        rows.append(
            [
                f"{size['triangles']:,}",
                number(build["seconds"], 2),
                number(build["seconds_per_million"], 3),
                number(build["prepare_seconds"], 2),
                number(build.get("cpu_seconds"), 2),
                number(build.get("prepare_cpu_seconds"), 2),
                number(build["peak_bytes_per_triangle"], 0),
                number(build["kept_bytes_per_triangle"], 0),
                number(wrap.get("seconds"), 1),
                number(wrap.get("cpu_seconds"), 1),
                str(wrap.get("iterations", "-")),
                number(wrap.get("peak_bytes_per_triangle"), 0),
                number(size.get("load_average"), 1),
            ]
        )
    header = [
        "triangles",
        "build s",
        "build s/M",
        "prepare s",
        "build CPU s",
        "prepare CPU s",
        "peak B/tri",
        "kept B/tri",
        "wrap s",
        "wrap CPU s",
        "iterations",
        "wrap peak B/tri",
        "load",
    ]
    return lines + table(header, rows) + [""]


BUILD_AIM = 0.3
"""Dense targets: the build's aim, seconds per million triangles."""
MEMORY_AIM = 200.0
"""Dense targets: the memory aim, bytes per triangle."""


def large_target_section(result: dict) -> list[str]:
    """Large targets (``benchmarks/large_target.py --json``): how soon an operation starts on a large target,
    the target cache, and the memory of a wrap on it."""
    triangles = result["triangles"]
    lines = [
        "### Large targets",
        "",
        f"A {triangles:,}-triangle target (a noise-displaced torus) and a {result['layout_vertices']:,}-vertex "
        "layout, in a fresh process (`.venv/bin/python benchmarks/large_target.py`): `springwrap.snap` three "
        "times (the first reads the target and builds its face tree; the later ones find it unchanged in the "
        "cache), then a wrap. *Starts after* is the time from the operator's call to its first query into the "
        "kernel; memory is per target triangle, above the scene's own.",
        "",
    ]
    rows = []
    for snap in result["snaps"]:
        reads = ", ".join(f"{path} {count}" for path, count in snap["reads"].items() if count) or "none"
        rows.append(
            [
                f"snap {snap['run']}",
                number(snap["start_seconds"], 3),
                number(snap["seconds"], 2),
                reads,
                number(snap["peak_bytes_per_triangle"], 0),
                number(snap["kept_bytes_per_triangle"], 0),
            ]
        )
    wrap = result["wrap"]
    rows.append(
        [
            f"wrap ({wrap['iterations']} iterations)",
            "-",
            number(wrap["seconds"], 2),
            "-",
            number(wrap["peak_bytes_per_triangle"], 0),
            number(wrap["kept_bytes_per_triangle"], 0),
        ]
    )
    header = ["operation", "starts after s", "seconds", "target reads", "peak B/triangle", "kept B/triangle"]
    read = result["read"]
    return (
        lines
        + table(header, rows, "lrrlrr")
        + [
            "",
            f"The target's read alone (numpy, traced): peak {number(read['peak_bytes_per_triangle'], 0)} B per "
            f"triangle, {number(read['seconds_to_build'], 2)} s to the kernel's build; the scene itself "
            f"{number(result['scene_megabytes'], 0)} MB.",
            "",
        ]
    )


# ---------------------------------------------------------------- the document


def machine_lines(name: str, run: dict) -> list[str]:
    machine = dict(run.get("machine", {}))
    machine.update(run.get("versions", {}))  # snap_throughput.py keeps the versions apart
    load = machine.get("load_average")
    load_text = ", ".join(number(value, 2) for value in load) if isinstance(load, list) else number(load, 2)
    end = run.get("load_average_end")
    end_text = f"; at the end {', '.join(number(value, 2) for value in end)}" if end else ""
    return [
        f"- **{name}**: {machine.get('cpu', '?')}, {machine.get('cpu_count', '?')} CPUs, "
        f"{machine.get('platform', '?')}; Python {machine.get('python', '?')}, bpy {machine.get('bpy', '?')}, "
        f"numpy {machine.get('numpy', '?')}, springwrap_kernel {machine.get('springwrap_kernel', '?')} "
        f"(native module {machine.get('kernel_build', '?')}), "
        f"commit `{machine.get('git_commit', '?')}`; finished {run.get('finished_utc', '?')}; load average "
        f"(1, 5, 15 min) at the start {load_text}{end_text}"
    ]


def build_document(
    retarget: dict | None,
    performance: dict | None,
    snap: dict | None,
    image_folder: Path = DOCS / "img",
    image_prefix: str = "img",
    speed: dict | None = None,
    batch: dict | None = None,
    features: dict | None = None,
    after_wrap: dict | None = None,
    few_anchors: dict | None = None,
    parts: dict | None = None,
    sequence: dict | None = None,
    pair_tool: dict | None = None,
    feature_lines: dict | None = None,
) -> str:
    """The whole of ``docs/benchmarks.md``."""
    lines = [
        "# Benchmarks",
        "",
        "<!-- Generated by benchmarks/report.py from out/bench/*.json: do not edit by hand, rerun `make bench`. -->",
        "",
        "How well and how fast Springwrap retargets a patch layout, against what a Blender user would use "
        "otherwise. Every number and picture below comes from the runs named in *Machine and "
        "versions*; the machine was shared with other work while they ran (the load averages say how much), "
        "so times are upper bounds.",
        "",
    ]
    lines += [
        "## How to rerun",
        "",
        "```sh",
        "make bench           # every case and the full performance sweep, then this page and docs/img/*.png",
        "make bench QUICK=1   # the quick subset (~5 minutes on 2 cores)",
        ".venv/bin/python -m benchmarks.retarget.run [--quick] [--cases NAME ...] [--anchors N]",
        ".venv/bin/python benchmarks/performance.py [--quick]",
        ".venv/bin/python benchmarks/snap_throughput.py [--quick] --json out/bench/snap_throughput.json",
        ".venv/bin/python benchmarks/wrap_speed.py [--large] --json out/bench/wrap_speed.json",
        ".venv/bin/python benchmarks/wrap_solvers.py --scans --nricp --json out/bench/wrap_solvers.json "
        "--markdown docs/wrap-solvers.md",
        ".venv/bin/python benchmarks/feature_curves.py [--quick] --json out/bench/feature_curves.json",
        ".venv/bin/python benchmarks/few_anchors.py [--cases NAME ...] [--anchors N ...] --json out/bench/few_anchors.json",
        ".venv/bin/python benchmarks/parts.py [--cases NAME ...] --json out/bench/parts.json",
        ".venv/bin/python benchmarks/sequence.py [--frames N] --json out/bench/sequence.json",
        ".venv/bin/python benchmarks/pair_tool.py --json out/bench/pair_tool.json",
        ".venv/bin/python benchmarks/dense_target.py [--sizes N ...] [--no-wrap] --json out/bench/dense_target.json",
        ".venv/bin/python benchmarks/feature_lines.py --off fandisk.off --json out/bench/feature_lines.json",
        ".venv/bin/python benchmarks/figures.py && .venv/bin/python benchmarks/report.py",
        "```",
        "",
        "Cases, landmarks, metrics and methods are described in "
        "[benchmarks/retarget/README.md](../benchmarks/retarget/README.md). The wrap against nricp, case by case, through the kernel "
        "alone, and on real scans without a known answer (the range-scanned bunny, CGAL's elephant with "
        "holes): [wrap-solvers.md](wrap-solvers.md).",
        "",
    ]
    lines += ["## Machine and versions", ""]
    for name, run in (("retarget", retarget), ("performance", performance), ("snap throughput", snap)):
        if run is not None:
            lines += machine_lines(name, run)
        else:
            lines.append(f"- **{name}**: not run (no JSON).")
    lines.append("")
    if retarget is not None:
        lines += ["## Headline", ""] + headline(retarget) + [""]
        lines += retarget_section(retarget, image_folder, image_prefix)
    if few_anchors is not None:  # benchmarks/few_anchors.py
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from benchmarks.few_anchors import markdown

        lines += markdown(few_anchors)
    if parts is not None:  # benchmarks/parts.py
        lines += parts_section(parts)
    if retarget is None:
        lines += ["## Accuracy", "", "Not run: no `out/bench/retarget.json`.", ""]
    lines += ["## Performance", ""]
    if snap is not None:
        lines += snap_section(snap)
    if speed is not None:
        lines += wrap_aims_section(speed)
    if pair_tool is not None:
        lines += pair_tool_section(pair_tool)
    if retarget is not None:
        lines += wrap_speed_lines(retarget)
    if performance is not None:
        lines += performance_section(performance, image_folder, image_prefix)
    if snap is None and performance is None:
        lines += ["Not run: no performance JSON.", ""]
    if batch is not None:
        lines += batch_section(batch)
    after_wrap = after_wrap or {}
    if any(value is not None for value in after_wrap.values()):
        lines += ["## After the wrap", ""]
        if after_wrap.get("quality") is not None:
            lines += quality_section(after_wrap["quality"])
        if after_wrap.get("cage_fit") is not None:
            lines += cage_fit_section(after_wrap["cage_fit"])
    if after_wrap.get("large_target") is not None:
        lines += ["## Large targets", ""] + large_target_section(after_wrap["large_target"])[2:]
    if after_wrap.get("dense_target") is not None:
        lines += dense_target_section(after_wrap["dense_target"])
    if features is not None:  # benchmarks/feature_curves.py
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from benchmarks.feature_curves import markdown_lines

        lines += markdown_lines(features)
    if feature_lines is not None:  # benchmarks/feature_lines.py
        lines += feature_lines_section(feature_lines)
    if sequence is not None:  # benchmarks/sequence.py
        lines += sequence_section(sequence)
    return "\n".join(lines).rstrip() + "\n"


def parts_section(parts: dict) -> list[str]:
    """The parts section (``benchmarks/parts.py``'s own Markdown)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks.parts import markdown

    return markdown(parts)


def splice_section(document: str, section: list[str], before: str = "## Performance") -> str:
    """``document`` with the section whose heading is ``section[0]`` replaced by ``section`` (up to the next
    heading of its level or above: ``## `` for a ``## `` section, ``## `` or ``### `` for a ``### `` one), or
    inserted before the ``before`` heading (at the end without one)."""
    lines = document.rstrip("\n").split("\n")
    heading = section[0]
    level = len(heading) - len(heading.lstrip("#"))
    ends = tuple("#" * depth + " " for depth in range(2, level + 1))
    if heading in lines:
        start = lines.index(heading)
        end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith(ends)), len(lines))
        lines[start:end] = section
    else:
        at = lines.index(before) if before in lines else len(lines)
        lines[at:at] = section
    return "\n".join(lines).rstrip() + "\n"


def few_anchors_section(result: dict) -> list[str]:
    """The *Few anchors* section (``benchmarks/few_anchors.py``)."""
    sys.path.insert(0, str(REPOSITORY_ROOT))
    from benchmarks.few_anchors import markdown as few_anchors_markdown

    return few_anchors_markdown(result)


def sequence_section(result: dict) -> list[str]:
    """The *Over time* section (``benchmarks/sequence.py``)."""
    sys.path.insert(0, str(REPOSITORY_ROOT))
    from benchmarks.sequence import markdown as sequence_markdown

    return sequence_markdown(result)


def feature_lines_section(result: dict) -> list[str]:
    """The feature-lines section (``benchmarks/feature_lines.py --json``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks.feature_lines import markdown as feature_lines_markdown

    return feature_lines_markdown(result) + [""]


def splice_retarget(document: str, retarget: dict) -> str:
    """``document`` with everything the retargeting benchmark writes replaced: its machine line, the headline,
    the accuracy section (its per-case tables and figures) and the wrap's speed on its cases."""
    lines = document.split("\n")
    machine = machine_lines("retarget", retarget)[0]
    at = next((i for i, line in enumerate(lines) if line.startswith("- **retarget**: ")), None)
    if at is not None:
        lines[at] = machine
    document = "\n".join(lines)
    document = splice_section(document, ["## Headline", "", *headline(retarget), ""])
    document = splice_section(document, retarget_section(retarget, DOCS / "img", "img"), "## Few anchors")
    speed = wrap_speed_lines(retarget)
    return splice_section(document, speed, "### Scaling (full sweep") if speed else document


ONLY_SECTIONS = {
    "snap": (snap_section, "snap", "### Wrap speed against its aims"),
    "wrap-speed": (wrap_aims_section, "speed", "### Pair tool"),
    "dense-target": (dense_target_section, "dense_target", "## Feature curves"),
    "few-anchors": (few_anchors_section, "few_anchors", "## Parts that follow the surface"),
    "sequence": (sequence_section, "sequence", None),
    "feature-lines": (feature_lines_section, "feature_lines", "## Over time"),
}
"""``--only``: the section's maker, the argument naming its JSON, and the heading it goes before when new."""


def load(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.exists() else None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="report.py", description=__doc__.splitlines()[0])
    parser.add_argument("--retarget", type=Path, default=OUT / "retarget.json")
    parser.add_argument("--performance", type=Path, default=OUT / "performance.json")
    parser.add_argument("--snap", type=Path, default=OUT / "snap_throughput.json")
    parser.add_argument("--speed", type=Path, default=OUT / "wrap_speed.json")
    parser.add_argument("--batch", type=Path, default=OUT / "batch_throughput.json")
    parser.add_argument("--features", type=Path, default=OUT / "feature_curves.json")
    parser.add_argument("--quality", type=Path, default=OUT / "quality_readout.json")
    parser.add_argument("--cage-fit", type=Path, default=OUT / "cage_fit.json")
    parser.add_argument("--large-target", type=Path, default=OUT / "large_target.json")
    parser.add_argument("--dense-target", type=Path, default=OUT / "dense_target.json")
    parser.add_argument("--few-anchors", type=Path, default=OUT / "few_anchors.json")
    parser.add_argument("--parts", type=Path, default=OUT / "parts.json")
    parser.add_argument(
        "--only-parts",
        action="store_true",
        help="only put the parts section (from --parts) into the existing --output, leaving the rest as it is",
    )
    parser.add_argument(
        "--only",
        choices=sorted([*ONLY_SECTIONS, "retarget"]),
        help="only put this section (from its JSON) into the existing --output, leaving the rest as it is",
    )
    parser.add_argument("--sequence", type=Path, default=OUT / "sequence.json")
    parser.add_argument("--pair-tool", type=Path, default=OUT / "pair_tool.json")
    parser.add_argument("--feature-lines", type=Path, default=OUT / "feature_lines.json")
    parser.add_argument("--output", type=Path, default=DOCS / "benchmarks.md")
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if arguments.only == "retarget":
        retarget = load(arguments.retarget)
        if retarget is None:
            print(f"report.py: no {arguments.retarget}", file=sys.stderr)
            return 1
        arguments.output.write_text(splice_retarget(arguments.output.read_text(), retarget))
        print(f"wrote the retarget sections into {arguments.output}")
        return 0
    if arguments.only:
        section, source, before = ONLY_SECTIONS[arguments.only]
        result = load(getattr(arguments, source))
        if result is None:
            print(f"report.py: no {getattr(arguments, source)}", file=sys.stderr)
            return 1
        arguments.output.write_text(splice_section(arguments.output.read_text(), section(result), before))
        print(f"wrote the {arguments.only} section into {arguments.output}")
        return 0
    if arguments.only_parts:
        parts = load(arguments.parts)
        if parts is None:
            print(f"report.py: no {arguments.parts}", file=sys.stderr)
            return 1
        arguments.output.write_text(splice_section(arguments.output.read_text(), parts_section(parts)))
        print(f"wrote the parts section into {arguments.output}")
        return 0
    inputs = {name: load(getattr(arguments, name)) for name in ("retarget", "performance", "snap")}
    for name, value in inputs.items():
        if value is None:
            print(f"report.py: no {getattr(arguments, name)}; its section is left out", file=sys.stderr)
    if inputs["retarget"] is None and inputs["performance"] is None and inputs["snap"] is None:
        return 1
    image_folder = arguments.output.parent / "img"
    arguments.output.write_text(
        build_document(
            inputs["retarget"],
            inputs["performance"],
            inputs["snap"],
            image_folder,
            "img",
            load(arguments.speed),
            load(arguments.batch),
            load(arguments.features),
            {name: load(getattr(arguments, name)) for name in ("quality", "cage_fit", "large_target", "dense_target")},
            load(arguments.few_anchors),
            load(arguments.parts),
            load(arguments.sequence),
            load(arguments.pair_tool),
            load(arguments.feature_lines),
        )
    )
    print(f"wrote {arguments.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
