"""The headless mirroring CLI (blender_scripts/mirror.py), end to end, in its own processes.

Inputs are generated OBJ text: the x >= 0 half of a UV sphere of radius 1.1 (the surfaced half: it
is snapped onto the target with ``--snap``) and a whole sphere of radius 1 (the target). Each run
is ``sys.executable mirror.py ...`` or, inside the blender binary, ``blender -b --python mirror.py
-- ...`` (see ``test_retarget_cli.script_command``).
"""

import functools
import json
import math

import pytest

from helpers import REPOSITORY, options, outputs, run_script, sphere_obj

MIRROR = REPOSITORY / "blender_scripts" / "mirror.py"
run = functools.partial(run_script, MIRROR)
RINGS, COLUMNS = 8, 6  # of the half-sphere layout: 7 rings between the poles, 7 meridians from -90 to +90 degrees


def half_sphere_obj(radius: float = 1.1, shift: float = 0.0) -> str:
    """The x >= 0 half of a UV sphere (poles and the two meridians at x = 0 exactly), shifted along x, as OBJ text."""
    lines = [f"v {shift:.6f} 0 {radius:.6f}"]
    for ring in range(1, RINGS):
        polar = math.pi * ring / RINGS
        for column in range(COLUMNS + 1):
            azimuth = -math.pi / 2 + math.pi * column / COLUMNS
            x = 0.0 if column in (0, COLUMNS) else radius * math.sin(polar) * math.cos(azimuth)
            lines.append(
                f"v {x + shift:.6f} {radius * math.sin(polar) * math.sin(azimuth):.6f} {radius * math.cos(polar):.6f}"
            )
    lines.append(f"v {shift:.6f} 0 {-radius:.6f}")
    bottom = 2 + (RINGS - 1) * (COLUMNS + 1)

    def vertex(ring, column):
        return 2 + (ring - 1) * (COLUMNS + 1) + column

    for column in range(COLUMNS):
        lines.append(f"f 1 {vertex(1, column)} {vertex(1, column + 1)}")
        lines.append(f"f {bottom} {vertex(RINGS - 1, column + 1)} {vertex(RINGS - 1, column)}")
        for ring in range(1, RINGS - 1):
            lines.append(
                f"f {vertex(ring, column)} {vertex(ring + 1, column)} "
                f"{vertex(ring + 1, column + 1)} {vertex(ring, column + 1)}"
            )
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("mirror_inputs")
    paths = {"half": folder / "half.obj", "far": folder / "far.obj", "target": folder / "ball.obj"}
    paths["half"].write_text(half_sphere_obj())
    paths["far"].write_text(half_sphere_obj(shift=3.0))
    paths["target"].write_text(sphere_obj(1.0))
    return paths


def test_mirrors_and_wraps_an_obj_half_onto_an_obj_target(inputs, tmp_path):
    out = tmp_path / "out"
    process = run(*options(layout=inputs["half"], target=inputs["target"], axis="X", snap=True), *outputs(out, "m"))
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((out / "m.json").read_text())
    half_vertices = 2 + (RINGS - 1) * (COLUMNS + 1)
    seam = 2 + 2 * (RINGS - 1)
    assert report["vertices_before"] == half_vertices
    assert report["seam_vertices"] == seam
    assert report["vertices"] == 2 * half_vertices - seam
    assert report["seam_max_distance_to_plane"] < 1e-5
    assert report["wrap"]["converged"] and report["wrap"]["space_points"] == 0
    # Every vertex on the target (a sphere of radius 1 tessellated with 32 segments: within its sagitta).
    assert report["metrics"]["max_distance"] < 1e-5
    assert report["crossing_faces"] == []
    exported = [line for line in (out / "m.obj").read_text().splitlines() if line.startswith("v ")]
    assert len(exported) == report["vertices"]
    assert (out / "m.blend").stat().st_size > 0


def test_mirror_only_needs_no_target(inputs, tmp_path):
    report_path = tmp_path / "m.json"
    process = run("--layout", inputs["half"], "--no-wrap", "--report", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["wrap"] is None and report["metrics"] is None
    assert report["seam_max_distance_to_plane"] < 1e-6


def test_a_plane_that_misses_the_layout_fails_in_one_line_and_writes_nothing(inputs, tmp_path):
    out = tmp_path / "out"
    process = run(
        *options(
            layout=inputs["far"], target=inputs["target"], axis="X", output_obj=out / "m.obj", report=out / "m.json"
        )
    )
    assert process.returncode == 1, process.stderr[-3000:]
    failures = [line for line in process.stderr.splitlines() if line.startswith("mirror: FAILED: ")]
    assert len(failures) == 1 and str(inputs["far"]) in failures[0] and "misses" in failures[0], process.stderr
    assert not out.exists() or list(out.iterdir()) == []


def test_bad_arguments_exit_with_code_2(inputs):
    assert run("--layout", inputs["half"]).returncode == 2  # no --target and no --no-wrap
    assert run("--layout", inputs["half"], "--no-wrap", "--weld-distance", "0").returncode == 2
    assert run("--layout", inputs["half"], "--no-wrap", "--mirror-object", "Empty").returncode == 2  # not a .blend
    assert run("--layout", inputs["half"], "--target", inputs["target"], "--max-iterations", "0").returncode == 2
