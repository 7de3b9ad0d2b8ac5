"""The quality read-out from the command line: the ``quality`` block of ``retarget.py``'s and ``mirror.py``'s JSON
reports, and the batch summary's flag on the mesh whose numbers stand out (a sphere with a hole under the
template, among whole spheres). Each run in a process of its own; the outlier rule itself on plain numbers."""

import json
import subprocess

import numpy as np
import pytest

from helpers import REPOSITORY, core_module, grid_obj, obj_text, run_script, sphere_faces, sphere_obj, sphere_points

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
    "part_vertices",
}


def half_grid_obj(columns=4, height=1.5) -> str:
    """The x >= 0 half of :func:`grid_obj`'s grid (x from 0 to 0.5, y from -0.5 to 0.5), facing up, as OBJ text."""
    u, v = np.meshgrid(np.linspace(0.0, 0.5, columns), np.linspace(-0.5, 0.5, SIDE))
    points = np.stack([u.ravel(), v.ravel(), np.full(u.size, height)], axis=1)
    corner = (np.arange(columns - 1)[None, :] + columns * np.arange(SIDE - 1)[:, None]).ravel()
    return obj_text(points, np.stack([corner, corner + 1, corner + columns + 1, corner + columns], axis=1), digits=6)


def holed_sphere_obj(top=0.75, rings=16, segments=32) -> str:
    """The unit UV sphere without its top cap (the faces whose corners are all above ``top``): a hole under the
    grid."""
    points = sphere_points(rings, segments)
    faces = [face for face in sphere_faces(rings, segments) if points[list(face), 2].min() <= top]
    return obj_text(points, faces, digits=6)


def run(script: str, *arguments) -> subprocess.CompletedProcess:
    return run_script(BLENDER_SCRIPTS / script, *arguments)


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("quality_inputs")
    paths = {"template": folder / "grid.obj", "half": folder / "half.obj", "ball": folder / "ball.obj"}
    paths["template"].write_text(grid_obj(SIDE))
    paths["half"].write_text(half_grid_obj())
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


def test_distances_at_the_storage_rounding_flag_nothing():
    """Snapped meshes' distances are float32 rounding (about 1e-7): one twice another's is no outlier, while a
    mesh off its target by a hundredth of the off-surface threshold still is."""
    import retarget_batch

    rows = {f"m{index}": dict(row(distance=3e-8), off_surface_threshold=1e-3) for index in range(4)}
    rows["m4"] = dict(row(distance=6e-8), off_surface_threshold=1e-3)
    assert retarget_batch.quality_outliers(rows) == {}
    rows["off"] = dict(row(distance=1e-4), off_surface_threshold=1e-3)
    assert set(retarget_batch.quality_outliers(rows)) == {"off"}


def test_the_rule_judges_metrics_the_report_has():
    import retarget_batch

    quality = core_module("quality")
    summary_keys = set(quality.summary(quality.Readout(np.ones(3), np.ones(3), np.zeros(2, bool), diagonal=1.0)))
    assert set(retarget_batch.OUTLIER_METRICS) <= summary_keys
