"""The headless retargeting CLI (blender_scripts/retarget.py), end to end, in its own processes.

Inputs are generated here: a grid (the template) and spheres (targets) written as OBJ text, a
.blend holding both; each run is ``sys.executable retarget.py ...`` (the venv's Python with the
bpy module) or, inside the blender binary (tests/run_in_blender.py), ``blender -b --python
retarget.py -- ...``, so nothing here touches the bpy state of other tests.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parent.parent
RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
TIMEOUT_SECONDS = 180
GRID_SIDE = 7  # vertices per side of the template grid


def grid_obj(side: int = GRID_SIDE, size: float = 1.0, height: float = 1.5) -> str:
    """A flat square grid of side x side vertices above the origin, as OBJ text."""
    lines = [f"v {size * (i / (side - 1) - 0.5):.6f} {size * (j / (side - 1) - 0.5):.6f} {height}"
             for j in range(side) for i in range(side)]
    for j in range(side - 1):
        for i in range(side - 1):
            a = j * side + i + 1
            lines.append(f"f {a} {a + 1} {a + side + 1} {a + side}")
    return "\n".join(lines) + "\n"


def sphere_obj(radius: float, segments: int = 32, rings: int = 16) -> str:
    """A UV sphere at the origin, as OBJ text (triangle fans at the poles, quads between)."""
    lines = ["v 0 0 %.6f" % radius]
    for ring in range(1, rings):
        polar = math.pi * ring / rings
        for segment in range(segments):
            azimuth = 2 * math.pi * segment / segments
            lines.append(f"v {radius * math.sin(polar) * math.cos(azimuth):.6f} "
                         f"{radius * math.sin(polar) * math.sin(azimuth):.6f} {radius * math.cos(polar):.6f}")
    lines.append("v 0 0 %.6f" % -radius)
    bottom = 2 + (rings - 1) * segments

    def ring_vertex(ring, segment):
        return 2 + (ring - 1) * segments + segment % segments

    for segment in range(segments):
        lines.append(f"f 1 {ring_vertex(1, segment)} {ring_vertex(1, segment + 1)}")
        lines.append(f"f {bottom} {ring_vertex(rings - 1, segment + 1)} {ring_vertex(rings - 1, segment)}")
        for ring in range(1, rings - 1):
            lines.append(f"f {ring_vertex(ring, segment)} {ring_vertex(ring + 1, segment)} "
                         f"{ring_vertex(ring + 1, segment + 1)} {ring_vertex(ring, segment + 1)}")
    return "\n".join(lines) + "\n"


def script_command(script: Path) -> list[str]:
    """How to run a Blender script here: with this Python (bpy module) or with this lane's blender binary."""
    blender = os.environ.get("SPRINGWRAP_BLENDER")
    if blender:
        return [blender, "-b", "--factory-startup", "--python-use-system-env", "--python-exit-code", "1",
                "--python", str(script), "--"]
    return [sys.executable, str(script)]


MAKE_BLEND = """
import sys, bpy
template, target, output = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:4]
bpy.ops.wm.read_homefile(use_empty=True)
for path, name in ((template, "Grid"), (target, "Ball")):
    bpy.ops.wm.obj_import(filepath=path)
    bpy.context.selected_objects[0].name = name
bpy.ops.wm.save_as_mainfile(filepath=output)
"""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("retarget_inputs")
    paths = {"template": folder / "grid.obj", "target": folder / "ball.obj", "big": folder / "big_ball.obj"}
    paths["template"].write_text(grid_obj())
    paths["target"].write_text(sphere_obj(1.0))
    paths["big"].write_text(sphere_obj(1.3, segments=24, rings=12))
    paths["blend"] = folder / "both.blend"
    maker = folder / "make_blend.py"
    maker.write_text(MAKE_BLEND)
    made = subprocess.run([*script_command(maker), str(paths["template"]), str(paths["target"]), str(paths["blend"])],
                          capture_output=True, text=True, timeout=TIMEOUT_SECONDS)
    assert made.returncode == 0, made.stderr[-2000:]
    return paths


def run(*arguments, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([*script_command(RETARGET), *map(str, arguments)], capture_output=True, text=True,
                          timeout=TIMEOUT_SECONDS, cwd=cwd or REPOSITORY)


def test_retargets_an_obj_template_onto_an_obj_target(inputs, tmp_path):
    out = tmp_path / "out"
    process = run("--template", inputs["template"], "--target", inputs["target"], "--anchors-spacing", 0,
                  "--output-blend", out / "r.blend", "--output-obj", out / "r.obj", "--report", out / "r.json")
    assert process.returncode == 0, process.stderr[-3000:]
    assert sorted(path.name for path in out.iterdir()) == ["r.blend", "r.json", "r.obj"]  # no partial files left
    report = json.loads((out / "r.json").read_text())
    assert report["vertices"] == GRID_SIDE ** 2 and report["faces"] == (GRID_SIDE - 1) ** 2
    assert report["anchors"] > 0 and report["wrap"]["converged"]
    assert report["wrap"]["face_points"] == GRID_SIDE ** 2  # the whole grid lies on the sphere
    # On the sphere (the faceted one: its flat faces are within 1 - cos(pi/16) ~ 0.02 of the radius).
    assert report["metrics"]["max_distance"] < 1e-5
    assert set(report["timings"]) == {"load", "align and detach", "anchors", "wrap", "metrics"}
    vertices = [line.split()[1:] for line in (out / "r.obj").read_text().splitlines() if line.startswith("v ")]
    radii = [math.dist([float(value) for value in vertex], (0, 0, 0)) for vertex in vertices]
    assert len(vertices) == GRID_SIDE ** 2 and all(0.97 < radius <= 1.0 + 1e-4 for radius in radii)


def blender_from_obj(point):
    """OBJ files are Y-up (Blender's importer and exporter convert): OBJ (x, y, z) is Blender (x, -z, y)."""
    x, y, z = point
    return [x, -z, y]


def test_anchors_from_json_and_a_blend_template_object(inputs, tmp_path):
    # The grid's two opposite corners (OBJ space: z = 1.5) anchored to points nearer the sphere; anchor
    # targets are world (Blender) coordinates, each vertex is pulled to the surface point closest to its target.
    corner = GRID_SIDE * GRID_SIDE - 1
    wanted = {0: (-0.5, -0.5, 1.0), corner: (0.5, 0.5, 1.0)}  # OBJ space
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"anchors": [{"vertex": vertex, "target": blender_from_obj(point)}
                                               for vertex, point in wanted.items()]}))
    report_path, obj_path = tmp_path / "r.json", tmp_path / "r.obj"
    process = run("--template", inputs["blend"], "--template-object", "Grid", "--target", inputs["big"],
                  "--anchors", anchors, "--report", report_path, "--output-obj", obj_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["anchors"] == 2 and report["vertices"] == GRID_SIDE ** 2
    vertices = [[float(value) for value in line.split()[1:4]] for line in obj_path.read_text().splitlines()
                if line.startswith("v ")]
    for vertex, point in wanted.items():
        on_sphere = [1.3 * value / math.dist(point, (0, 0, 0)) for value in point]  # the smooth sphere's closest point
        assert math.dist(vertices[vertex], on_sphere) < 0.06  # the faceted one is within 1.3 (1 - cos(pi / 12))
    # Vertices left off the surface are counted and warned about in the report.
    space_points = report["wrap"]["space_points"]
    assert space_points == 0 or any(f"{space_points} of {GRID_SIDE ** 2} vertices" in line for line in report["warnings"])


@pytest.mark.parametrize("case", ["missing template", "unreadable target", "target without faces",
                                  "several meshes unnamed", "anchors not JSON", "anchors not a list",
                                  "anchor on a missing vertex", "anchor target not numbers"])
def test_bad_input_is_one_line_naming_the_file_and_leaves_nothing(inputs, tmp_path, case):
    out = tmp_path / "out"
    template, target, extra = inputs["template"], inputs["target"], []
    anchors = tmp_path / "anchors.json"
    blamed = {"missing template": tmp_path / "nowhere.obj", "unreadable target": tmp_path / "junk.ply",
              "target without faces": tmp_path / "points.obj", "several meshes unnamed": inputs["blend"]}.get(case, anchors)
    if case == "missing template":
        template = blamed
    elif case == "unreadable target":
        blamed.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\nend_header\n\x00\x01")
        target = blamed
    elif case == "target without faces":
        blamed.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
        target = blamed
    elif case == "several meshes unnamed":
        target = blamed
    else:
        anchors.write_text({"anchors not JSON": '{"anchors": [', "anchors not a list": '{"anchors": 3}',
                            "anchor on a missing vertex": '{"anchors": [{"vertex": 4900, "target": [0, 0, 1]}]}',
                            "anchor target not numbers": '[{"vertex": 1, "target": [0, "up", 1]}]'}[case])
        extra = ["--anchors", anchors]
    process = run("--template", template, "--target", target, *extra, "--output-blend", out / "r.blend",
                  "--output-obj", out / "r.obj", "--report", out / "r.json")
    assert process.returncode == 1, process.stderr[-3000:]
    failures = [line for line in process.stderr.splitlines() if line.startswith("retarget: FAILED: ")]
    assert len(failures) == 1 and str(blamed) in failures[0], process.stderr[-3000:]
    assert 'retarget.py", line' not in process.stderr  # no traceback of ours (Blender prints an importer's own)
    assert not out.exists() or list(out.iterdir()) == []


def test_bad_arguments_exit_with_code_2(inputs):
    assert run("--template", inputs["template"]).returncode == 2  # neither --target nor --batch
    assert run("--template", inputs["template"], "--batch", inputs["template"].parent).returncode == 2  # no --output-dir
    assert run("--template", inputs["template"], "--target", inputs["target"], "--jobs", 0).returncode == 2


def test_batch_retargets_every_mesh_and_skips_a_failing_one(inputs, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "ball.obj").write_text(inputs["target"].read_text())
    (folder / "big_ball.obj").write_text(inputs["big"].read_text())
    (folder / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")  # no faces: fails
    (folder / "notes.txt").write_text("not a mesh")
    out = tmp_path / "out"
    process = run("--template", inputs["template"], "--batch", folder, "--output-dir", out, "--jobs", 2,
                  "--anchors-spacing", 0.3)
    assert process.returncode == 3, process.stderr[-3000:]
    progress = [line for line in process.stderr.splitlines() if line.startswith("[")]
    assert len(progress) == 3 and sum("FAILED" in line for line in progress) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["ok"], summary["failed"], summary["jobs"]) == (2, 1, 2)
    [failed] = [entry for entry in summary["meshes"] if entry["status"] == "failed"]
    assert failed["target"].endswith("flat.obj") and "no faces" in failed["error"]
    assert sorted(path.name for path in out.iterdir()) == sorted(
        f"{stem}.{suffix}" for stem in ("ball", "big_ball") for suffix in ("blend", "obj", "json")) + ["summary.json"]
    for stem in ("ball", "big_ball"):
        report = json.loads((out / f"{stem}.json").read_text())
        assert report["wrap"]["face_points"] == GRID_SIDE ** 2


def test_align_anchors_then_icp_recovers_the_targets_placement(inputs, tmp_path):
    """The template is the ball; the target the same ball scaled by 1.3 and moved: ``--align anchors`` finds it."""
    scale, shift = 1.3, (0.4, -0.2, 0.1)  # OBJ space
    template_lines = inputs["target"].read_text().splitlines()
    moved = []
    for line in template_lines:
        if line.startswith("v "):
            point = [scale * float(value) + offset for value, offset in zip(line.split()[1:4], shift)]
            line = "v " + " ".join(f"{value:.6f}" for value in point)
        moved.append(line)
    target = tmp_path / "moved_ball.obj"
    target.write_text("\n".join(moved) + "\n")
    points = [[float(value) for value in line.split()[1:4]] for line in template_lines if line.startswith("v ")]
    chosen = [0, len(points) - 1, 1 + 7 * 32, 1 + 7 * 32 + 8, 1 + 3 * 32 + 20]  # poles, equator, upper ring
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"anchors": [
        {"vertex": vertex, "target": blender_from_obj([scale * value + offset for value, offset in zip(points[vertex], shift)])}
        for vertex in chosen]}))
    report_path = tmp_path / "r.json"
    process = run("--template", inputs["target"], "--target", target, "--anchors", anchors, "--align", "anchors",
                  "--report", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    alignment = json.loads(report_path.read_text())["alignment"]
    assert alignment["method"] == "similarity" and alignment["anchors"] and alignment["icp"]
    expected = [[scale, 0, 0, shift[0]], [0, scale, 0, -shift[2]], [0, 0, scale, shift[1]], [0, 0, 0, 1]]
    for row, expected_row in zip(alignment["matrix"], expected):
        assert all(abs(value - wanted) < 1e-4 for value, wanted in zip(row, expected_row)), alignment["matrix"]


def test_align_arguments_that_cannot_work_exit_with_code_2(inputs):
    assert run("--template", inputs["template"], "--target", inputs["target"], "--align", "anchors").returncode == 2
    assert run("--template", inputs["template"], "--target", inputs["target"], "--align", "icp",
               "--align-method", "affine").returncode == 2
