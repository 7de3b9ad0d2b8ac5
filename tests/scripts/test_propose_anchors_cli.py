"""``retarget.py --propose-anchors``, end to end in its own processes: from three anchors on a bumpy ball's tips,
further pairs are proposed and accepted before the wrap (counted in the report); with too few anchors the run
fails with one line saying so and writes nothing.

Inputs are generated: a coarse bumpy ball as the template, a finer one stretched as the target (OBJ text).
"""

import functools
import json

import pytest

from helpers import REPOSITORY, ball_landmarks, ball_stretch, bumpy_ball, obj_text, run_script

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"
run = functools.partial(run_script, RETARGET)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("propose_inputs")
    rest, faces = bumpy_ball(60, 90)
    fine, fine_faces = bumpy_ball(110, 170)
    paths = {"template": folder / "ball.obj", "target": folder / "stretched.obj"}
    paths["template"].write_text(obj_text(rest * 1.05 + [0.1, -0.2, 0.05], faces))
    paths["target"].write_text(obj_text(ball_stretch(fine), fine_faces))
    truth = ball_stretch(rest)
    for count in (2, 3):
        marks = ball_landmarks(rest, count).tolist()
        pairs = [{"vertex": vertex, "target": truth[vertex].tolist()} for vertex in marks]
        paths[count] = folder / f"anchors{count}.json"
        paths[count].write_text(json.dumps({"anchors": pairs}))
    return paths


def test_proposed_pairs_are_accepted_before_the_wrap(inputs, tmp_path):
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors", inputs[3],
        "--propose-anchors", "--report", tmp_path / "r.json", "--output-obj", tmp_path / "r.obj",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["proposed_anchors"] >= 1
    assert report["anchors"] == 3 + report["proposed_anchors"]


def test_without_the_flag_nothing_is_proposed(inputs, tmp_path):
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors", inputs[3],
        "--report", tmp_path / "r.json",
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["proposed_anchors"] == 0 and report["anchors"] == 3


def test_too_few_anchors_fail_in_one_line_and_write_nothing(inputs, tmp_path):
    process = run(
        "--template", inputs["template"], "--target", inputs["target"], "--anchors", inputs[2],
        "--propose-anchors", "--report", tmp_path / "r.json",
    )  # fmt: skip
    assert process.returncode != 0
    assert "at least 3 anchors" in process.stderr
    assert not (tmp_path / "r.json").exists()


def test_a_batch_proposes_for_every_mesh(inputs, tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "stretched.obj").write_text(inputs["target"].read_text())
    out = tmp_path / "out"
    process = run(
        "--template", inputs["template"], "--batch", folder, "--output-dir", out, "--anchors", inputs[3],
        "--propose-anchors", "--jobs", 1,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr[-3000:]
    report = json.loads((out / "stretched.json").read_text())
    assert report["proposed_anchors"] >= 1 and report["anchors"] == 3 + report["proposed_anchors"]
