"""``retarget.py --symmetric-anchors X|Y|Z``, end to end in its own processes: anchors in pairs across the
template's plane, the pairs in the report, the wrapped result symmetric; the batch passes the flag on.

Inputs are generated: a square grid template symmetric across x = 0 (and y = 0) above a UV sphere centred on
the origin (symmetric across both too), as OBJ text.
"""

import functools
import json

import numpy as np
import pytest

from helpers import REPOSITORY, grid_obj, run_script, sphere_obj

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
run = functools.partial(run_script, RETARGET)
SIDE = 9  # vertices per side of the template grid


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("symmetric_inputs")
    paths = {"template": folder / "grid.obj", "target": folder / "ball.obj"}
    paths["template"].write_text(grid_obj(SIDE))
    paths["target"].write_text(sphere_obj(1.0))
    return paths


def obj_vertices(path) -> np.ndarray:
    return np.array(
        [
            [float(value) for value in line.split()[1:4]]
            for line in path.read_text().splitlines()
            if line.startswith("v ")
        ]
    )


def mirror_error(points: np.ndarray, axis: int) -> float:
    """The largest distance from a point's reflection (coordinate ``axis`` negated) to the nearest point."""
    reflected = points.copy()
    reflected[:, axis] *= -1.0
    return float(np.linalg.norm(reflected[:, None] - points[None], axis=2).min(axis=1).max())


@pytest.mark.parametrize("axis", ["X", "Y"])
def test_symmetric_anchors_come_in_pairs_and_the_result_is_symmetric(inputs, tmp_path, axis):
    out = tmp_path / "out"
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors-spacing", 0.3,
        "--symmetric-anchors", axis, "--output-obj", out / "r.obj", "--report", out / "r.json",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((out / "r.json").read_text())
    symmetric = report["symmetric_anchors"]
    assert symmetric["axis"] == axis and symmetric["alone"] == 0
    assert symmetric["pairs"] >= 3 and symmetric["on_plane"] >= 1
    assert report["anchors"] == 2 * symmetric["pairs"] + symmetric["on_plane"]
    points = obj_vertices(out / "r.obj")
    assert len(points) == SIDE**2
    assert mirror_error(points, "XYZ".index(axis)) < 1e-3  # the wrapped grid stays symmetric


def test_without_the_flag_the_report_has_no_pairs(inputs, tmp_path):
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors-spacing", 0.3,
        "--report", tmp_path / "r.json",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    assert json.loads((tmp_path / "r.json").read_text())["symmetric_anchors"] is None


def test_an_anchors_file_gets_twins_too(inputs, tmp_path):
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"anchors": [{"vertex": 1, "target": [-0.4, -0.4, 0.8]}]}))  # x = -0.375
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors", anchors,
        "--symmetric-anchors", "X", "--report", tmp_path / "r.json",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["anchors"] == 2 and report["symmetric_anchors"]["pairs"] == 1


def test_a_wrong_axis_is_a_usage_error(inputs, tmp_path):
    process = run("--template", inputs["template"], "--target", inputs["target"], "--symmetric-anchors", "W")
    assert process.returncode == 2 and "--symmetric-anchors" in process.stderr


def test_the_batch_passes_the_flag_on(inputs, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "ball.obj").write_text(sphere_obj(1.0))
    out = tmp_path / "out"
    process = run(
        "--template", inputs["template"], "--batch", folder, "--output-dir", out, "--jobs", 1,
        "--anchors-spacing", 0.3, "--symmetric-anchors", "X",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((out / "ball.json").read_text())
    assert report["symmetric_anchors"]["pairs"] >= 3 and report["symmetric_anchors"]["alone"] == 0
