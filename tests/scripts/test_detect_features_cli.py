"""The headless feature-detection CLI (blender_scripts/detect_features.py), end to end, in its own processes.

The input is a .blend (built by a small script run the same way) holding the rounded box of ``helpers.rounded_box``
(half-size 1, blend radius 0.25: 12 ridges on known centre-lines) as ``Box``, a 4 x 4 grid ``Grid`` scaled by 1.5
(world edges 0.375) whose Springwrap target is the box, and a flat grid ``Plane``.
"""

import json
import subprocess

import numpy as np
import pytest

from helpers import REPOSITORY, TIMEOUT_SECONDS, centre_line_distance, rounded_box, script_command

DETECT = REPOSITORY / "blender_scripts" / "detect_features.py"

BUILD = """
import sys
import bpy
import addon_utils
import numpy as np

addon_utils.enable("springwrap", default_set=True)
folder = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
vertices, triangles = np.load(folder + "/box.npy"), np.load(folder + "/triangles.npy")
bpy.ops.wm.read_homefile(use_empty=True)
mesh = bpy.data.meshes.new("Box")
mesh.from_pydata(vertices.tolist(), [], triangles.tolist())
box = bpy.data.objects.new("Box", mesh)
bpy.context.scene.collection.objects.link(box)
bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=1, location=(0, 0, 3))
grid = bpy.context.active_object
grid.name = "Grid"
grid.scale = (1.5, 1.5, 1.5)
grid.springwrap.target = box
bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=10, size=2, location=(5, 0, 0))
bpy.context.active_object.name = "Plane"
bpy.context.view_layer.objects.active = box
bpy.ops.wm.save_as_mainfile(filepath=folder + "/scene.blend")
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("detect_inputs")
    vertices, triangles = rounded_box()
    np.save(folder / "box.npy", vertices)
    np.save(folder / "triangles.npy", triangles)
    builder = folder / "build.py"
    builder.write_text(BUILD)
    process = subprocess.run(
        [*script_command(builder), str(folder)], capture_output=True, text=True, timeout=TIMEOUT_SECONDS
    )
    assert process.returncode == 0, process.stderr[-3000:]
    return folder / "scene.blend"


def run(*arguments) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*script_command(DETECT), *map(str, arguments)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
        cwd=REPOSITORY,
    )


def test_the_automatic_scale_from_the_target_finds_the_twelve_ridges(scene, tmp_path):
    report_path, output = tmp_path / "r.json", tmp_path / "out.blend"
    process = run("--blend", scene, "--object", "Box", "--json", report_path, "--output", output)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    # A tenth of the box's diagonal (2 sqrt 3).
    assert report["scale"] == pytest.approx(0.2 * np.sqrt(3.0), rel=1e-4)
    assert report["scale_chosen"] == "automatic, from the target" and report["layout"] is None
    assert (report["ridges"], report["valleys"]) == (12, 0)
    for curve in report["curves"]:
        assert centre_line_distance(np.array(curve["points"])).max() < 0.01
    assert "scale 0.3464 (automatic, from the target)" in process.stdout
    assert output.stat().st_size > 0


def test_a_layout_sets_the_scale_and_a_given_scale_wins(scene, tmp_path):
    report_path = tmp_path / "r.json"
    process = run("--blend", scene, "--object", "Box", "--layout", "Grid", "--json", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["scale"] == pytest.approx(0.375, rel=1e-5) and report["layout"] == "Grid"
    assert report["layout_edge_length"] == pytest.approx(0.375, rel=1e-5)
    assert report["ridges"] == 12
    process = run("--blend", scene, "--object", "Box", "--layout", "Grid", "--scale", 0.25, "--json", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["scale"] == pytest.approx(0.25) and report["scale_chosen"] == "given"


@pytest.mark.parametrize(
    ("arguments", "code", "message"),
    [
        (("--object", "Nowhere"), 1, "no mesh object 'Nowhere'"),
        (("--object", "Box", "--layout", "Nowhere"), 1, "no mesh object 'Nowhere' for the layout"),
        (("--object", "Plane"), 1, "no curvature"),
        (("--object", "Box", "--scale", "100"), 1, "invalid feature scale"),
        (("--object", "Box", "--scale", "-1"), 2, "--scale must be a finite number"),
        (("--object", "Box", "--hysteresis", "2"), 2, "--hysteresis must be within"),
    ],
)
def test_bad_input_exits_non_zero_and_writes_nothing(scene, tmp_path, arguments, code, message):
    report_path, output = tmp_path / "r.json", tmp_path / "out.blend"
    process = run("--blend", scene, *arguments, "--json", report_path, "--output", output)
    assert process.returncode == code, process.stdout[-2000:] + process.stderr[-2000:]
    assert message in process.stderr, process.stderr[-3000:]
    assert not report_path.exists() and not output.exists()


def test_the_help_gives_the_kernels_minimum_curve_length():
    import springwrap_kernel

    scales = springwrap_kernel.feature_defaults()["min_length_scales"]
    assert scales == 3.0
    shown = run("--help")
    assert shown.returncode == 0, shown.stderr
    assert "shorter curves are dropped (default: 3 times the scale)" in " ".join(shown.stdout.split())
