"""The wrap with few anchors: the retargeting benchmark at 4, 6, 12 and 24 anchors on the body cases.

    .venv/bin/python benchmarks/few_anchors.py [--cases heavy heavy-old ...] [--anchors 4 6 12 24]
        [--methods "aligned template" "Springwrap wrap" ...] [--json out/bench/few_anchors.json]

Runs ``benchmarks.retarget.run`` once per anchor count (the same landmarks, the first N, given to every
method) with the aligned template, trimesh's ``nricp_amberg`` and the wrap with each stiffness schedule
(``Springwrap wrap``: the default, automatic choice; ``Springwrap wrap local``: the local schedule;
``Springwrap wrap global``: global to local) and the wrap after ``springwrap.anchors_propose``
(``Springwrap wrap proposals``: further pairs proposed from the anchors and all accepted), and gathers the
per-case mean error, p95, flipped quads and time into one JSON, with the proposals' truth check (how many
proposed, the share within 1 % of the diagonal of the true point). :func:`markdown` turns it into the
section of ``docs/benchmarks.md`` (``benchmarks/report.py --few-anchors``). No ``bpy`` here: the runs are
subprocesses.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_JSON = REPOSITORY_ROOT / "out" / "bench" / "few_anchors.json"
DEFAULT_CASES = ("heavy", "heavy-old", "old-male", "young-female")
DEFAULT_ANCHORS = (4, 6, 12, 24)
METHODS = (
    "aligned template",
    "trimesh nricp_amberg",
    "Springwrap wrap",
    "Springwrap wrap local",
    "Springwrap wrap global",
    "Springwrap wrap proposals",
)
"""The methods compared, in the table's order."""
REFERENCE = "trimesh nricp_amberg"
"""The method the wraps are measured against."""
FIELDS = ("error_percent_mean", "error_percent_p95", "flipped_quads")


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="few_anchors.py", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), metavar="CASE")
    parser.add_argument("--anchors", nargs="+", type=int, default=list(DEFAULT_ANCHORS), metavar="N")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS, help="default: all")
    return parser.parse_args(argv)


def rows_of(retarget: dict, anchors: int) -> list[dict]:
    """One row per case and method of a ``benchmarks.retarget.run`` JSON run with ``anchors`` anchors."""
    rows = []
    for record in retarget["cases"]:
        for method, entry in record["methods"].items():
            metrics = entry.get("metrics") or {}
            row = {"case": record["case"], "anchors": anchors, "method": method, "status": entry["status"]}
            row.update({field: metrics.get(field) for field in FIELDS})
            row["seconds"] = entry.get("seconds")
            row["wrap_seconds"] = (entry.get("details") or {}).get("wrap_seconds")
            proposals = (entry.get("details") or {}).get("proposals")
            if proposals is not None:
                row["proposals"] = proposals
            rows.append(row)
    return rows


def run(arguments: argparse.Namespace) -> int:
    """One retarget run per anchor count; the rows gathered into ``arguments.json``. The exit code."""
    rows: list[dict] = []
    runs = []
    started = time.perf_counter()
    for anchors in arguments.anchors:
        path = arguments.json.with_name(f"{arguments.json.stem}-{anchors}.json")
        command = [sys.executable, "-m", "benchmarks.retarget.run", "--cases", *arguments.cases]
        command += ["--anchors", str(anchors), "--json", str(path), "--methods", *arguments.methods]
        print(f"few anchors: {anchors}", flush=True)
        completed = subprocess.run(command, cwd=REPOSITORY_ROOT, check=False)
        if completed.returncode != 0:
            print(f"the run with {anchors} anchors failed ({completed.returncode})", file=sys.stderr)
            return completed.returncode
        retarget = json.loads(path.read_text())
        rows += rows_of(retarget, anchors)
        runs.append({key: retarget.get(key) for key in ("machine", "finished_utc", "load_average_end", "seconds")})
        # Written after every anchor count, so that an interrupted run keeps what it measured.
        result = {
            "benchmark": "few_anchors",
            "cases": arguments.cases,
            "anchors": [
                run_anchors for run_anchors in arguments.anchors if any(r["anchors"] == run_anchors for r in rows)
            ],
            "methods": list(arguments.methods),
            "runs": runs,
            "seconds": time.perf_counter() - started,
            "rows": rows,
        }
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(result, indent=1))
    print(f"wrote {arguments.json}")
    return 0


def _number(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}f}"


def _seconds(row: dict) -> str:
    """The method's time, and the wrap's own in brackets when it reported one."""
    wrap = row.get("wrap_seconds")
    return _number(row["seconds"], 1) + (f" ({wrap:.1f})" if wrap is not None else "")


def markdown(result: dict) -> list[str]:
    """The few-anchors section: per case and anchor count, each method's mean, p95, flipped quads and time,
    and the wraps' mean and p95 over nricp's."""
    rows = result["rows"]
    lookup = {(row["case"], row["anchors"], row["method"]): row for row in rows}
    methods = [method for method in result["methods"] if any(row["method"] == method for row in rows)]
    lines = [
        "## Few anchors",
        "",
        f"The body cases with the first {', '.join(str(n) for n in sorted(result['anchors']))} landmarks as anchors, the "
        "same anchors to every method (`benchmarks/few_anchors.py`, one run per anchor count). `Springwrap wrap` "
        "is the energy wrap with its default schedule (`'AUTO'`: global to local for 3 to 11 anchors, or for more "
        "that slide along the surface from a similarity of the template without a pose, else local); "
        "`Springwrap wrap local` the local schedule (`schedule='LOCAL'`); "
        "`Springwrap wrap global` the global-to-local schedule (`schedule='GLOBAL_TO_LOCAL'`); `Springwrap wrap "
        "proposals` the default wrap after `springwrap.anchors_propose(accept=True)` (further pairs proposed from "
        "the anchors, all accepted: soft pairs that steer the global-to-local schedule's stiff levels). Errors in % of the diagonal; flipped quads against the true quads; time: every "
        "operator call of the method (the wrap's own time in brackets); × nricp: the wrap's mean (p95) over "
        "nricp's with the same anchors; proposed: the pairs proposed, and how many (share) lie within 1 % of the "
        "diagonal of their vertex's true point.",
        "",
    ]
    header = ["case", "anchors", "method", "mean %", "p95 %", "flipped", "time s", "× nricp mean (p95)", "proposed"]
    table_rows = []
    for case in result["cases"]:
        for anchors in sorted(result["anchors"]):
            reference = lookup.get((case, anchors, REFERENCE))
            for method in methods:
                row = lookup.get((case, anchors, method))
                if row is None:
                    continue
                if row["status"] != "ok":
                    table_rows.append([case, str(anchors), method, row["status"], "", "", "", "", ""])
                    continue
                ratio = ""
                if method.startswith("Springwrap") and reference and reference["status"] == "ok":
                    ratio = (
                        f"{row['error_percent_mean'] / reference['error_percent_mean']:.2f} "
                        f"({row['error_percent_p95'] / reference['error_percent_p95']:.2f})"
                    )
                table_rows.append(
                    [
                        case,
                        str(anchors),
                        method,
                        _number(row["error_percent_mean"]),
                        _number(row["error_percent_p95"]),
                        str(row["flipped_quads"]),
                        _seconds(row),
                        ratio,
                        _proposal_cell(row.get("proposals")),
                    ]
                )
    lines += ["| " + " | ".join(header) + " |", "|" + "|".join([":---"] * 3 + ["---:"] * 6) + "|"]
    lines += ["| " + " | ".join(cells) + " |" for cells in table_rows]
    lines += aims(lookup, result["cases"], 6)
    lines += proposal_aims(lookup, result["cases"], 6, 24)
    loads = [run.get("load_average_end") or [] for run in result.get("runs", [])]
    if loads:
        text = "; ".join(", ".join(f"{load:.1f}" for load in triple) for triple in loads)
        lines += ["", f"Load averages (1, 5, 15 minutes) at the end of each run: {text} (2 cores, shared)."]
    lines.append("")
    return lines


def _proposal_cell(proposals: dict | None) -> str:
    """``count (right, share %)`` of a row's proposals, empty for a method that proposes none."""
    if not proposals:
        return ""
    if not proposals["count"]:
        return "0"
    return f"{proposals['count']} ({proposals['right']} right, {100.0 * proposals['share_right']:.0f} %)"


def proposal_aims(lookup: dict, case_names: list[str], anchors: int, many: int) -> list[str]:
    """Per case, the wrap with proposals from ``anchors`` anchors against the local wrap with ``many`` anchors:
    the mean's ratio (the aim: at most 1.25)."""
    lines = []
    for case in case_names:
        row = lookup.get((case, anchors, "Springwrap wrap proposals"))
        reference = lookup.get((case, many, "Springwrap wrap"))
        plain = lookup.get((case, anchors, "Springwrap wrap"))
        if not row or not reference or row["status"] != "ok" or reference["status"] != "ok":
            continue
        text = (
            f"- {case}: with proposals from {anchors} anchors the mean is "
            f"{row['error_percent_mean'] / reference['error_percent_mean']:.2f}× the {many}-anchor wrap's"
        )
        if plain and plain["status"] == "ok":
            text += f" ({plain['error_percent_mean'] / reference['error_percent_mean']:.2f}× without proposals)"
        lines.append(text + ".")
    return [""] + lines if lines else []


def aims(lookup: dict, case_names: list[str], anchors: int) -> list[str]:
    """Per case with ``anchors`` anchors, each wrap against nricp: mean and p95 ratios, quads flipped beyond the
    aligned template's, and how many times faster."""
    lines = []
    for case in case_names:
        reference = lookup.get((case, anchors, REFERENCE))
        aligned = lookup.get((case, anchors, "aligned template"))
        if not reference or not aligned or reference["status"] != "ok":
            continue
        parts = []
        for method in ("Springwrap wrap", "Springwrap wrap local", "Springwrap wrap global"):
            row = lookup.get((case, anchors, method))
            if not row or row["status"] != "ok":
                continue
            parts.append(
                f"{method}: mean {row['error_percent_mean'] / reference['error_percent_mean']:.2f}×, "
                f"p95 {row['error_percent_p95'] / reference['error_percent_p95']:.2f}× nricp's, "
                f"{row['flipped_quads'] - aligned['flipped_quads']:+d} flipped quads against the aligned template, "
                f"{reference['seconds'] / row['seconds']:.1f}× faster"
                + (
                    f" ({reference['seconds'] / row['wrap_seconds']:.1f}× by the wrap's own time)"
                    if row.get("wrap_seconds")
                    else ""
                )
            )
        if parts:
            lines.append(f"- {case}, {anchors} anchors: " + "; ".join(parts) + ".")
    return [""] + lines if lines else []


def main(argv: list[str] | None = None) -> int:
    return run(parse_arguments(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    raise SystemExit(main())
