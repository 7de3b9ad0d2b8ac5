"""What the headless scripts share (``blender_scripts/headless.py``): their arguments, the one-line failure,
outputs written all or nothing. Plain Python, no Blender."""

import argparse
import os
from pathlib import Path

import pytest

import headless


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["blender", "-b", "--python", "x.py", "--", "--layout", "L"], ["--layout", "L"]),
        (["/somewhere/x.py", "--layout", "L"], ["--layout", "L"]),
        (["blender", "-b", "--python", "x.py"], []),
    ],
)
def test_script_arguments(argv, expected):
    assert headless.script_arguments(argv, "blender_scripts/x.py") == expected


def test_outputs_are_written_all_or_nothing(tmp_path):
    first, second = tmp_path / "out" / "a.json", tmp_path / "out" / "b.json"

    def failing(_path):
        raise headless.ScriptError("no")

    with pytest.raises(headless.ScriptError):
        headless.write_all_or_nothing([(first, lambda path: path.write_text("a")), (second, failing)])
    assert not (tmp_path / "out").exists()  # nor the folder it created
    written = headless.write_all_or_nothing(
        [(first, lambda path: path.write_text("a")), (None, failing), (second, lambda path: path.write_text("b"))]
    )
    assert written == [first, second] and first.read_text() == "a" and second.read_text() == "b"
    with pytest.raises(headless.ScriptError, match="nothing was written"):
        headless.write_atomically(tmp_path / "c.json", lambda path: None)


def test_a_failure_is_one_line_and_exit_code_one(capsys):
    assert headless.failed("wrap", headless.ScriptError("no such file: x.blend")) == headless.EXIT_FAILED
    assert capsys.readouterr().err == "wrap: FAILED: no such file: x.blend\n"
    try:
        raise ValueError("bad")
    except ValueError as error:
        assert headless.failed("wrap", error) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback") and err.endswith("wrap: FAILED: ValueError: bad\n")


def test_a_failure_while_renaming_puts_every_earlier_file_back(tmp_path, monkeypatch):
    """The last rename fails (an output that became a folder): the outputs already renamed are removed, the
    files they replaced are back as they were, and no temporary file is left (Blender's ``FILE@`` neither)."""
    out = tmp_path / "out"
    out.mkdir()
    first, second = out / "r.blend", out / "r.obj"
    first.write_text("earlier run")

    def save(path: Path) -> None:  # as Blender saves: to FILE@, then renamed
        Path(f"{path}@").write_text("half")
        path.write_text("new blend")

    real_replace = os.replace

    def replace(source, destination):
        if Path(destination) == second.resolve():
            raise IsADirectoryError(21, "Is a directory", str(destination))
        real_replace(source, destination)

    monkeypatch.setattr(headless.os, "replace", replace)
    with pytest.raises(IsADirectoryError):
        headless.write_all_or_nothing([(first, save), (second, lambda path: path.write_text("v 0 0 0\n"))])
    assert sorted(path.name for path in out.iterdir()) == ["r.blend"]
    assert first.read_text() == "earlier run"


def test_outputs_are_checked_before_any_work(tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "a_file").write_text("")
    with pytest.raises(headless.ScriptError, match="is a folder; name the output file"):
        headless.check_output_paths([tmp_path / "ok.obj", tmp_path / "taken"])
    with pytest.raises(headless.ScriptError, match="is a file, not a folder"):
        headless.check_output_paths([tmp_path / "a_file" / "deeper" / "r.obj"])
    # Even root cannot create files in /proc, and the system's "No such file or directory" would mislead.
    with pytest.raises(headless.ScriptError, match="^/proc: not writable: no file can be created in this folder$"):
        headless.check_output_paths([Path("/proc/springwrap-test/r.obj")])
    headless.check_output_paths([tmp_path / "new" / "folders" / "r.obj", None])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a_file", "taken"]  # nothing created by checking


@pytest.mark.parametrize(
    "outputs, inputs, message",
    [
        ({"--output-obj": "r.ply"}, [], "must end with .obj"),
        ({"--output-blend": "r.obj"}, [], "must end with .blend"),
        ({"--output-obj": "r.obj", "--report": "r.obj"}, [], "name the same file"),
        ({"--output-obj": "t.obj"}, ["t.obj"], "would replace an input"),
    ],
)
def test_outputs_that_cannot_be_meant_are_bad_arguments(outputs, inputs, message, capsys):
    parser = argparse.ArgumentParser(prog="x.py")
    with pytest.raises(SystemExit) as exit_info:
        headless.check_output_arguments(parser, {key: Path(value) for key, value in outputs.items()}, map(Path, inputs))
    assert exit_info.value.code == headless.EXIT_USAGE and message in capsys.readouterr().err


def test_axes_are_read_in_either_spelling_and_must_differ(capsys):
    parser = argparse.ArgumentParser(prog="x.py")
    headless.add_frame_arguments(parser)
    arguments = parser.parse_args([])
    assert (arguments.up_axis, arguments.forward_axis) == ("Z", "Y")
    arguments = parser.parse_args(["--up-axis", "y", "--forward-axis=-Z"])
    assert (arguments.up_axis, arguments.forward_axis) == ("Y", "NEGATIVE_Z")
    assert headless.signed_axis(arguments.forward_axis) == "-Z"
    arguments = parser.parse_args(["--up-axis", "NEGATIVE_Y", "--forward-axis", "Y"])
    with pytest.raises(SystemExit):
        headless.check_frame_arguments(parser, arguments)
    assert "are the same axis" in capsys.readouterr().err
