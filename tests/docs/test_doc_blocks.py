"""Every shell and Python block of README.md and docs/user-guide.md runs as written: docs that drift from the
code fail here.

Each ```` ```sh ````, ```` ```bash ```` and ```` ```python ```` block is a test case, run in one work folder
holding the files the examples name (``tests/docs/docs_scene.py``: ``scan.blend`` with ``Layout`` and
``Scan``, ``layout.obj``, ``scan.ply``, ``scans/``, ``half.blend``, ``head.obj``), ``.venv`` and
``blender_scripts`` linked to the repository's, and ``dist/`` with the Linux packages. Python blocks run
in a fresh process of the venv's Python (the ``bpy`` module) after ``scan.blend`` is opened; shell blocks
in ``bash -e``, with Blender's user folders inside the work folder (an install there touches nothing of
yours). A block fails on a non-zero exit. ```` ```text ```` blocks are a program's output, not run.

A marker, an HTML comment on the line just before the opening fence, changes that (they are listed at the
top of docs/user-guide.md and in docs/architecture.md, *The docs test*):

- ``<!-- docs-test: skip REASON -->``: not run; REASON (required) says why, and what runs it instead;
- ``<!-- docs-test: continues -->``: a Python block run after the previous Python block of the same file,
  in its process (a snippet that goes on from the one before);
- ``<!-- docs-test: needs blender -->``: run only when a ``blender`` binary is on PATH (skipped otherwise).

About 40 s in all on 2 shared cores (most of it the retarget batch's two workers and the Blender binary's demo).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

import build_packages
from helpers import REPOSITORY

DOCUMENTS = (REPOSITORY / "README.md", REPOSITORY / "docs" / "user-guide.md")
RUN_LANGUAGES = {"sh": "shell", "bash": "shell", "python": "python"}
OUTPUT_LANGUAGES = {"text"}
MARKER = re.compile(r"^<!-- docs-test: (?P<kind>skip|continues|needs blender)(?: (?P<reason>.*?))? -->$")
FENCE = re.compile(r"^(?P<indent> *)```(?P<language>[\w-]*)\s*$")
TIMEOUT_SECONDS = 300


class Block(NamedTuple):
    document: Path
    line: int  # of the opening fence, 1-based
    language: str
    code: str
    marker: str | None  # skip, continues, needs blender
    reason: str | None

    @property
    def name(self) -> str:
        return f"{self.document.relative_to(REPOSITORY)}:{self.line}"


def blocks_of(document: Path) -> list[Block]:
    """The fenced blocks of ``document``, each with the marker on the line before it."""
    lines = document.read_text(encoding="utf-8").splitlines()
    found, index = [], 0
    while index < len(lines):
        fence = FENCE.match(lines[index])
        if fence is None:
            index += 1
            continue
        end = index + 1
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        indent = len(fence["indent"])
        code = "\n".join(line[indent:] for line in lines[index + 1 : end]) + "\n"
        marker = MARKER.match(lines[index - 1].strip()) if index else None
        found.append(
            Block(
                document,
                index + 1,
                fence["language"],
                code,
                marker["kind"] if marker else None,
                marker["reason"] if marker else None,
            )
        )
        index = end + 1
    return found


ALL_BLOCKS = [block for document in DOCUMENTS for block in blocks_of(document)]
RUN_BLOCKS = [block for block in ALL_BLOCKS if block.language in RUN_LANGUAGES]


def test_every_block_is_run_or_says_why_not():
    """A block's language is one this test runs or output (text); a skip gives its reason; markers are known."""
    for block in ALL_BLOCKS:
        assert block.language in RUN_LANGUAGES or block.language in OUTPUT_LANGUAGES, (
            f"{block.name}: a ``` block needs a language: sh or python (run here) or text (output)"
        )
        if block.marker == "skip":
            assert block.reason and len(block.reason) > 15, f"{block.name}: a skip marker must say why"
        if block.marker == "continues":
            assert block.language == "python", f"{block.name}: only a Python block continues the one before"
    for document in DOCUMENTS:
        for number, line in enumerate(document.read_text(encoding="utf-8").splitlines(), 1):
            if "docs-test:" in line and line.strip().startswith("<!--") and "`" not in line:
                assert MARKER.match(line.strip()), f"{document.name}:{number}: unknown marker {line.strip()!r}"
    assert len(RUN_BLOCKS) >= 10  # the parser found the blocks


@pytest.fixture(scope="session")
def work(tmp_path_factory) -> Path:
    """The folder every block runs in: the example files, the venv, the scripts and the Linux packages."""
    folder = tmp_path_factory.mktemp("docs-work")
    made = subprocess.run(
        [sys.executable, str(REPOSITORY / "tests" / "docs" / "docs_scene.py"), str(folder)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
    )
    assert made.returncode == 0, made.stdout[-3000:] + made.stderr[-3000:]
    (folder / ".venv").symlink_to(REPOSITORY / ".venv")
    (folder / "blender_scripts").symlink_to(REPOSITORY / "blender_scripts")
    build_packages.build(REPOSITORY / "target" / "wheels", folder / "dist")
    for user in ("user-resources", "user-scripts/addons"):
        (folder / user).mkdir(parents=True)
    return folder


def python_program(block: Block) -> str:
    """The block's program: ``scan.blend`` opened first, and the blocks it continues before it."""
    blocks = [block]
    while blocks[0].marker == "continues":
        earlier = [other for other in RUN_BLOCKS if other.document == block.document and other.line < blocks[0].line]
        earlier = [other for other in earlier if other.language == "python"]
        assert earlier, f"{block.name}: continues, but no Python block comes before it"
        blocks.insert(0, earlier[-1])
    opening = 'import bpy\nbpy.ops.wm.open_mainfile(filepath="scan.blend")\n'
    return opening + "".join(part.code for part in blocks)


@pytest.mark.parametrize("block", RUN_BLOCKS, ids=[block.name for block in RUN_BLOCKS])
def test_the_block_runs_as_written(block, work):
    if block.marker == "skip":
        pytest.skip(f"not run: {block.reason}")
    if block.marker == "needs blender" and shutil.which("blender") is None:
        pytest.skip("needs a `blender` binary on PATH")
    environment = {
        **os.environ,
        "BLENDER_USER_RESOURCES": str(work / "user-resources"),
        "BLENDER_USER_SCRIPTS": str(work / "user-scripts"),
    }
    if RUN_LANGUAGES[block.language] == "python":
        command = [sys.executable, "-c", python_program(block)]
    else:
        command = ["bash", "-e", "-o", "pipefail", "-c", block.code]
    process = subprocess.run(
        command, cwd=work, env=environment, capture_output=True, text=True, timeout=TIMEOUT_SECONDS
    )
    output = process.stdout[-3000:] + process.stderr[-3000:]
    assert process.returncode == 0, f"{block.name} exited with {process.returncode}:\n{block.code}\n{output}"
    assert "Traceback (most recent call last)" not in process.stderr, output
