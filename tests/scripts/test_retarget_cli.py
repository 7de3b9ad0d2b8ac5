"""The headless retargeting CLI (blender_scripts/retarget.py), end to end, in its own processes.

Inputs are generated here: a grid (the template) and spheres (targets) written as OBJ text, a
.blend holding both; each run is ``sys.executable retarget.py ...`` (the venv's Python with the
bpy module) or, inside the blender binary (tests/run_in_blender.py), ``blender -b --python
retarget.py -- ...``, so nothing here touches the bpy state of other tests.

The batch tests run both executors (local worker processes; Ray actors on a Ray instance the script
starts with 2 CPUs) on one folder of six meshes, one of them broken, and check that they agree; worker
deaths are made by ``SPRINGWRAP_BATCH_ABORT`` (the worker aborts on the named mesh, see
``blender_scripts/retarget_batch.py``).
"""

import fcntl
import functools
import json
import math
import os
import pty
import signal
import socket
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

from helpers import REPOSITORY, TIMEOUT_SECONDS, grid_obj, options, outputs, run_script, script_command, sphere_obj

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
run = functools.partial(run_script, RETARGET)
GRID_SIDE = 7  # vertices per side of the template grid


MAKE_BLEND = """
import sys, bpy
template, target, output = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:4]
bpy.ops.wm.read_homefile(use_empty=True)
for path, name in ((template, "Grid"), (target, "Ball")):
    bpy.ops.wm.obj_import(filepath=path)
    bpy.context.selected_objects[0].name = name
grid = bpy.data.objects["Grid"]
centre = sum((vertex.co for vertex in grid.data.vertices), grid.data.vertices[0].co * 0) / len(grid.data.vertices)
group = grid.vertex_groups.new(name="Centre")  # the middle of the grid, for --free-group / --stiffness-group
group.add([vertex.index for vertex in grid.data.vertices if (vertex.co - centre).length < 0.25], 1.0, "REPLACE")
bpy.ops.wm.save_as_mainfile(filepath=output)
"""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("retarget_inputs")
    paths = {"template": folder / "grid.obj", "target": folder / "ball.obj", "big": folder / "big_ball.obj"}
    paths["template"].write_text(grid_obj(GRID_SIDE))
    paths["target"].write_text(sphere_obj(1.0))
    paths["big"].write_text(sphere_obj(1.3, segments=24, rings=12))
    paths["blend"] = folder / "both.blend"
    maker = folder / "make_blend.py"
    maker.write_text(MAKE_BLEND)
    made = subprocess.run(
        [*script_command(maker), str(paths["template"]), str(paths["target"]), str(paths["blend"])],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
    )
    assert made.returncode == 0, made.stderr[-2000:]
    return paths


def test_retargets_an_obj_template_onto_an_obj_target(inputs, tmp_path):
    out = tmp_path / "out"
    process = run(*options(template=inputs["template"], target=inputs["target"], anchors_spacing=0), *outputs(out, "r"))
    assert process.returncode == 0, process.stderr[-3000:]
    assert sorted(path.name for path in out.iterdir()) == ["r.blend", "r.json", "r.obj"]  # no partial files left
    report = json.loads((out / "r.json").read_text())
    assert report["vertices"] == GRID_SIDE**2 and report["faces"] == (GRID_SIDE - 1) ** 2
    assert report["anchors"] > 0 and report["wrap"]["converged"]
    assert report["wrap"]["face_points"] == GRID_SIDE**2  # the whole grid lies on the sphere
    # On the sphere (the faceted one: its flat faces are within 1 - cos(pi/16) ~ 0.02 of the radius).
    assert report["metrics"]["max_distance"] < 1e-5
    assert set(report["timings"]) == {"load", "align and detach", "anchors", "wrap", "metrics"}
    vertices = [line.split()[1:] for line in (out / "r.obj").read_text().splitlines() if line.startswith("v ")]
    radii = [math.dist([float(value) for value in vertex], (0, 0, 0)) for vertex in vertices]
    assert len(vertices) == GRID_SIDE**2 and all(0.97 < radius <= 1.0 + 1e-4 for radius in radii)


Y_UP = ("--up-axis", "Y", "--forward-axis", "NEGATIVE_Z")  # the frame of OBJ files from Blender's exporter


def test_anchors_from_json_and_a_blend_template_object(inputs, tmp_path):
    # The .blend holds the grid as Blender's OBJ importer placed it (Y up: OBJ (x, y, z) is Blender (x, -z, y)).
    # With the Y-up frame, the target OBJ is read the same way, and the anchors file and the output OBJ are in
    # the OBJ files' own coordinates: the grid's two opposite corners (z = 1.5) anchored to points nearer the
    # sphere, each vertex pulled to the surface point closest to its target.
    corner = GRID_SIDE * GRID_SIDE - 1
    wanted = {0: (-0.5, -0.5, 1.0), corner: (0.5, 0.5, 1.0)}  # OBJ space
    anchors = tmp_path / "anchors.json"
    anchors.write_text(
        json.dumps({"anchors": [{"vertex": vertex, "target": point} for vertex, point in wanted.items()]})
    )
    report_path, obj_path = tmp_path / "r.json", tmp_path / "r.obj"
    process = run(
        *options(
            template=inputs["blend"],
            template_object="Grid",
            target=inputs["big"],
            anchors=anchors,
            report=report_path,
            output_obj=obj_path,
        ),
        *Y_UP,
    )
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["anchors"] == 2 and report["vertices"] == GRID_SIDE**2
    vertices = [
        [float(value) for value in line.split()[1:4]]
        for line in obj_path.read_text().splitlines()
        if line.startswith("v ")
    ]
    for vertex, point in wanted.items():
        on_sphere = [1.3 * value / math.dist(point, (0, 0, 0)) for value in point]  # the smooth sphere's closest point
        assert math.dist(vertices[vertex], on_sphere) < 0.06  # the faceted one is within 1.3 (1 - cos(pi / 12))
    # Vertices left off the surface are counted and warned about in the report.
    space_points = report["wrap"]["space_points"]
    assert space_points == 0 or any(f"{space_points} of {GRID_SIDE**2} vertices" in line for line in report["warnings"])


def test_a_free_group_floats_and_the_retired_solver_is_mapped_with_a_warning(inputs, tmp_path):
    common = (
        "--template",
        inputs["blend"],
        "--template-object",
        "Grid",
        "--target",
        inputs["target"],
        "--anchors-spacing",
        0.6,
        "--free-group",
        "Centre",
    )
    report_path = tmp_path / "r.json"
    process = run(*common, "--solver", "energy", "--report", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["wrap"]["converged"] and report["wrap"]["space_points"] >= 1, report["wrap"]
    mapped = run(*common, "--solver", "springs", "--report", tmp_path / "mapped.json")
    assert mapped.returncode == 0, mapped.stderr[-3000:]
    mapped_report = json.loads((tmp_path / "mapped.json").read_text())
    assert any("The Springs solver was retired" in line for line in mapped_report["warnings"])
    assert mapped_report["wrap"]["space_points"] == report["wrap"]["space_points"]
    missing = run(*common[:-1], "Nowhere", "--solver", "energy")
    assert missing.returncode == 1 and "no vertex group 'Nowhere'" in missing.stderr


def test_a_follow_group_follows_the_surface_and_the_report_says_so(inputs, tmp_path):
    common = ("--template", inputs["blend"], "--template-object", "Grid", "--target", inputs["target"])
    common += ("--anchors-spacing", 0.6)
    report_path = tmp_path / "r.json"
    process = run(*common, "--follow-group", "Centre", "--report", report_path)
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert "followed the surface" in report["wrap"]["parts"] and "Follow group" in report["wrap"]["parts"]
    assert report["quality"]["part_vertices"] >= 1
    assert report["quality"]["vertices"] == GRID_SIDE * GRID_SIDE - report["quality"]["part_vertices"]
    missing = run(*common, "--follow-soft-group", "Nowhere")
    assert missing.returncode == 1 and "no vertex group 'Nowhere'" in missing.stderr


@pytest.mark.parametrize(
    "case",
    [
        "missing template",
        "unreadable target",
        "target without faces",
        "several meshes unnamed",
        "anchors not JSON",
        "anchors not a list",
        "anchor on a missing vertex",
        "anchor target not numbers",
    ],
)
def test_bad_input_is_one_line_naming_the_file_and_leaves_nothing(inputs, tmp_path, case):
    out = tmp_path / "out"
    template, target, extra = inputs["template"], inputs["target"], []
    anchors = tmp_path / "anchors.json"
    blamed = {
        "missing template": tmp_path / "nowhere.obj",
        "unreadable target": tmp_path / "junk.ply",
        "target without faces": tmp_path / "points.obj",
        "several meshes unnamed": inputs["blend"],
    }.get(case, anchors)
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
        anchors.write_text(
            {
                "anchors not JSON": '{"anchors": [',
                "anchors not a list": '{"anchors": 3}',
                "anchor on a missing vertex": '{"anchors": [{"vertex": 4900, "target": [0, 0, 1]}]}',
                "anchor target not numbers": '[{"vertex": 1, "target": [0, "up", 1]}]',
            }[case]
        )
        extra = ["--anchors", anchors]
    process = run(*options(template=template, target=target), *extra, *outputs(out, "r"))
    assert process.returncode == 1, process.stderr[-3000:]
    failures = [line for line in process.stderr.splitlines() if line.startswith("retarget: FAILED: ")]
    assert len(failures) == 1 and str(blamed) in failures[0], process.stderr[-3000:]
    assert 'retarget.py", line' not in process.stderr  # no traceback of ours (Blender prints an importer's own)
    assert not out.exists() or list(out.iterdir()) == []


def test_bad_arguments_exit_with_code_2(inputs):
    assert run("--template", inputs["template"]).returncode == 2  # neither --target nor --batch
    assert (
        run("--template", inputs["template"], "--batch", inputs["template"].parent).returncode == 2
    )  # no --output-dir
    assert run("--template", inputs["template"], "--target", inputs["target"], "--jobs", 0).returncode == 2
    folder = inputs["template"].parent
    assert (
        run("--template", inputs["template"], "--batch", folder, "--output-dir", folder / "o", "--jobs", 0).returncode
        == 2
    )
    assert (
        run(
            *options(template=inputs["template"], batch=folder, output_dir=folder / "o", address="127.0.0.1:6379")
        ).returncode
        == 2
    )  # --address without --executor ray
    assert run("--template", inputs["template"], "--target", inputs["target"], "--resume").returncode == 2


def test_batch_retargets_every_mesh_and_skips_a_failing_one(inputs, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "ball.obj").write_text(inputs["target"].read_text())
    (folder / "big_ball.obj").write_text(inputs["big"].read_text())
    (folder / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")  # no faces: fails
    (folder / "notes.txt").write_text("not a mesh")
    out = tmp_path / "out"
    process = run(*options(template=inputs["template"], batch=folder, output_dir=out, jobs=2, anchors_spacing=0.3))
    assert process.returncode == 3, process.stderr[-3000:]
    progress = [line for line in process.stderr.splitlines() if line.startswith("[")]
    assert len(progress) == 3 and sum("FAILED" in line for line in progress) == 1
    assert "%|" not in process.stderr  # no progress bar when stderr is not a terminal
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["ok"], summary["failed"], summary["jobs"], summary["executor"]) == (2, 1, 2, "local")
    # Two long-lived workers were started (one may have been stopped before it was ready: the other served
    # all three); each ready one says what starting it cost and its peak memory.
    assert len(summary["workers"]) == 2 and sum(worker["meshes"] for worker in summary["workers"]) == 3
    ready = [worker for worker in summary["workers"] if worker["worker"] is not None]
    assert all(
        worker["start_seconds"] > 0 and worker["peak_memory_mb"] > 10 and worker["fault"] is None for worker in ready
    )
    assert {entry["worker"] for entry in summary["meshes"]} <= {worker["worker"] for worker in ready}
    [failed] = [entry for entry in summary["meshes"] if entry["status"] == "failed"]
    assert failed["target"].endswith("flat.obj") and "no faces" in failed["error"]
    assert sorted(path.name for path in out.iterdir()) == sorted(
        f"{stem}.{suffix}" for stem in ("ball", "big_ball") for suffix in ("blend", "obj", "json")
    ) + ["summary.json"]
    for stem in ("ball", "big_ball"):
        report = json.loads((out / f"{stem}.json").read_text())
        assert report["wrap"]["face_points"] == GRID_SIDE**2


@pytest.mark.parametrize("frame", [(), Y_UP], ids=["z-up", "y-up"])
def test_align_anchors_then_icp_recovers_the_targets_placement(inputs, tmp_path, frame):
    """The template is the ball; the target the same ball scaled by 1.3 and moved: ``--align anchors`` finds it.
    The anchors file and the alignment in the report are in the files' frame, whichever it is."""
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
    anchors.write_text(
        json.dumps(
            {
                "anchors": [
                    {
                        "vertex": vertex,
                        "target": [scale * value + offset for value, offset in zip(points[vertex], shift)],
                    }
                    for vertex in chosen
                ]
            }
        )
    )
    report_path = tmp_path / "r.json"
    process = run(
        *options(template=inputs["target"], target=target, anchors=anchors, align="anchors", report=report_path), *frame
    )
    assert process.returncode == 0, process.stderr[-3000:]
    alignment = json.loads(report_path.read_text())["alignment"]
    assert alignment["method"] == "similarity" and alignment["anchors"] and alignment["icp"]
    expected = [[scale, 0, 0, shift[0]], [0, scale, 0, shift[1]], [0, 0, scale, shift[2]], [0, 0, 0, 1]]
    for row, expected_row in zip(alignment["matrix"], expected):
        assert all(abs(value - wanted) < 1e-4 for value, wanted in zip(row, expected_row)), alignment["matrix"]


def test_align_arguments_that_cannot_work_exit_with_code_2(inputs):
    assert run("--template", inputs["template"], "--target", inputs["target"], "--align", "anchors").returncode == 2
    assert (
        run(
            *options(template=inputs["template"], target=inputs["target"], align="icp", align_method="affine")
        ).returncode
        == 2
    )


# ---------------------------------------------------------------- batch: executors, isolation, resume, progress

BATCH_SPHERES = {
    "ball_a": (1.0, 32, 16),
    "ball_b": (1.3, 24, 12),
    "ball_c": (0.8, 20, 10),
    "ball_d": (1.1, 28, 14),
    "ball_e": (0.9, 16, 8),
}  # name: radius, segments, rings
BROKEN = "flat"  # three vertices, no faces: fails with "no faces"
VARYING = ("seconds", "worker")  # per-mesh fields that differ from run to run


@pytest.fixture(scope="module")
def batch_folder(tmp_path_factory) -> Path:
    """Six meshes: five spheres of different sizes and resolutions, and one broken (no faces)."""
    folder = tmp_path_factory.mktemp("batch_meshes")
    for name, (radius, segments, rings) in BATCH_SPHERES.items():
        (folder / f"{name}.obj").write_text(sphere_obj(radius, segments, rings))
    (folder / f"{BROKEN}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return folder


def run_batch(inputs, folder: Path, out: Path, *extra, environment=None) -> tuple[subprocess.CompletedProcess, dict]:
    """retarget.py --batch on ``folder`` (2 workers, automatic anchors); the process and its summary."""
    process = run(
        *options(template=inputs["template"], batch=folder, output_dir=out, jobs=2, anchors_spacing=0.3),
        *extra,
        environment=environment,
    )
    summary_path = out / "summary.json"
    assert summary_path.is_file(), process.stderr[-3000:]
    return process, json.loads(summary_path.read_text())


def require_ray() -> None:
    """Where the project's .venv runs the tests, `make setup` installed ray: a missing ray fails the run. The
    other lanes (the bpy 4.2 venv, a Blender binary) skip the Ray tests."""
    if os.environ.get("SPRINGWRAP_BLENDER"):
        pytest.skip("--executor ray runs with the bpy module, not inside a Blender binary")
    if Path(sys.prefix).resolve() != (REPOSITORY / ".venv").resolve():
        pytest.importorskip("ray", reason="ray is installed by `make setup`, in .venv only")


def comparable(summary: dict, out: Path) -> dict:
    """A summary without what differs between two equal runs: timings, worker names, the executor, the folder."""
    text = json.dumps({key: value for key, value in summary.items() if key not in ("seconds", "workers", "executor")})
    entries = json.loads(text.replace(str(out), "OUT"))
    for entry in entries["meshes"]:
        for key in VARYING:
            entry.pop(key, None)
    return entries


def obj_vertex_lines(path: Path) -> list[str]:
    return [line for line in path.read_text().splitlines() if line.startswith("v ")]


def report_without_timings(path: Path) -> dict:
    report = json.loads(path.read_text())
    report.pop("timings")
    report["wrap"].pop("kernel_seconds")
    return report


def test_ray_batch_gives_the_local_batchs_outputs_and_summary(inputs, batch_folder, tmp_path):
    require_ray()
    local, local_summary = run_batch(inputs, batch_folder, tmp_path / "local")
    start = time.perf_counter()
    distributed, ray_summary = run_batch(inputs, batch_folder, tmp_path / "ray", "--executor", "ray")
    ray_seconds = time.perf_counter() - start
    assert local.returncode == 3 and distributed.returncode == 3, distributed.stderr[-3000:]
    assert (ray_summary["executor"], ray_summary["jobs"], ray_summary["ok"], ray_summary["failed"]) == ("ray", 2, 5, 1)
    assert comparable(ray_summary, tmp_path / "ray") == comparable(local_summary, tmp_path / "local")
    [failed] = [entry for entry in ray_summary["meshes"] if entry["status"] == "failed"]
    assert failed["target"].endswith(f"{BROKEN}.obj") and "no faces" in failed["error"] and failed["attempts"] == 1
    # Two Ray workers, each started once, served all six meshes.
    assert len(ray_summary["workers"]) == 2 and sum(worker["meshes"] for worker in ray_summary["workers"]) == 6
    assert all(worker["fault"] is None for worker in ray_summary["workers"])
    assert all(worker["start_seconds"] > 0 for worker in ray_summary["workers"] if worker["meshes"])
    for name in BATCH_SPHERES:
        local_obj, ray_obj = tmp_path / "local" / f"{name}.obj", tmp_path / "ray" / f"{name}.obj"
        assert (
            obj_vertex_lines(ray_obj) == obj_vertex_lines(local_obj) and len(obj_vertex_lines(ray_obj)) == GRID_SIDE**2
        )
        assert report_without_timings(tmp_path / "ray" / f"{name}.json") == report_without_timings(
            tmp_path / "local" / f"{name}.json"
        )
        assert (tmp_path / "ray" / f"{name}.blend").stat().st_size > 0
    assert sorted(path.name for path in (tmp_path / "ray").iterdir()) == sorted(
        path.name for path in (tmp_path / "local").iterdir()
    )  # no partial files left on either side
    print(f"ray batch of {len(BATCH_SPHERES) + 1} meshes: {ray_seconds:.1f} s")


@pytest.fixture
def ray_head(tmp_path):
    """A Ray head with 2 CPUs started as a cluster is (`ray start --head --block`), on a free loopback port,
    without token authentication; its address. Stopped afterwards, with every process it started."""
    require_ray()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    environment = os.environ | {"RAY_AUTH_MODE": "disabled"}
    head = subprocess.Popen(
        [
            str(Path(sys.executable).with_name("ray")),
            "start",
            "--head",
            "--block",
            "--port",
            str(port),
            "--num-cpus",
            "2",
            "--include-dashboard",
            "false",
            "--disable-usage-stats",
        ],
        env=environment,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert head.poll() is None and time.monotonic() < deadline, "the Ray head did not start"
                time.sleep(0.5)
        yield f"127.0.0.1:{port}"
    finally:
        head.terminate()
        try:
            head.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        try:
            os.killpg(head.pid, signal.SIGKILL)  # what it started, in its process group
        except ProcessLookupError:
            pass


def test_ray_batch_on_a_running_cluster_by_its_address(inputs, batch_folder, tmp_path, ray_head):
    local, local_summary = run_batch(inputs, batch_folder, tmp_path / "local")
    process = run(
        *options(
            template=inputs["template"],
            batch=batch_folder,
            output_dir=tmp_path / "ray",
            anchors_spacing=0.3,
            executor="ray",
            address=ray_head,
        ),
        environment={"RAY_AUTH_MODE": "disabled"},
    )
    assert process.returncode == 3, process.stderr[-3000:]
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    assert summary["jobs"] == 2  # without --jobs: one worker per CPU of the cluster
    assert comparable(summary, tmp_path / "ray") == comparable(local_summary, tmp_path / "local")
    for name in BATCH_SPHERES:
        assert obj_vertex_lines(tmp_path / "ray" / f"{name}.obj") == obj_vertex_lines(
            tmp_path / "local" / f"{name}.obj"
        )


def test_an_address_where_no_ray_head_answers_is_one_line(inputs, batch_folder, tmp_path):
    require_ray()
    with socket.socket() as probe:  # a loopback port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    process = run(
        *options(
            template=inputs["template"],
            batch=batch_folder,
            output_dir=tmp_path / "out",
            executor="ray",
            address=f"127.0.0.1:{port}",
        )
    )
    assert process.returncode == 1, process.stderr[-3000:]
    assert f"retarget: FAILED: Ray cannot start or connect (127.0.0.1:{port}): no Ray head answers" in process.stderr


def test_a_long_lived_worker_gives_what_a_single_run_gives(inputs, batch_folder, tmp_path):
    """A worker's later meshes see nothing of its earlier ones: the batch's OBJ is the one-mesh run's."""
    _process, summary = run_batch(inputs, batch_folder, tmp_path / "batch", "--jobs", 1)
    name = sorted(BATCH_SPHERES)[-1]  # the last mesh of the sorted folder: the worker served four before it
    assert [worker["meshes"] for worker in summary["workers"]] == [6]
    single = run(
        *options(
            template=inputs["template"],
            target=batch_folder / f"{name}.obj",
            anchors_spacing=0.3,
            output_obj=tmp_path / "single.obj",
        )
    )
    assert single.returncode == 0, single.stderr[-3000:]
    assert obj_vertex_lines(tmp_path / "batch" / f"{name}.obj") == obj_vertex_lines(tmp_path / "single.obj")


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_a_worker_that_dies_is_replaced_and_its_mesh_retried_once_on_a_fresh_worker(
    inputs, batch_folder, tmp_path, executor
):
    """ball_a kills its worker once (the retry succeeds); ball_c every time (it fails after two); the batch goes on."""
    if executor == "ray":
        require_ray()
    marker = tmp_path / "ball_a-aborted-once"
    process, summary = run_batch(
        inputs,
        batch_folder,
        tmp_path / "out",
        *options(executor=executor),
        environment={"SPRINGWRAP_BATCH_ABORT": f"ball_a.obj:{marker},ball_c.obj"},
    )
    assert process.returncode == 3, process.stderr[-3000:]
    entries = {Path(entry["target"]).stem: entry for entry in summary["meshes"]}
    assert entries["ball_a"]["status"] == "ok" and entries["ball_a"]["attempts"] == 2
    assert entries["ball_c"]["status"] == "failed" and entries["ball_c"]["attempts"] == 2
    assert "died" in entries["ball_c"]["error"] and "two workers" in entries["ball_c"]["error"]
    assert entries[BROKEN]["status"] == "failed" and entries[BROKEN]["attempts"] == 1  # its own error: not retried
    assert all(entries[name]["status"] == "ok" for name in ("ball_b", "ball_d", "ball_e"))
    assert (summary["ok"], summary["failed"], summary["not_run"]) == (4, 2, 0)
    faults = [worker["fault"] for worker in summary["workers"] if worker["fault"]]
    assert len(faults) == 3 and all("died" in fault for fault in faults)
    if executor == "local":
        assert all("SIGABRT" in fault for fault in faults)
    # The retry ran on a fresh worker: one started after the first death, which served nothing before it.
    retried_on = entries["ball_a"]["worker"]
    [record] = [worker for worker in summary["workers"] if worker["worker"] == retried_on]
    assert summary["workers"].index(record) >= 2
    assert obj_vertex_lines(tmp_path / "out" / "ball_a.obj") and not (tmp_path / "out" / "ball_c.obj").exists()
    assert sum("retrying on a fresh worker" in line for line in process.stderr.splitlines()) == 2


def test_resume_skips_the_meshes_already_done(inputs, batch_folder, tmp_path):
    folder, out = tmp_path / "meshes", tmp_path / "out"
    folder.mkdir()
    for path in batch_folder.iterdir():
        (folder / path.name).write_text(path.read_text())
    first, _summary = run_batch(inputs, folder, out)
    assert first.returncode == 3
    (out / "ball_b.json").unlink()  # its report missing: incomplete, done again
    (out / "ball_d.obj").write_text("")  # an empty OBJ: incomplete too
    kept = {name: (out / f"{name}.obj").stat().st_mtime_ns for name in ("ball_a", "ball_c", "ball_e")}
    process, summary = run_batch(inputs, folder, out, "--resume")
    assert process.returncode == 3, process.stderr[-3000:]
    ran = sorted(line.split()[1].rstrip(":") for line in process.stderr.splitlines() if line.startswith("["))
    assert ran == ["ball_b.obj", "ball_d.obj", f"{BROKEN}.obj"]  # the failed one is tried again
    assert (summary["ok"], summary["failed"], summary["resumed"]) == (5, 1, 3)
    assert {Path(entry["target"]).stem for entry in summary["meshes"] if entry.get("resumed")} == set(kept)
    assert {name: (out / f"{name}.obj").stat().st_mtime_ns for name in kept} == kept  # untouched
    assert obj_vertex_lines(out / "ball_d.obj") and (out / "ball_b.json").is_file()
    # Without the broken mesh, everything is done: no worker is started at all.
    (folder / f"{BROKEN}.obj").unlink()
    process, summary = run_batch(inputs, folder, out, "--resume")
    assert process.returncode == 0, process.stderr[-3000:]
    assert summary["workers"] == [] and (summary["resumed"], summary["ok"]) == (5, 5)


def test_resume_makes_again_what_another_template_or_other_settings_made(inputs, tmp_path):
    """Outputs made from another template (same path, other contents) or with other settings are not "already
    done": a resume makes them again and the summary counts them as redone; the same run resumed keeps them."""
    folder, out = tmp_path / "meshes", tmp_path / "out"
    folder.mkdir()
    for name in ("ball_a", "ball_b"):
        (folder / f"{name}.obj").write_text(sphere_obj(*BATCH_SPHERES[name]))
    template = tmp_path / "template.obj"
    template.write_text(grid_obj(GRID_SIDE))
    changed = dict(inputs, template=template)
    first, _summary = run_batch(changed, folder, out)
    assert first.returncode == 0, first.stderr[-3000:]
    template.write_text(grid_obj(GRID_SIDE + 4))  # another template at the same path
    process, summary = run_batch(changed, folder, out, "--resume")
    assert process.returncode == 0, process.stderr[-3000:]
    assert (summary["resumed"], summary["redone"], summary["ok"]) == (0, 2, 2)
    assert all(entry.get("redone") and not entry.get("resumed") for entry in summary["meshes"])
    assert "2 made again" in process.stderr
    for name in ("ball_a", "ball_b"):
        assert json.loads((out / f"{name}.json").read_text())["vertices"] == (GRID_SIDE + 4) ** 2
    process, summary = run_batch(changed, folder, out, "--resume", "--max-iterations", "500")  # another setting
    assert (summary["resumed"], summary["redone"]) == (0, 2), process.stderr[-3000:]
    process, summary = run_batch(changed, folder, out, "--resume", "--max-iterations", "500")  # the same run
    assert (summary["resumed"], summary["redone"], summary["workers"]) == (2, 0, []), process.stderr[-3000:]


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_ctrl_c_stops_the_batch_and_the_summary_lists_the_meshes_not_run(inputs, tmp_path, executor):
    if executor == "ray":
        require_ray()
    folder = tmp_path / "many"
    folder.mkdir()
    for index in range(30):
        (folder / f"mesh_{index:02d}.obj").write_text(inputs["target"].read_text())
    out = tmp_path / "out"
    # A session of its own, signalled as a whole: as a terminal's Ctrl-C reaches every process in the foreground.
    process = subprocess.Popen(
        [
            *script_command(RETARGET),
            *map(str, options(template=inputs["template"], batch=folder, output_dir=out, jobs=2, anchors_spacing=0.3)),
            *("--executor", executor),
        ],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        for line in process.stderr:
            if line.startswith("[2/"):
                os.killpg(process.pid, signal.SIGINT)
                break
        rest = process.stderr.read()
        assert process.wait(timeout=60) == 130, rest[-3000:]
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and summary["not_run"] > 0 and summary["ok"] >= 2
    assert summary["ok"] + summary["failed"] + summary["not_run"] == 30
    assert all(entry["status"] in ("ok", "not run") for entry in summary["meshes"])
    assert "run again with --resume" in rest
    assert not [path.name for path in out.iterdir() if "partial" in path.name]
    time.sleep(0.5)
    for worker in summary["workers"]:  # every worker that got going is gone
        if worker["worker"] is None:
            continue
        pid = int(worker["worker"].rpartition(":")[2])
        assert not Path(f"/proc/{pid}").exists() or "zombie" in Path(f"/proc/{pid}/status").read_text(), worker


def test_progress_is_a_bar_with_an_eta_in_a_terminal(inputs, batch_folder, tmp_path):
    pytest.importorskip("tqdm")
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a new pty is 0 columns wide
    process = subprocess.Popen(
        [
            *script_command(RETARGET),
            *map(str, options(template=inputs["template"], batch=batch_folder, output_dir=tmp_path / "out")),
            *("--anchors-spacing", "0.3"),
        ],
        stderr=follower,
        stdout=subprocess.DEVNULL,
    )
    os.close(follower)
    shown = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the terminal's other end closed
            break
        if not chunk:
            break
        shown += chunk
    os.close(leader)
    assert process.wait(timeout=TIMEOUT_SECONDS) == 3
    text = shown.decode(errors="replace")
    assert "6/6" in text and "100%|" in text and "mesh/s" in text and "<" in text, text[-2000:]  # bar, rate, ETA
    assert f"FAILED: {batch_folder / BROKEN}.obj" in text  # failures are printed above the bar
    assert "] ball_a.obj: ok" not in text  # successes only move the bar


def test_ray_executor_without_ray_says_how_to_install_it(inputs, batch_folder, tmp_path):
    shadow = tmp_path / "no_ray"
    shadow.mkdir()
    (shadow / "ray.py").write_text("raise ImportError(\"No module named 'ray'\")\n")
    path = os.pathsep.join(filter(None, [str(shadow), os.environ.get("PYTHONPATH")]))
    process = run(
        *options(template=inputs["template"], batch=batch_folder, output_dir=tmp_path / "out", executor="ray"),
        environment={"PYTHONPATH": path},
    )
    assert process.returncode == 1, process.stderr[-3000:]
    failures = [line for line in process.stderr.splitlines() if line.startswith("retarget: FAILED: ")]
    expected = (
        "not inside a Blender binary" if os.environ.get("SPRINGWRAP_BLENDER") else "pip install -r requirements-ray.txt"
    )
    assert len(failures) == 1 and expected in failures[0], process.stderr[-3000:]
    assert not (tmp_path / "out" / "summary.json").exists()


def test_max_iterations_caps_the_wrap_and_changes_its_result(inputs, tmp_path):
    reports = {}
    for name, extra in (("capped", ("--max-iterations", "2")), ("default", ())):
        out = tmp_path / name
        process = run(
            *options(template=inputs["template"], target=inputs["big"], anchors_spacing=0),
            *outputs(out, "r", kinds=("report",)),
            *extra,
        )
        assert process.returncode == 0, process.stderr[-3000:]
        reports[name] = json.loads((out / "r.json").read_text())["wrap"]
    capped, default = reports["capped"], reports["default"]
    assert capped["iterations"] == 2 and not capped["converged"]
    assert default["iterations"] > 2 and default["converged"]
    # Stopped before its points landed: the capped wrap leaves them in space, the full one on the target.
    assert capped["face_points"] < default["face_points"] == GRID_SIDE**2
