"""``retarget.py --fit-subdivision LEVELS``: after the wrap, the layout is fitted as a subdivision cage, and the
JSON report carries its Subdivision Surface's distances to the target before and after (own processes)."""

import functools
import json

import pytest

from helpers import REPOSITORY, grid_obj, options, run_script, sphere_obj

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
run = functools.partial(run_script, RETARGET)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("fit_inputs")
    paths = {"template": folder / "grid.obj", "target": folder / "ball.obj"}
    paths["template"].write_text(grid_obj(6, size=1.2, height=1.5, up="Y"))
    paths["target"].write_text(sphere_obj(1.0, segments=64, rings=32))
    return paths


def test_the_report_gives_the_subdivided_surfaces_distances_before_and_after(inputs, tmp_path):
    report_path = tmp_path / "r.json"
    process = run(
        *options(
            template=inputs["template"],
            target=inputs["target"],
            anchors_spacing=0,
            fit_subdivision=2,
            report=report_path,
        )
    )
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    fit = report["fit_subdivision"]
    assert fit["levels"] == 2 and fit["blender_surface"]
    assert fit["surface_points"] == (4 * 5 + 1) ** 2  # a 5 x 5 grid of quads, subdivided twice
    # Automatic anchors on every vertex of this small grid hold the surface at each cage vertex's own point
    # (36 of the 441 points), which leaves the fit less to do than on a free cage.
    assert report["anchors"] == 36
    assert fit["max_distance_before"] > 0.005
    assert fit["max_distance_after"] * 1.5 < fit["max_distance_before"]
    assert fit["mean_distance_after"] * 3.0 < fit["mean_distance_before"]
    assert "fit subdivision" in report["timings"]


def test_without_the_option_there_is_no_fit(inputs, tmp_path):
    report_path = tmp_path / "r.json"
    process = run("--template", inputs["template"], "--target", inputs["target"], "--report", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    assert json.loads(report_path.read_text())["fit_subdivision"] is None


@pytest.mark.parametrize("levels", [0, 7])
def test_a_level_out_of_range_exits_with_code_2(inputs, levels):
    process = run("--template", inputs["template"], "--target", inputs["target"], "--fit-subdivision", levels)
    assert process.returncode == 2
    assert "--fit-subdivision" in process.stderr
