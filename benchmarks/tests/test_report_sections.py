"""``benchmarks/report.py --only``: one section of ``docs/benchmarks.md`` replaced (or added) from its JSON, the
rest of the document left as it was; the dense-target table on a made-up result. Fast, no Blender."""

import json
from pathlib import Path

from benchmarks import report

DOCUMENT = """# Benchmarks

## Performance

### Snap throughput: kernel vs Shrinkwrap vs mathutils BVHTree

old snap table

### Wrap speed against its aims

wrap speed

## Feature curves

curves
"""

DENSE = {
    "machine": {"load_average": 3.0, "cpu_count": 2},
    "sizes": [
        {
            "triangles": 1_250_000,
            "load_average": 3.0,
            "build": {
                "seconds": 0.5,
                "prepare_seconds": 0.7,
                "cpu_seconds": 0.9,
                "prepare_cpu_seconds": 1.1,
                "seconds_per_million": 0.4,
                "peak_bytes_per_triangle": 180.0,
                "kept_bytes_per_triangle": 150.0,
            },
            "wrap": {"seconds": 2.0, "cpu_seconds": 2.5, "iterations": 25, "peak_bytes_per_triangle": 300.0},
        },
        {
            "triangles": 20_000_000,
            "load_average": 3.0,
            "build": {
                "seconds": 8.0,
                "prepare_seconds": 9.0,
                "seconds_per_million": 0.4,
                "peak_bytes_per_triangle": 190.0,
                "kept_bytes_per_triangle": 150.0,
            },
        },
    ],
}


def test_a_third_level_section_is_replaced_up_to_the_next_heading_of_its_level():
    section = ["### Snap throughput: kernel vs Shrinkwrap vs mathutils BVHTree", "", "new snap table", ""]
    once = report.splice_section(DOCUMENT, section)
    assert "new snap table" in once and "old snap table" not in once
    assert "### Wrap speed against its aims\n\nwrap speed" in once and "## Feature curves\n\ncurves" in once
    assert report.splice_section(once, section) == once


def test_the_dense_target_table_is_added_before_the_feature_curves(tmp_path):
    dense = tmp_path / "dense_target.json"
    dense.write_text(json.dumps(DENSE))
    output = tmp_path / "benchmarks.md"
    output.write_text(DOCUMENT)
    assert report.main(["--only", "dense-target", "--dense-target", str(dense), "--output", str(output)]) == 0
    text = output.read_text()
    assert text.index("### Dense targets") < text.index("## Feature curves")
    assert "| 20,000,000 | 8.00 | 0.400 | 9.00 | - | - | 190 | 150 | - | - | - | - | 3.0 |" in text
    assert "| 1,250,000 | 0.50 | 0.400 | 0.70 | 0.90 | 1.10 | 180 | 150 | 2.0 | 2.5 | 25 | 300 | 3.0 |" in text
    assert "old snap table" in text
    assert report.main(["--only", "dense-target", "--dense-target", str(dense), "--output", str(output)]) == 0
    assert output.read_text() == text


RETARGET_DOCUMENT = """# Benchmarks

## Machine and versions

- **retarget**: old machine line
- **performance**: performance machine line

## Headline

old headline

## Accuracy: retargeting with a known answer

old accuracy

### heavy

old heavy table

## Few anchors

few anchors table

## Performance

### Wrap on the retarget cases

old wrap speed

### Scaling (full sweep, 1 s)

scaling
"""


def test_the_retarget_sections_are_replaced_and_nothing_else(tmp_path):
    """``--only retarget``: the machine line, the headline, the accuracy section with its per-case tables and
    the wrap's speed on the cases come from the run (a one-case excerpt of a real run); the rest stays."""
    source = Path(__file__).parent / "data" / "retarget_one_case.json"
    output = tmp_path / "benchmarks.md"
    output.write_text(RETARGET_DOCUMENT)
    assert report.main(["--only", "retarget", "--retarget", str(source), "--output", str(output)]) == 0
    text = output.read_text()
    for old in ("old machine line", "old headline", "old accuracy", "old heavy table", "old wrap speed"):
        assert old not in text
    for kept in ("- **performance**: performance machine line", "few anchors table", "scaling"):
        assert kept in text
    assert "commit `abded38ae656`" in text and "load average (1, 5, 15 min) at the start 20.46" in text
    assert text.index("## Headline") < text.index("### heavy") < text.index("## Few anchors")
    assert "| heavy | Springwrap wrap | 23 | yes |" in text
    assert report.main(["--only", "retarget", "--retarget", str(source), "--output", str(output)]) == 0
    assert output.read_text() == text
