"""Mirror the surfaced half of a layout and wrap the new half onto the target's other half, headless.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python blender_scripts/mirror.py --layout L --target T --axis X [options]
    blender -b --python blender_scripts/mirror.py -- --layout L --target T --axis X [options]

Layout and target: a mesh file (.obj, .ply, .stl, .glb / .gltf) or a .blend with ``--layout-object`` /
``--target-object`` naming the object (without a name, the file's only mesh object). Mesh files are
checked and read in one convention as in ``retarget.py`` (``--up-axis`` / ``--forward-axis``); the
output OBJ and the plane in the report are in that frame. A layout from a
.blend keeps its Springwrap state (face-points, rest shape, anchors); ``--snap`` first snaps it onto
the target (a layout read from a mesh file is all space-points otherwise). The plane is the
layout's local ``--axis`` plane, or that plane of ``--mirror-object`` (an object of the layout's
.blend, e.g. an empty: its local YZ plane for X). Then ``springwrap.mirror`` runs with
``--weld-distance``, ``--seam SLIDE|HOLD``, ``--surfaced-half PIN|FREE``, ``--no-mirror-anchors``,
``--max-iterations``, ``--tolerance``, ``--shape-keys TRANSFER|REFUSE`` (a layout's shape keys mirrored onto
the new half and carried over the wrap, the default, or refused); ``--no-wrap`` only mirrors (no target
needed).

Outputs: ``--output-blend F.blend``, ``--output-obj F.obj`` (the mirrored layout alone) and
``--report F.json`` (counts, the seam's distance from the plane, faces crossing the plane, the wrap,
distances to the target, timings, warnings), checked before any work, each written to a temporary file
and all renamed at the end.

Exit codes (as ``retarget.py``): 0 done; 1 failed (one line ``mirror: FAILED: ...`` on stderr naming
the file and the problem, e.g. a plane that misses the layout; nothing is written); 2 bad arguments.
Faces crossing the plane and a wrap stopped at the iteration limit are warnings, not failures.
"""

import argparse
import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import (
    EXIT_OK,
    ScriptError,
    add_frame_arguments,
    add_shape_keys_argument,
    addon_module,
    check_frame_arguments,
    check_output_arguments,
    check_output_paths,
    failed,
    finite_number,
    script_arguments,
    shape_keys_report,
)
from scene_io import (
    Laps,
    add_wrap_options,
    distances_to_target,
    frame_matrix,
    load_mesh,
    run_operator,
    wrap_defaults_module,
    write_outputs,
)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's own arguments (see the module docstring); exits with code 2 when they are wrong."""
    parser = argparse.ArgumentParser(prog="mirror.py", description=__doc__.splitlines()[0])
    parser.add_argument("--layout", type=Path, required=True, help="the layout: mesh file or .blend")
    parser.add_argument("--layout-object", help="the layout's object in a .blend")
    parser.add_argument("--target", type=Path, help="the target: mesh file or .blend (not needed with --no-wrap)")
    parser.add_argument("--target-object", help="the target's object in a .blend")
    parser.add_argument("--axis", choices=("X", "Y", "Z"), default="X", help="the mirror plane's axis (default X)")
    parser.add_argument("--mirror-object", help="an object of the layout's .blend whose local plane is the mirror")
    parser.add_argument(
        "--weld-distance",
        type=finite_number,
        default=wrap_defaults_module().WELD_FRACTION,
        help="seam: vertices this close to the plane, fraction of their edge length (default %(default)s)",
    )
    parser.add_argument("--seam", choices=("SLIDE", "HOLD"), default="SLIDE", help="seam during the wrap")
    parser.add_argument(
        "--surfaced-half",
        choices=("PIN", "FREE"),
        default="PIN",
        help="the half that was there: pinned (default) or wrapped too",
    )
    parser.add_argument("--no-mirror-anchors", action="store_true", help="do not mirror the anchors")
    parser.add_argument("--no-wrap", action="store_true", help="only mirror")
    parser.add_argument("--snap", action="store_true", help="snap the layout onto the target first")
    add_wrap_options(parser, weights=False)
    add_shape_keys_argument(parser)
    add_frame_arguments(parser)
    parser.add_argument("--output-blend", type=Path, help="save layout, target and result here")
    parser.add_argument("--output-obj", type=Path, help="export the mirrored layout here")
    parser.add_argument("--report", type=Path, help="write the JSON report here")
    arguments = parser.parse_args(script_arguments(argv, __file__))
    check_frame_arguments(parser, arguments)
    check_output_arguments(
        parser,
        {"--output-blend": arguments.output_blend, "--output-obj": arguments.output_obj, "--report": arguments.report},
        [arguments.layout, arguments.target],
    )
    if arguments.max_iterations < 1:
        parser.error("--max-iterations must be at least 1")
    try:
        wrap_defaults_module().wrap_defaults().replace(tolerance=arguments.tolerance)
    except ValueError as error:  # springwrap_kernel.InvalidArgumentError
        parser.error(str(error))
    if not arguments.weld_distance > 0:
        parser.error("--weld-distance must be positive")
    if arguments.target is None and not arguments.no_wrap:
        parser.error("--target is needed unless --no-wrap")
    if arguments.snap and arguments.target is None:
        parser.error("--snap needs --target")
    if arguments.mirror_object and arguments.layout.suffix.lower() != ".blend":
        parser.error("--mirror-object names an object of the layout's .blend")
    return arguments


def _load_mirror_object(path: Path, name: str) -> str:
    """Link the object ``name`` of the .blend ``path`` into the scene; its name there."""
    with bpy.data.libraries.load(str(path), link=False) as (source, loaded):
        if name not in source.objects:
            raise ScriptError(f"{path}: no object '{name}' to mirror across")
        loaded.objects = [name]
    mirror = loaded.objects[0]
    bpy.context.scene.collection.objects.link(mirror)
    return mirror.name


def mirror(arguments: argparse.Namespace) -> dict:
    """Load, (snap,) mirror and wrap, measure, write; the report (also written to --report)."""
    from mathutils import Vector

    lap, warnings = Laps(), []
    timings = lap.timings

    check_output_paths([arguments.output_blend, arguments.output_obj, arguments.report])  # before any work
    SPRINGWRAP_OT_mirror = addon_module("operators.mirror").SPRINGWRAP_OT_mirror  # noqa: N806
    bpy.ops.wm.read_homefile(use_empty=True)
    frame = frame_matrix(arguments.up_axis, arguments.forward_axis)
    to_files = frame.inverted().to_3x3()
    layout = load_mesh(arguments.layout, arguments.layout_object, "Layout", frame)
    target = load_mesh(arguments.target, arguments.target_object, "Target", frame) if arguments.target else None
    mirror_object = _load_mirror_object(arguments.layout, arguments.mirror_object) if arguments.mirror_object else ""
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    layout.springwrap.target = target
    lap("load")
    blame = f"layout {arguments.layout}" + (f", target {arguments.target}" if arguments.target else "")
    if arguments.snap:
        run_operator(blame, "snap")
        lap("snap")
    run_operator(
        blame,
        "mirror",
        axis=arguments.axis,
        mirror_object=mirror_object,
        weld_distance=arguments.weld_distance,
        wrap=not arguments.no_wrap,
        seam=arguments.seam,
        surfaced_half=arguments.surfaced_half,
        mirror_anchors=not arguments.no_mirror_anchors,
        max_iterations=arguments.max_iterations,
        tolerance=arguments.tolerance,
        shape_keys=arguments.shape_keys,
    )
    outcome = SPRINGWRAP_OT_mirror.last_outcome
    lap("mirror and wrap")
    if outcome.crossing_faces.size:
        warnings.append(
            f"{outcome.crossing_faces.size} faces cross the mirror plane (their mirror overlaps them): "
            f"faces {outcome.crossing_faces[:20].tolist()}"
        )
    wrap = None
    if outcome.wrap is not None:
        wrap = {
            "iterations": outcome.wrap.iterations,
            "converged": outcome.wrap.converged,
            "face_points": outcome.wrap.face_points,
            "space_points": outcome.wrap.space_points,
            "kernel_seconds": round(outcome.wrap.kernel_seconds, 4),
        }
        if not outcome.wrap.converged:
            warnings.append(
                f"the wrap did not converge within {arguments.max_iterations} iterations; the result is kept"
            )
        if outcome.wrap.space_points:
            warnings.append(f"{outcome.wrap.space_points} of {outcome.vertices} vertices are off the surface")
    report = {
        "layout": str(arguments.layout),
        "target": str(arguments.target) if arguments.target else None,
        "plane": {
            "axis": arguments.axis,
            "object": outcome.plane_owner,
            "point": list(to_files @ Vector(outcome.plane.point.tolist())),  # in the files' frame
            "normal": list(to_files @ Vector(outcome.plane.normal.tolist())),
        },
        "frame": {"up_axis": arguments.up_axis, "forward_axis": arguments.forward_axis},
        "vertices_before": outcome.original_vertices,
        "vertices": outcome.vertices,
        "new_vertices": outcome.copies,
        "seam_vertices": outcome.seam_vertices,
        "seam_max_distance_to_plane": outcome.seam_max_distance,
        "crossing_faces": outcome.crossing_faces.tolist(),
        "anchors_mirrored": outcome.mirrored_anchors,
        "anchors_dropped": outcome.dropped_anchors,
        "wrap": wrap,
        "shape_keys": shape_keys_report(layout, arguments.shape_keys),
        "metrics": distances_to_target(layout, target) if target is not None else None,
        "quality": quality_block(layout) if target is not None else None,
        "timings": timings,
        "warnings": warnings,
        "blender": bpy.app.version_string,
    }
    lap("metrics")
    write_outputs(arguments, layout, report)
    return report


def quality_block(layout) -> dict | None:
    """The report's ``quality`` block: the read-out the mirror wrote (``core.quality.summary``); None without a
    target (nothing to measure against)."""
    readout = addon_module("blender.quality").read_readout(layout)
    return None if readout is None else addon_module("blender.parts").readout_summary(layout, readout)


def main() -> int:
    try:
        arguments = parse_arguments(sys.argv)  # reads the kernel's defaults: ScriptError without the add-on
        report = mirror(arguments)
    except Exception as error:  # noqa: BLE001 - any failure must become a non-zero exit code, also under `blender -b`
        return failed("mirror", error)
    wrap = report["wrap"]
    print(
        f"mirror: {report['vertices']} vertices ({report['new_vertices']} new, {report['seam_vertices']} on the seam)"
        + (f", wrapped in {wrap['iterations']} iterations" if wrap else "")
        + "".join(f"\n  warning: {line}" for line in report["warnings"])
    )
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
