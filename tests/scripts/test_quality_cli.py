"""The quality read-out from the command line: the ``quality`` block of ``retarget.py``'s and ``mirror.py``'s JSON
reports, and the batch summary's flag on the mesh whose numbers stand out (a sphere with a hole under the
template, among whole spheres). Each run in a process of its own; the outlier rule itself on plain numbers."""

import json
import subprocess

import numpy as np
import pytest

from helpers import REPOSITORY, TIMEOUT_SECONDS, core_module, script_command, sphere_obj

BLENDER_SCRIPTS = REPOSITORY / "blender_scripts"
SIDE = 7  # vertices per side of the template grid
QUALITY_KEYS = {
    "vertices",
    "faces",
    "distance_mean",
    "distance_p50",
    "distance_p95",
    "distance_max",
    "stretch_p5",
    "stretch_p50",
    "stretch_p95",
    "stretch_max",
    "flipped",
    "off_surface",
    "off_surface_threshold",
}


def grid_obj(x_range=(-0.5, 0.5), columns=SIDE, height=1.5) -> str:
    """A flat grid over the origin (``columns`` x SIDE vertices, y from -0.5 to 0.5), facing up, as OBJ text."""
    low, high = x_range
    lines = [
        f"v {low + (high - low) * i / (columns - 1):.6f} {j / (SIDE - 1) - 0.5:.6f} {height}"
        for j in range(SIDE)
        for i in range(columns)
    ]
    for j in range(SIDE - 1):
        for i in range(columns - 1):
            a = j * columns + i + 1
            lines.append(f"f {a} {a + 1} {a + columns + 1} {a + columns}")
    return "\n".join(lines) + "\n"


def holed_sphere_obj(radius=1.0, top=0.75) -> str:
    """A UV sphere without its top cap (faces whose corners are all above ``top`` x radius): a hole under the grid."""
    lines = sphere_obj(radius).splitlines()
    heights = [float(line.split()[3]) for line in lines if line.startswith("v ")]
    kept = [
        line
        for line in lines
        if not line.startswith("f ") or min(heights[int(index) - 1] for index in line.split()[1:]) <= top * radius
    ]
    return "\n".join(kept) + "\n"


def run(script: str, *arguments) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*script_command(BLENDER_SCRIPTS / script), *map(str, arguments)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
        cwd=REPOSITORY,
    )


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("quality_inputs")
    paths = {"template": folder / "grid.obj", "half": folder / "half.obj", "ball": folder / "ball.obj"}
    paths["template"].write_text(grid_obj())
    paths["half"].write_text(grid_obj(x_range=(0.0, 0.5), columns=4))
    paths["ball"].write_text(sphere_obj(1.0))
    batch = folder / "batch"
    batch.mkdir()
    for index, radius in enumerate((0.95, 1.0, 1.05, 1.1)):
        (batch / f"ball_{index}.obj").write_text(sphere_obj(radius))
    (batch / "holed.obj").write_text(holed_sphere_obj())
    paths["batch"] = batch
    return paths


def test_the_retarget_report_carries_the_quality_block(meshes, tmp_path):
    report_path = tmp_path / "r.json"
    process = run(
        "retarget.py", "--template", meshes["template"], "--target", meshes["ball"], "--anchors-spacing", 0,
        "--report", report_path,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    quality = report["quality"]
    assert set(quality) == QUALITY_KEYS
    assert (quality["vertices"], quality["faces"]) == (SIDE**2, (SIDE - 1) ** 2)
    # The grid lies on the (faceted) sphere; the read-out's distances are the metrics' own.
    assert quality["distance_max"] == pytest.approx(report["metrics"]["max_distance"], abs=1e-6)
    assert quality["distance_max"] < 1e-5 and quality["off_surface"] == 0 and quality["flipped"] == 0
    assert quality["stretch_p5"] <= quality["stretch_p50"] <= quality["stretch_p95"] <= quality["stretch_max"]
    # Pulled from 1.5 up onto the unit sphere, the grid shrinks (its corners land 0.27 from the axis, not 0.5).
    assert 0.3 < quality["stretch_p5"] and quality["stretch_max"] < 1.05


def test_the_mirror_report_carries_the_quality_block(meshes, tmp_path):
    report_path = tmp_path / "m.json"
    process = run(
        "mirror.py", "--layout", meshes["half"], "--target", meshes["ball"], "--axis", "X", "--snap",
        "--report", report_path,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    quality = report["quality"]
    assert set(quality) == QUALITY_KEYS and quality["vertices"] == report["vertices"] == SIDE * 7
    assert quality["distance_max"] < 1e-4 and quality["flipped"] == 0


def test_the_batch_summary_flags_the_mesh_that_stands_out(meshes, tmp_path):
    out = tmp_path / "out"
    process = run(
        "retarget.py", "--template", meshes["template"], "--batch", meshes["batch"], "--output-dir", out,
        "--jobs", 2, "--anchors-spacing", 0.3,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stand_out"] == [str((meshes["batch"] / "holed.obj").resolve())]
    assert "robust z-score" in summary["quality_rule"]
    for entry in summary["meshes"]:
        report = json.loads((out / f"{entry['target'].rsplit('/', 1)[1][:-4]}.json").read_text())
        assert entry["quality"] == report["quality"]  # the summary carries the report's numbers
        holed = entry["target"].endswith("holed.obj")
        assert bool(entry["stands_out"]) == holed
    [holed] = [entry for entry in summary["meshes"] if entry["target"].endswith("holed.obj")]
    assert {"distance_p95", "off_surface"} <= set(holed["stands_out"])
    assert holed["quality"]["off_surface"] > 0
    assert "stands out from the batch:" in process.stderr and "holed.obj" in process.stderr


# ---------------------------------------------------------------- the rule on plain numbers


def row(distance=0.01, stretch=1.0, flipped=0, off_surface=0):
    return {
        "distance_p50": distance,
        "distance_p95": 2 * distance,
        "distance_max": 3 * distance,
        "stretch_p5": stretch * 0.9,
        "stretch_p95": stretch * 1.1,
        "stretch_max": stretch * 1.2,
        "flipped": flipped,
        "off_surface": off_surface,
    }


def test_the_rule_flags_the_mesh_that_stands_out_in_the_worse_direction():
    import retarget_batch

    rows = {f"m{index}": row(distance=0.010 + 0.001 * index) for index in range(5)}
    assert retarget_batch.quality_outliers(rows) == {}
    rows["bad"] = row(distance=0.05, flipped=40)
    rows["better"] = row(distance=0.001)  # closer than the rest: not a problem
    rows["failed"] = None  # a mesh without numbers is left out
    flagged = retarget_batch.quality_outliers(rows)
    assert set(flagged) == {"bad"}
    assert {"distance_p50", "distance_p95", "distance_max", "flipped"} <= set(flagged["bad"])
    assert flagged["bad"]["flipped"]["median"] == 0.0


def test_the_rule_needs_three_meshes_and_a_count_needs_more_than_one_element():
    import retarget_batch

    assert retarget_batch.quality_outliers({"a": row(), "b": row(flipped=50)}) == {}
    rows = {"a": row(), "b": row(), "c": row(flipped=1), "d": row()}
    assert retarget_batch.quality_outliers(rows) == {}  # one flipped face more than the others: within one element
    rows["e"] = row(stretch=2.0)
    assert set(retarget_batch.quality_outliers(rows)) == {"e"}
    rows["f"] = row(stretch=0.4)  # compressed: its p5 is low
    assert "stretch_p5" in retarget_batch.quality_outliers(rows)["f"]


def test_the_rule_judges_metrics_the_report_has():
    import retarget_batch

    quality = core_module("quality")
    summary_keys = set(quality.summary(quality.Readout(np.ones(3), np.ones(3), np.zeros(2, bool), diagonal=1.0)))
    assert set(retarget_batch.OUTLIER_METRICS) <= summary_keys
