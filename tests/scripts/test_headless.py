"""What the headless scripts share (``blender_scripts/headless.py``): their arguments, the one-line failure,
outputs written all or nothing. Plain Python, no Blender."""

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
    assert sorted(path.name for path in (tmp_path / "out").iterdir()) == []
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
