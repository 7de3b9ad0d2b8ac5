"""The few-anchors benchmark's bookkeeping and its section of the page, on made-up runs (no Blender)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import few_anchors, report


def retarget_run(wrap_mean: float) -> dict:
    """A ``benchmarks.retarget.run`` JSON with one case and three methods."""

    def entry(mean, p95, flipped, seconds, status="ok"):
        metrics = {"error_percent_mean": mean, "error_percent_p95": p95, "flipped_quads": flipped}
        return {"status": status, "seconds": seconds, "metrics": metrics if status == "ok" else None}

    return {
        "cases": [
            {
                "case": "heavy",
                "methods": {
                    "trimesh nricp_amberg": entry(0.4, 1.2, 2, 60.0),
                    "Springwrap wrap": entry(wrap_mean, 1.5, 12, 6.0),
                    "Springwrap wrap global": entry(0.3, 1.0, 9, 9.0),
                },
            }
        ],
        "load_average_end": [3.0, 2.5, 2.0],
    }


def test_rows_and_the_section_give_each_method_and_its_ratio_to_nricp():
    rows = few_anchors.rows_of(retarget_run(0.6), 6) + few_anchors.rows_of(retarget_run(0.5), 4)
    assert [(row["anchors"], row["method"]) for row in rows][:2] == [
        (6, "trimesh nricp_amberg"),
        (6, "Springwrap wrap"),
    ]
    result = {"cases": ["heavy"], "anchors": [6, 4], "methods": list(few_anchors.METHODS), "runs": [], "rows": rows}
    lines = few_anchors.markdown(result)
    assert lines[0] == "## Few anchors"
    table = [line for line in lines if line.startswith("| heavy")]
    # Sorted by anchor count; the aligned template, absent from the run, has no row.
    assert [line.split(" | ")[1] for line in table] == ["4"] * 3 + ["6"] * 3
    wrap_at_6 = next(line for line in table if "| 6 | Springwrap wrap |" in line)
    assert wrap_at_6.endswith("| 1.50 (1.25) |  |"), wrap_at_6
    global_at_6 = next(line for line in table if "| 6 | Springwrap wrap global |" in line)
    assert "| 0.300 | 1.000 | 9 | 9.0 | 0.75 (0.83) |" in global_at_6


def test_the_report_places_the_section_when_its_json_is_given():
    rows = few_anchors.rows_of(retarget_run(0.6), 6)
    result = {"cases": ["heavy"], "anchors": [6], "methods": list(few_anchors.METHODS), "runs": [], "rows": rows}
    page = report.build_document(None, None, None, few_anchors=result)
    assert "## Few anchors" in page and "| heavy | 6 | Springwrap wrap global |" in page
    assert "## Few anchors" not in report.build_document(None, None, None)


def test_the_proposals_column_and_aim():
    """The wrap with proposals gets its proposals' count and truth in its row, and its mean against the 24-anchor
    wrap's below the table."""
    runs = {}
    for anchors, mean in ((6, 0.6), (24, 0.4)):
        run = retarget_run(mean)
        run["cases"][0]["methods"]["Springwrap wrap proposals"] = {
            "status": "ok",
            "seconds": 7.0,
            "metrics": {"error_percent_mean": 0.45, "error_percent_p95": 1.4, "flipped_quads": 10},
            "details": {"proposals": {"count": 12, "right": 9, "share_right": 0.75, "median_error_percent": 0.5}},
        }
        runs[anchors] = few_anchors.rows_of(run, anchors)
    rows = runs[6] + runs[24]
    result = {"cases": ["heavy"], "anchors": [6, 24], "methods": list(few_anchors.METHODS), "runs": [], "rows": rows}
    lines = few_anchors.markdown(result)
    row = next(line for line in lines if "| 6 | Springwrap wrap proposals |" in line)
    assert row.endswith("| 12 (9 right, 75 %) |"), row
    assert (
        "- heavy: with proposals from 6 anchors the mean is 1.12× the 24-anchor wrap's (1.50× without proposals)."
        in lines
    )
