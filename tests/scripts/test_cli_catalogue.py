"""The command line under hostile input: every refusal is exit code 1 (2 for arguments that cannot be meant)
with one line ``<script>: FAILED: <file>: <problem>``, no traceback of ours, and no output left behind — not
the outputs, not their temporary files, not a folder created for them. Each case runs the script in its own
process (``sys.executable X.py`` with the bpy module, or the lane's blender binary), as a pipeline would.

The catalogue: missing, empty, truncated, binary garbage, huge element counts (which aborted Blender's PLY
importer), NaN and absurd coordinates, a folder as an output, an output folder that cannot be written, batch
meshes whose outputs would clash, stale outputs of an earlier run beside a mesh that now fails.
"""

import json
import os
import subprocess
from pathlib import Path

import pytest

from helpers import REPOSITORY, options, outputs, run_script, sphere_obj
from mesh_writers import ellipsoid, glb, ply_binary, stl_binary

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
MIRROR = REPOSITORY / "blender_scripts" / "mirror.py"
WRAP = REPOSITORY / "blender_scripts" / "wrap.py"
GRID = "".join(f"v {i / 4 - 0.5:.3f} {j / 4 - 0.5:.3f} 1.5\n" for j in range(5) for i in range(5)) + "".join(
    f"f {j * 5 + i + 1} {j * 5 + i + 2} {j * 5 + i + 7} {j * 5 + i + 6}\n" for j in range(4) for i in range(4)
)


def the_failure(process: subprocess.CompletedProcess, script: str = "retarget") -> str:
    """The one ``FAILED`` line of a run that exited with code 1 and printed no traceback of ours."""
    assert process.returncode == 1, (process.returncode, process.stderr[-3000:])
    failures = [line for line in process.stderr.splitlines() if line.startswith(f"{script}: FAILED: ")]
    assert len(failures) == 1, process.stderr[-3000:]
    assert "Traceback" not in process.stderr, process.stderr[-3000:]
    return failures[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("catalogue")
    vertices, triangles = ellipsoid(segments=12, rings=6)
    good_ply = ply_binary(vertices, triangles)
    broken = vertices.copy()
    broken[7] = (0.0, float("nan"), 0.0)
    body = good_ply.index(b"end_header\n") + len(b"end_header\n")
    contents = {
        "grid.obj": GRID.encode(),
        "ball.obj": sphere_obj(1.0, 16, 8).encode(),
        "empty.obj": b"",
        "truncated.ply": good_ply[: body + (len(good_ply) - body) // 2],
        "garbage.obj": bytes(range(256)) * 8,
        "garbage.stl": b"\x93" * 200,
        "huge.ply": (
            b"ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0 0\n"
        ),
        "nan.obj": b"v nan nan nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "far.obj": b"v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n",
        "bad_index.ply": ply_binary(vertices, [*triangles.tolist(), [0, 1, 999]]),
        "truncated.stl": stl_binary(vertices, triangles)[:-30],
        # Its header states finite bounds, and Blender's importer reads the NaN as 0: its data is checked.
        "nan.glb": glb(broken, triangles, bounds=([-2.0] * 3, [2.0] * 3)),
        "empty.blend": b"",
        "garbage.blend": b"\x00\x01\x02 not Blender" * 20,
    }
    paths = {}
    for name, data in contents.items():
        paths[name] = folder / name
        paths[name].write_bytes(data)
    return paths


CASES = {
    # target file: what the one line says about it
    "missing.obj": "no such file",
    "empty.obj": "the file is empty",
    "truncated.ply": "truncated: element 'face'",
    "garbage.obj": "binary data (a NUL byte at byte 0): not a text file",
    "garbage.stl": "truncated binary STL",
    "huge.ply": "element 'vertex' has 4000000000 entries, more than Blender's PLY importer can read",
    "nan.obj": "vertex 0 (line 1) has a NaN or infinite coordinate (nan, nan, nan)",
    "far.obj": "vertex 1 (line 2) is absurdly far from the origin (1e+30, 0, 0)",
    "bad_index.ply": "element 'face': vertex index 999 does not exist",
    "truncated.stl": "truncated binary STL",
    "nan.glb": "accessor 0: vertex 7 has a NaN or infinite coordinate (0, nan, 0)",
    "empty.blend": "the file is empty",
    "garbage.blend": "not a .blend file",
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_hostile_target_is_one_line_and_leaves_nothing(files, tmp_path, name):
    target = files.get(name, files["grid.obj"].parent / name)
    out = tmp_path / "out"
    process = run_script(RETARGET, *options(template=files["grid.obj"], target=target), *outputs(out, "r"))
    failure = the_failure(process)
    assert failure.startswith(f"retarget: FAILED: {target}: ") and CASES[name] in failure, failure
    assert not out.exists()  # not even the folder


@pytest.mark.parametrize("name", ["nan.obj", "huge.ply"])
def test_a_hostile_template_is_refused_the_same_way(files, tmp_path, name):
    process = run_script(
        RETARGET, *options(template=files[name], target=files["ball.obj"], output_obj=tmp_path / "r.obj")
    )
    failure = the_failure(process)
    assert failure.startswith(f"retarget: FAILED: {files[name]}: ") and CASES[name] in failure, failure
    assert list(tmp_path.iterdir()) == []


def test_a_folder_as_an_output_is_refused_before_any_work(files, tmp_path):
    out = tmp_path / "out"
    (out / "r.obj").mkdir(parents=True)
    process = run_script(
        RETARGET,
        *options(
            template=files["grid.obj"], target=files["ball.obj"], output_blend=out / "r.blend", output_obj=out / "r.obj"
        ),
    )
    assert the_failure(process) == f"retarget: FAILED: {out / 'r.obj'}: is a folder; name the output file"
    assert [path.name for path in out.iterdir()] == ["r.obj"] and list((out / "r.obj").iterdir()) == []
    assert "import of" not in process.stdout + process.stderr  # refused before the meshes were read


def test_an_output_folder_that_cannot_be_written_is_refused_before_any_work(files, tmp_path):
    blocked = tmp_path / "a_file"
    blocked.write_text("not a folder")
    process = run_script(
        RETARGET, *options(template=files["grid.obj"], target=files["ball.obj"], report=blocked / "out" / "r.json")
    )
    assert (
        the_failure(process)
        == f"retarget: FAILED: {blocked}: is a file, not a folder, so {blocked / 'out'} cannot be written"
    )
    process = run_script(
        RETARGET, *options(template=files["grid.obj"], target=files["ball.obj"], output_obj="/proc/springwrap/r.obj")
    )
    assert "retarget: FAILED: /proc: not writable: no file can be created in this folder" in the_failure(process)
    assert "No such file" not in the_failure(process)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--output-obj", "OUT/r.ply"], "--output-obj OUT/r.ply: the file name must end with .obj"),
        (["--output-blend", "OUT/r.obj", "--output-obj", "OUT/r.obj"], "must end with .blend"),
        (["--output-obj", "OUT/r.obj", "--report", "OUT/r.obj"], "--output-obj and --report name the same file"),
        (["--output-obj", "TARGET"], "would replace an input"),
        (["--up-axis", "Y", "--forward-axis", "NEGATIVE_Y"], "are the same axis"),
    ],
)
def test_outputs_that_cannot_be_meant_are_bad_arguments(files, tmp_path, arguments, message):
    arguments = [
        str(files["ball.obj"]) if word == "TARGET" else word.replace("OUT", str(tmp_path / "out")) for word in arguments
    ]
    process = run_script(RETARGET, "--template", files["grid.obj"], "--target", files["ball.obj"], *arguments)
    assert process.returncode == 2, process.stderr[-3000:]
    assert message.replace("OUT", str(tmp_path / "out")) in process.stderr
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- batch


def batch(files, folder: Path, out: Path, *extra) -> subprocess.CompletedProcess:
    return run_script(
        RETARGET, *options(template=files["grid.obj"], batch=folder, output_dir=out, anchors_spacing=0), *extra
    )


def test_batch_meshes_whose_outputs_would_clash_are_refused_up_front(files, tmp_path):
    folder, out = tmp_path / "meshes", tmp_path / "out"
    folder.mkdir()
    for name in ("a.obj", "a.ply", "b.obj", "c.stl", "c.glb"):
        (folder / name).write_bytes(files["ball.obj"].read_bytes())
    failure = the_failure(batch(files, folder, out))
    assert failure == (
        f"retarget: FAILED: {folder}: meshes that differ only by their suffix would write the same outputs "
        "(OUT/<name>.blend, .obj, .json): a.obj, a.ply; c.glb, c.stl; rename or move one of each"
    )
    assert not out.exists()


def test_batch_output_folder_problems(files, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "a.obj").write_bytes(files["ball.obj"].read_bytes())
    (tmp_path / "taken").write_text("")
    assert (
        the_failure(batch(files, folder, tmp_path / "taken"))
        == f"retarget: FAILED: {tmp_path / 'taken'}: is a file; --output-dir names a folder"
    )
    same = batch(files, folder, folder)
    assert same.returncode == 2 and "--output-dir is the --batch folder" in same.stderr
    bad_template = run_script(
        RETARGET, *options(template=files["nan.obj"], batch=folder, output_dir=tmp_path / "out")
    )  # refused once, before any worker starts: not once per mesh
    assert the_failure(bad_template).startswith(f"retarget: FAILED: {files['nan.obj']}: {CASES['nan.obj']}")
    assert not (tmp_path / "out").exists() and sorted(path.name for path in folder.iterdir()) == ["a.obj"]


def test_a_mesh_that_now_fails_loses_the_outputs_of_an_earlier_run(files, tmp_path):
    """The summary says it failed: its .blend, .obj and report of the earlier run must not sit beside it."""
    folder, out = tmp_path / "meshes", tmp_path / "out"
    folder.mkdir()
    for name in ("ball_a.obj", "ball_b.obj"):
        (folder / name).write_bytes(files["ball.obj"].read_bytes())
    first = batch(files, folder, out)
    assert first.returncode == 0, first.stderr[-3000:]
    assert {path.name for path in out.iterdir()} >= {"ball_b.blend", "ball_b.obj", "ball_b.json"}
    kept = (out / "ball_a.obj").read_bytes()
    (folder / "ball_b.obj").write_bytes(files["nan.obj"].read_bytes())  # the scan was replaced by a broken one
    second = batch(files, folder, out)
    assert second.returncode == 3, second.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    [failed] = [entry for entry in summary["meshes"] if entry["status"] == "failed"]
    assert failed["target"] == str(folder / "ball_b.obj") and "NaN or infinite coordinate" in failed["error"]
    assert sorted(path.name for path in out.iterdir()) == ["ball_a.blend", "ball_a.json", "ball_a.obj", "summary.json"]
    assert (out / "ball_a.obj").read_bytes() == kept


# ---------------------------------------------------------------- mirror.py and wrap.py


def test_mirror_refuses_hostile_files_and_folder_outputs(files, tmp_path):
    out = tmp_path / "out"
    process = run_script(MIRROR, "--layout", files["nan.obj"], "--no-wrap", "--output-obj", out / "m.obj")
    assert the_failure(process, "mirror").startswith(f"mirror: FAILED: {files['nan.obj']}: {CASES['nan.obj']}")
    process = run_script(
        MIRROR, "--layout", files["grid.obj"], "--target", files["huge.ply"], "--output-obj", out / "m.obj"
    )
    failure = the_failure(process, "mirror")
    assert failure.startswith(f"mirror: FAILED: {files['huge.ply']}: ") and CASES["huge.ply"] in failure
    assert not out.exists()
    out.mkdir()
    (out / "m.json").mkdir()
    process = run_script(
        MIRROR, *options(layout=files["grid.obj"], no_wrap=True, output_obj=out / "m.obj", report=out / "m.json")
    )
    assert the_failure(process, "mirror") == f"mirror: FAILED: {out / 'm.json'}: is a folder; name the output file"
    assert [path.name for path in out.iterdir()] == ["m.json"]


@pytest.mark.parametrize("name", ["empty.blend", "garbage.blend", "missing.blend"])
def test_wrap_refuses_a_file_that_is_not_a_blend_before_blender_reads_it(files, name):
    path = files.get(name, files["grid.obj"].parent / name)
    process = run_script(WRAP, "--blend", path, "--layout", "Layout")
    expected = {"empty.blend": "the file is empty", "missing.blend": "no such file"}.get(name, "not a .blend file")
    assert the_failure(process, "wrap").startswith(f"wrap: FAILED: {path}: {expected}")


def test_wrap_refuses_a_folder_as_its_output_before_opening_the_file(tmp_path):
    (tmp_path / "taken.blend").mkdir()
    process = run_script(WRAP, "--blend", tmp_path / "scene.blend", "--output", tmp_path / "taken.blend")
    assert (
        the_failure(process, "wrap") == f"wrap: FAILED: {tmp_path / 'taken.blend'}: is a folder; name the output file"
    )
    wrong = run_script(WRAP, "--blend", tmp_path / "scene.blend", "--output", tmp_path / "scene.obj")
    assert wrong.returncode == 2 and "--output" in wrong.stderr and "must end with .blend" in wrong.stderr


def test_the_ply_header_that_aborted_blender_now_fails_cleanly_in_a_batch(files, tmp_path):
    """In a batch, the mesh is a failed entry (not a worker killed twice by an abort, exit 134)."""
    folder, out = tmp_path / "meshes", tmp_path / "out"
    folder.mkdir()
    (folder / "ball.obj").write_bytes(files["ball.obj"].read_bytes())
    (folder / "huge.ply").write_bytes(files["huge.ply"].read_bytes())
    process = batch(files, folder, out)
    assert process.returncode == 3, process.stderr[-3000:]
    entries = {Path(entry["target"]).name: entry for entry in json.loads((out / "summary.json").read_text())["meshes"]}
    assert entries["huge.ply"]["status"] == "failed" and entries["huge.ply"]["attempts"] == 1
    assert CASES["huge.ply"] in entries["huge.ply"]["error"] and entries["ball.obj"]["status"] == "ok"
    assert not [name for name in os.listdir(out) if name.startswith("huge")]


DETECT_FEATURES = REPOSITORY / "blender_scripts" / "detect_features.py"


@pytest.mark.parametrize(
    "script, arguments",
    [
        (RETARGET, ["--template", "GRID", "--target", "BALL", "--anchors-spacing", "nan"]),
        (RETARGET, ["--template", "GRID", "--target", "BALL", "--tolerance", "nan"]),
        (WRAP, ["--blend", "GRID", "--layout", "Layout", "--anchors-spacing", "nan"]),
        (MIRROR, ["--layout", "GRID", "--tolerance", "inf"]),
        (DETECT_FEATURES, ["--blend", "GRID", "--min-length", "nan"]),
    ],
    ids=["retarget --anchors-spacing", "retarget --tolerance", "wrap --anchors-spacing", "mirror", "detect_features"],
)
def test_a_number_option_that_is_not_finite_is_a_bad_argument(files, script, arguments):
    """Every number the command line takes follows the add-on's policy: NaN and infinity are refused as arguments
    (exit code 2, naming the option), never taken as "automatic" or "unlimited"."""
    names = {"GRID": str(files["grid.obj"]), "BALL": str(files["ball.obj"])}
    process = run_script(script, *[names.get(word, word) for word in arguments])
    assert process.returncode == 2, process.stderr[-3000:]
    assert f"{arguments[-2]}: must be a finite number, not {arguments[-1]}" in process.stderr
