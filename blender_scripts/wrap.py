"""Wrap a layout onto its target, headless: open a .blend, (optionally) spread anchors, wrap, save.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python blender_scripts/wrap.py --blend FILE.blend --layout NAME [options]
    blender -b FILE.blend --python blender_scripts/wrap.py -- --layout NAME [options]

Options: ``--target NAME`` (default: the layout's own target), ``--anchors-spacing S`` (run
``springwrap.anchors_auto`` first, replacing the anchors; 0 = a tenth of the layout's size),
``--max-iterations N`` (default the add-on's ``core.defaults.MAX_ITERATIONS``), ``--shape-keys TRANSFER|REFUSE`` (a layout with shape keys: its
basis wrapped and the other keys carried over, the default, or refused), ``--output FILE.blend``
(default: nothing is saved).
Prints the wrap's progress and a summary; exits non-zero on any failure (a wrap that stops at
the iteration limit is not a failure: it is kept and reported).
"""

import argparse
import sys
import time
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import (
    ScriptError,
    add_shape_keys_argument,
    addon_module,
    check_output_arguments,
    check_output_paths,
    finite_number,
    script_arguments,
    script_main,
    write_atomically,
)
from scene_io import find_mesh, open_blend, wrap_defaults_module

PROGRESS_CHUNK = 100
"""Iterations between two progress lines."""


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's own arguments (see the module docstring)."""
    parser = argparse.ArgumentParser(prog="wrap.py", description=__doc__.splitlines()[0])
    parser.add_argument("--blend", type=Path, help="the .blend to open (not needed under `blender -b FILE.blend`)")
    parser.add_argument("--layout", help="the layout object (default: the active object)")
    parser.add_argument("--target", help="the target object (default: the layout's own target)")
    parser.add_argument(
        "--anchors-spacing", type=finite_number, help="spread anchors with this spacing first (0: automatic)"
    )
    parser.add_argument(
        "--max-iterations",
        type=int,
        default=wrap_defaults_module().MAX_ITERATIONS,
        help="iteration limit (default %(default)s)",
    )
    add_shape_keys_argument(parser)
    parser.add_argument("--output", type=Path, help="the .blend to save the result to")
    arguments = parser.parse_args(script_arguments(argv, __file__))
    check_output_arguments(parser, {"--output": arguments.output}, [])
    if arguments.max_iterations < 1:
        parser.error("--max-iterations must be at least 1")
    if arguments.anchors_spacing is not None and arguments.anchors_spacing < 0:
        parser.error("--anchors-spacing must not be negative")
    return arguments


def prepare(arguments: argparse.Namespace) -> bpy.types.Object:
    """Open the file, pick the layout and its target, make the layout active (object mode)."""
    open_blend(arguments.blend)
    if arguments.layout is not None:
        layout = find_mesh(arguments.layout, "layout")
    else:
        layout = bpy.context.view_layer.objects.active
        if layout is None or layout.type != "MESH":
            raise ScriptError("no --layout given and the active object is not a mesh")
    if layout.mode != "OBJECT":
        bpy.context.view_layer.objects.active = layout
        bpy.ops.object.mode_set(mode="OBJECT")
    if arguments.target is not None:
        layout.springwrap.target = find_mesh(arguments.target, "target")
    if layout.springwrap.target is None:
        raise ScriptError(f"layout '{layout.name}' has no target: give --target")
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    return layout


def wrap(layout: bpy.types.Object, max_iterations: int, shape_keys: str = "TRANSFER"):
    """Run the wrap to the end with progress lines, then write it; returns the ``WrapResult``."""
    WrapSession = addon_module("blender.wrap_session").WrapSession  # noqa: N806
    ERRORS = addon_module("core.errors").ERRORS  # noqa: N806
    WrapParameters = addon_module("core.wrap_inputs").WrapParameters  # noqa: N806

    def progress(report) -> None:
        print(
            f"  iteration {report.total_iterations:>6}/{max_iterations}: {report.face_points} face-points, "
            f"{report.space_points} space-points, last move {report.max_displacement:.2e}",
            flush=True,
        )

    try:
        session = WrapSession(bpy.context, layout, WrapParameters(max_iterations=max_iterations), shape_keys=shape_keys)
    except ERRORS as error:
        raise ScriptError(f"cannot wrap '{layout.name}': {error}") from error
    session.run(progress=progress, chunk=PROGRESS_CHUNK)
    return session.finish()


def run(arguments: argparse.Namespace) -> None:
    """Everything: prepare, anchors, wrap, report, save."""
    start = time.perf_counter()
    check_output_paths([arguments.output])  # before any work
    layout = prepare(arguments)
    target = layout.springwrap.target
    print(
        f"layout '{layout.name}': {len(layout.data.vertices)} vertices, {len(layout.data.polygons)} faces; "
        f"target '{target.name}'"
    )
    if arguments.anchors_spacing is not None:
        result = bpy.ops.springwrap.anchors_auto(spacing=arguments.anchors_spacing, replace=True)
        if result != {"FINISHED"}:
            raise ScriptError(f"anchors_auto returned {result}")
    print(f"anchors: {len(layout.springwrap.anchors)}")
    result = wrap(layout, arguments.max_iterations, arguments.shape_keys)
    print(result.summary())
    if layout.data.shape_keys is not None:
        names = ", ".join(block.name for block in layout.data.shape_keys.key_blocks)
        print(f"shape keys carried over onto the wrapped basis: {names}")
    print(
        f"  kernel {result.kernel_seconds:.2f} s; {result.anchor_count} anchors, "
        f"{result.unreliable_triangles} unreliable target triangles"
    )
    print(f"  {addon_module('core.quality').report_line(result.readout)}")  # in the saved .blend's attributes too
    if not result.converged:
        print(
            f"WARNING: did not converge within {arguments.max_iterations} iterations "
            f"(last move {result.max_displacement:.2e} of the layout's size); the result is kept"
        )
    if arguments.output is not None:

        def save(path: Path) -> None:
            if bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, copy=True) != {"FINISHED"}:
                raise ScriptError(f"{arguments.output}: could not save")

        print(f"saved {write_atomically(arguments.output, save)}")
    else:
        print("not saved (no --output)")
    print(f"done in {time.perf_counter() - start:.1f} s")


def main() -> int:
    return script_main("wrap", parse_arguments, run)


if __name__ == "__main__":
    sys.exit(main())
