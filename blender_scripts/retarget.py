"""Retarget a template layout onto a target mesh (or every mesh of a folder), headless.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python blender_scripts/retarget.py --template T --target M [options]
    blender -b --python blender_scripts/retarget.py -- --template T --target M [options]

Template and target: a mesh file (.obj, .ply, .stl, .glb / .gltf) or a .blend with ``--template-object`` /
``--target-object`` naming the object (without a name, the file's only mesh object). Mesh files are checked
before Blender's importers read them (``mesh_files.py``: empty, truncated, garbage, counts the file cannot
hold, indices out of range, NaN or absurd coordinates) and read in one convention, ``--up-axis`` /
``--forward-axis`` (default Z up, Y forward: the coordinates as written), whatever their format; the
anchors file and the output OBJ are in that frame too (a .blend is in Blender's own frame). Steps: the
template is copied as the layout, aligned to the target (``--align bounds``: its bounding box's
centre and diagonal onto the target's; ``icp``: that, then ``springwrap.align`` by ICP alone;
``anchors``: ``springwrap.align`` fitted to the ``--anchors`` file's pairs, then ICP;
``--align-method`` picks rigid, similarity or affine; ``none``, the default: as placed), detached, anchored (``--anchors FILE.json``:
``{"anchors": [{"vertex": 12, "target": [x, y, z]}, ...]}``, each layout vertex pulled to the target
surface point closest to that point of the files' frame; or ``--anchors-spacing S``, spread automatically;
0 = a tenth of the layout's size; ``--propose-anchors``: then further pairs proposed from them and all accepted;
``--symmetric-anchors X|Y|Z``: each anchor, from the file or spread, with its
twin across the layout's local plane of that axis, spread on one side and mirrored), then wrapped (``--max-iterations``, ``--fairness``,
``--arc-length``, ``--thin-plate``, ``--tolerance``). A template with shape keys (a .blend's object, or a
glTF's morph targets) has its basis wrapped and every other key carried over onto it (``--shape-keys
TRANSFER``, the default; ``REFUSE`` fails on such a template); ``--fit-subdivision`` refuses one.
``--sequence START END`` wraps at every frame of the target's animation instead (a .blend target: armature,
shape keys, modifiers, a Mesh Sequence Cache), each frame from the previous one's result, as one keyed shape key
per frame on the layout; the report's ``sequence`` block lists each frame's time and any frame that failed.
``--point-cache F.abc`` (or ``.usd``, ``.usdc``, ``.usda``) also writes those frames as an Alembic or USD
point cache (``springwrap.export_sequence``).

Outputs: ``--output-blend F.blend`` (template, target and the retargeted layout), ``--output-obj
F.obj`` (the retargeted layout alone) and ``--report F.json`` (metrics, timings, warnings). They are
checked before any work (not a folder, in a folder that can be written), each written to a temporary file
and all renamed at the end: a failing run leaves none of them behind, and the files they would replace
as they were.

Batch: ``--batch DIR --output-dir OUT [--jobs N]`` retargets the template onto every mesh file in
DIR (sorted), writing ``OUT/<name>.blend``, ``OUT/<name>.obj``, ``OUT/<name>.json`` and
``OUT/summary.json``; meshes whose names differ only by their suffix (``a.obj``, ``a.ply``) are refused
before anything runs, and a mesh that fails loses the outputs an earlier run wrote for it. N workers
(``--executor local``, the default: processes on this machine;
``--executor ray [--address ADDR]``: Ray actors, on a Ray instance started here or on a cluster;
see retarget_batch.py) each import bpy and enable the add-on once, then serve many meshes with one
task function (``retarget_task``). A mesh that fails is reported and skipped, never the whole batch;
one whose worker dies is retried once on a fresh worker. Progress goes to stderr (a bar with an ETA
in a terminal, one line per mesh otherwise); ``--resume`` skips the meshes whose outputs are all
there and were made from the same template, anchors and target files and the same settings (each report
carries their fingerprint), and makes the others again; Ctrl-C stops the workers and writes a summary listing the meshes not run.

Exit codes: 0 done; 1 the retarget failed (a one-line ``retarget: FAILED: ...`` on stderr names
the file and the problem: a missing or unreadable file, bad anchors, a wrap that cannot start), or
a batch could not run (no worker could start, no ray package); 2 bad command-line arguments; 3 a
batch in which at least one mesh failed (the others are written); 130 a batch stopped by Ctrl-C.
A wrap that stops at the iteration limit is not a failure: it is kept and warned about in the report.
(``--batch-worker`` is internal: a local batch's worker process.)
"""

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import (
    EXIT_BATCH_FAILURES,
    EXIT_INTERRUPTED,
    EXIT_OK,
    ScriptError,
    add_frame_arguments,
    add_shape_keys_argument,
    addon_module,
    check_frame_arguments,
    check_output_arguments,
    check_output_folder,
    check_output_paths,
    enable_addon,
    failed,
    finite_number,
    partial_path,
    script_arguments,
    shape_keys_report,
    write_atomically,
)
from mesh_files import check_blend_file, check_mesh_file
from scene_io import (
    INPUT_SUFFIXES,
    Laps,
    add_wrap_options,
    distances_to_target,
    frame_matrix,
    load_mesh,
    run_operator,
    to_file_frame,
    world_vertices,
    wrap_defaults_module,
    write_outputs,
)

if TYPE_CHECKING:
    from mathutils import Matrix

OUTPUT_SUFFIXES = ("blend", "obj", "json")  # a batch's outputs per mesh: OUT/<name>.<suffix>
WORKER_FLAG = "--batch-worker"
TASK_ENTRY_POINT = "retarget:retarget_task"  # what a Ray worker runs, imported there by name
SCRIPTS_FOLDER = Path(__file__).resolve().parent
LAYOUT_NAME = "Retargeted"


def wrap_settings(arguments: argparse.Namespace):
    """The ``springwrap_kernel.WrapSettings`` of --tolerance, --fairness, --arc-length, --thin-plate, --constraint,
    --folding and --schedule (checked by the kernel: ``springwrap_kernel.InvalidArgumentError`` names a value out of
    its range)."""
    return (
        wrap_defaults_module()
        .wrap_defaults()
        .replace(
            tolerance=arguments.tolerance,
            fairness=arguments.fairness,
            arc_length=arguments.arc_length,
            thin_plate=arguments.thin_plate,
            constraint=arguments.constraint,
            folding=arguments.folding,
            schedule=arguments.schedule.upper().replace("-", "_"),
        )
    )


def point_cache_format(path: Path) -> str | None:
    """The point-cache format a file name asks for by its suffix (``blender.point_cache.FORMATS``), None for
    another suffix."""
    formats = addon_module("blender.point_cache").FORMATS
    suffix = Path(path).suffix.lower()
    return next((name for name, suffixes in formats.items() if suffix in suffixes), None)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's own arguments (see the module docstring); exits with code 2 when they are wrong."""
    defaults = wrap_defaults_module().wrap_defaults()
    parser = argparse.ArgumentParser(prog="retarget.py", description=__doc__.splitlines()[0])
    parser.add_argument("--template", type=Path, required=True, help="the template layout: mesh file or .blend")
    parser.add_argument("--template-object", help="the template's object in a .blend")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--target", type=Path, help="the target: mesh file or .blend")
    source.add_argument("--batch", type=Path, help="retarget onto every mesh file of this folder")
    parser.add_argument("--target-object", help="the target's object in a .blend")
    anchors = parser.add_mutually_exclusive_group()
    anchors.add_argument("--anchors", type=Path, help="JSON file of layout-vertex -> target-point pairs")
    anchors.add_argument(
        "--anchors-spacing", type=finite_number, help="spread anchors automatically (0: automatic spacing)"
    )
    parser.add_argument(
        "--symmetric-anchors",
        choices=("X", "Y", "Z"),
        help="anchors in symmetric pairs across the template's local plane perpendicular to this axis (in "
        "Blender's frame): each anchor also anchors its twin vertex (by topology, else by position) to the target "
        "point closest to its reflected target point; automatic ones are spread on one side and mirrored",
    )
    parser.add_argument(
        "--propose-anchors",
        action="store_true",
        help="after anchoring, propose further pairs where both shapes agree (tips and pits; springwrap."
        "anchors_propose) and accept them all; needs at least 3 anchors",
    )
    parser.add_argument(
        "--align",
        choices=("none", "bounds", "icp", "anchors"),
        default="none",
        help="alignment: none, bounds (box centre and size), icp (bounds, then ICP), "
        "anchors (fit to --anchors, then ICP) (default none)",
    )
    parser.add_argument(
        "--align-method",
        choices=("rigid", "similarity", "affine"),
        default="similarity",
        help="transform of --align icp / anchors (default similarity; ICP alone: rigid or similarity)",
    )
    add_wrap_options(parser, weights=True)
    parser.add_argument(
        "--solver",
        choices=("energy", "springs"),
        default="energy",
        help="retired: the wrap has one solver, the energy solver; 'springs' wraps with it and warns",
    )
    parser.add_argument(
        "--schedule",
        choices=("auto", "local", "global-to-local"),
        default=defaults.schedule.lower().replace("_", "-"),
        help="the wrap's stiffness schedule: local, or stiff nearly affine levels first, for a few anchors "
        "on a large change of shape; auto chooses from the anchors (default %(default)s)",
    )
    parser.add_argument(
        "--stiffness-group",
        default="",
        help="the template's vertex group of per-vertex stiffness (weight 0 "
        "follows the target freely, 0.5 as the others, 1 keeps the template's shape)",
    )
    parser.add_argument(
        "--free-group",
        default="",
        help="the template's vertex group with no pull toward the target "
        "(sockets, teeth: they follow their neighbours and stay off the surface)",
    )
    parser.add_argument(
        "--follow-group",
        default="",
        help="the template's vertex group of parts (eyeballs, teeth): never pulled onto the target, each piece moved "
        "rigidly with the surface around it",
    )
    parser.add_argument(
        "--follow-soft-group",
        default="",
        help="the template's vertex group of soft parts (lashes): each vertex follows the surface around it",
    )
    parser.add_argument(
        "--surface-group",
        default="",
        help="the template's vertex group whose pieces are wrapped like the body, whatever the parts' guess",
    )
    parser.add_argument(
        "--no-find-parts",
        action="store_true",
        help="do not guess which separate pieces the target lacks (only the Follow groups' vertices are parts)",
    )
    parser.add_argument(
        "--fit-subdivision",
        type=int,
        metavar="LEVELS",
        help="after the wrap, fit the layout as a subdivision cage: its Subdivision Surface at LEVELS (1 to 6) "
        "onto the target (the report gains the surface's distances before and after)",
    )
    parser.add_argument(
        "--feature-lines",
        action="store_true",
        help="after the wrap, pair the template's feature lines (sharp edges, creases, open borders) with the "
        "target's ridges, valleys and hole borders as curve constraints, and wrap again (the report lists them)",
    )
    add_shape_keys_argument(parser)
    parser.add_argument(
        "--sequence",
        nargs=2,
        type=int,
        metavar=("START", "END"),
        help="wrap at every frame START..END of the target's animation (a .blend target: armature, shape keys, "
        "modifiers, a Mesh Sequence Cache), each frame from the previous one's result, one shape key per frame on "
        "the layout, keyed (--output-blend keeps them; the OBJ and the metrics are the first frame's)",
    )
    parser.add_argument(
        "--point-cache",
        type=Path,
        help="with --sequence: also write the layout's frames as a point cache here (springwrap.export_sequence: "
        "Blender's own exporter, one sample of the vertex positions per frame), Alembic for .abc, USD for .usd, "
        ".usdc or .usda",
    )
    add_frame_arguments(parser)
    parser.add_argument("--output-blend", type=Path, help="save template, target and result here")
    parser.add_argument("--output-obj", type=Path, help="export the retargeted layout here")
    parser.add_argument("--report", type=Path, help="write the JSON report here")
    parser.add_argument("--output-dir", type=Path, help="batch: where each mesh's outputs and summary.json go")
    parser.add_argument(
        "--jobs", type=int, help="batch: workers at a time (default: local 1; ray, one per CPU of the cluster)"
    )
    parser.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="batch: worker processes on this machine, or Ray actors (default local)",
    )
    parser.add_argument("--address", help="batch, --executor ray: the cluster's address (default: start Ray here)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="batch: skip the meshes whose .blend, .obj and report are already in --output-dir, made from the "
        "same template, anchors, target and settings (the others are made again)",
    )
    arguments = parser.parse_args(script_arguments(argv, __file__))
    check_frame_arguments(parser, arguments)
    check_output_arguments(
        parser,
        {
            "--output-blend": arguments.output_blend,
            "--output-obj": arguments.output_obj,
            "--report": arguments.report,
            "--point-cache": arguments.point_cache,
        },
        [arguments.template, arguments.target, arguments.anchors],
    )
    if arguments.max_iterations < 1:
        parser.error("--max-iterations must be at least 1")
    try:
        wrap_settings(arguments)
    except ValueError as error:  # springwrap_kernel.InvalidArgumentError
        parser.error(str(error))
    if arguments.anchors_spacing is not None and arguments.anchors_spacing < 0:
        parser.error("--anchors-spacing must not be negative")
    if arguments.fit_subdivision is not None and not 1 <= arguments.fit_subdivision <= 6:
        parser.error("--fit-subdivision LEVELS must be 1 to 6")
    if arguments.sequence is not None:
        if arguments.sequence[1] < arguments.sequence[0]:
            parser.error("--sequence START END: END must not come before START")
        if arguments.batch is not None or arguments.fit_subdivision is not None:
            parser.error("--sequence wraps one target over time: not with --batch or --fit-subdivision")
    if arguments.point_cache is not None:
        if arguments.sequence is None:
            parser.error("--point-cache writes a sequence's frames: it needs --sequence START END")
        if point_cache_format(arguments.point_cache) is None:
            parser.error(
                f"--point-cache {arguments.point_cache}: the file name must end with .abc (Alembic) or .usd, .usdc, "
                ".usda (USD)"
            )
    if arguments.jobs is not None and arguments.jobs < 1:
        parser.error("--jobs must be at least 1")
    if arguments.address is not None and arguments.executor != "ray":
        parser.error("--address needs --executor ray")
    if arguments.align == "anchors" and arguments.anchors is None:
        parser.error("--align anchors needs --anchors FILE.json")
    if arguments.align == "icp" and arguments.align_method == "affine":
        parser.error("--align icp refines by rigid or similarity steps: --align-method affine needs --align anchors")
    if arguments.batch is not None:
        if arguments.output_dir is None:
            parser.error("--batch needs --output-dir")
        if arguments.output_blend or arguments.output_obj or arguments.report:
            parser.error("--batch writes into --output-dir: no --output-blend, --output-obj or --report")
        if arguments.output_dir.resolve() == arguments.batch.resolve():
            parser.error("--output-dir is the --batch folder: its outputs would replace the meshes")
    elif arguments.jobs is not None or arguments.executor != "local" or arguments.resume:
        parser.error("--jobs, --executor and --resume are for --batch")
    return arguments


# ---------------------------------------------------------------- loading


def read_anchors(path: Path, vertex_count: int) -> list[tuple[int, tuple[float, float, float]]]:
    """The (layout vertex, target point) pairs of an anchors JSON file, all checked first; the points are in
    the mesh files' frame (``--up-axis``, ``--forward-axis``)."""
    if not path.is_file():
        raise ScriptError(f"{path}: no such file")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ScriptError(f"{path}: not valid JSON: {error}") from None
    entries = data.get("anchors") if isinstance(data, dict) else data
    if not isinstance(entries, list):
        raise ScriptError(f'{path}: expected {{"anchors": [{{"vertex": i, "target": [x, y, z]}}, ...]}}')
    pairs = []
    for index, entry in enumerate(entries):
        where = f"{path}: anchor {index}"
        if not isinstance(entry, dict) or "vertex" not in entry or "target" not in entry:
            raise ScriptError(f'{where}: expected {{"vertex": i, "target": [x, y, z]}}, found {entry!r}')
        vertex, target = entry["vertex"], entry["target"]
        if not isinstance(vertex, int) or isinstance(vertex, bool):
            raise ScriptError(f"{where}: vertex {vertex!r} is not an integer")
        if not 0 <= vertex < vertex_count:
            raise ScriptError(f"{where}: vertex {vertex} does not exist (the template has {vertex_count} vertices)")
        if (
            not isinstance(target, list)
            or len(target) != 3
            or not all(isinstance(value, (int, float)) and not isinstance(value, bool) for value in target)
            or not all(math.isfinite(value) for value in target)
        ):
            raise ScriptError(f"{where}: target {target!r} is not three finite numbers")
        pairs.append((vertex, tuple(float(value) for value in target)))
    if len({vertex for vertex, _ in pairs}) != len(pairs):
        raise ScriptError(f"{path}: a vertex is anchored twice")
    return pairs


# ---------------------------------------------------------------- the retarget


def align_bounds(layout, target, frame: "Matrix") -> dict:
    """Move and scale the layout uniformly so that its bounding box's centre and diagonal are the target's;
    the translation in the files' frame (the frame's axes are Blender's, permuted: the box is the same)."""
    import numpy as np
    from mathutils import Matrix, Vector

    layout_points, _ = world_vertices(layout)
    target_points, _ = world_vertices(target)
    layout_low, layout_high = layout_points.min(axis=0), layout_points.max(axis=0)
    target_low, target_high = target_points.min(axis=0), target_points.max(axis=0)
    layout_size = float(np.linalg.norm(layout_high - layout_low))
    if layout_size == 0.0:
        raise ScriptError("the template is a single point: it cannot be aligned")
    scale = float(np.linalg.norm(target_high - target_low)) / layout_size
    layout_centre, target_centre = (layout_low + layout_high) / 2, (target_low + target_high) / 2
    transform = (
        Matrix.Translation(Vector(target_centre)) @ Matrix.Scale(scale, 4) @ Matrix.Translation(-Vector(layout_centre))
    )
    layout.matrix_world = transform @ layout.matrix_world
    translation = frame.inverted().to_3x3() @ Vector(target_centre - layout_centre * scale)
    return {"scale": scale, "translation": list(translation)}


def align_with_operator(layout, arguments: argparse.Namespace, blame: str, frame: "Matrix") -> dict:
    """``springwrap.align`` (anchors then ICP, or ICP alone) on the layout's object transform; what it did
    (the matrix in the files' frame)."""
    import numpy as np

    before = np.array(layout.matrix_world, dtype=np.float64)
    use_anchors = arguments.align == "anchors"
    run_operator(
        blame, "align", method=arguments.align_method.upper(), use_anchors=use_anchors, use_icp=True, apply="OBJECT"
    )
    bpy.context.view_layer.update()
    change = np.array(layout.matrix_world, dtype=np.float64) @ np.linalg.inv(before)
    return {
        "method": arguments.align_method,
        "anchors": use_anchors,
        "icp": True,
        "matrix": to_file_frame(frame, change.tolist()),
    }


def quality_block(layout, refresh: bool) -> dict:
    """The report's ``quality`` block: the layout's quality read-out (``core.quality.summary``), as the wrap's
    finish wrote it, or measured again and rewritten (``refresh``: the cage fit moved the layout since); of its
    surface alone when the wrap moved parts (their count is ``part_vertices``)."""
    quality_data = addon_module("blender.quality")
    readout = None if refresh else quality_data.read_readout(layout)
    if readout is None:
        target = addon_module("blender.target").read_target(bpy.context.evaluated_depsgraph_get(), layout)
        readout = quality_data.update_layout(layout, target)
    return addon_module("blender.parts").readout_summary(layout, readout)


def fit_subdivision_report(levels: int) -> dict:
    """The report's entry of the subdivision cage fit just run: its Subdivision Surface's distances to the target
    (world units) before and after."""
    outcome = bpy.types.SPRINGWRAP_OT_fit_subdivision.last_outcome
    return {
        "levels": levels,
        "rounds": outcome.rounds,
        "surface_points": outcome.fine_vertex_count,
        "mean_distance_before": outcome.before.mean,
        "max_distance_before": outcome.before.max,
        "mean_distance_after": outcome.after.mean,
        "max_distance_after": outcome.after.max,
        "blender_surface": outcome.exact,
    }


def symmetric_anchor_properties(arguments: argparse.Namespace) -> dict:
    """The anchor operators' symmetric properties of ``--symmetric-anchors`` (none without it)."""
    axis = getattr(arguments, "symmetric_anchors", None)
    return {"symmetric": True, "symmetry_axis": axis} if axis else {}


def symmetric_anchor_report(layout, arguments: argparse.Namespace, warnings: list) -> dict | None:
    """``--symmetric-anchors``: the pairs made (anchors with a twin, on the plane, alone); a warning for lone ones."""
    axis = getattr(arguments, "symmetric_anchors", None)
    if not axis:
        return None
    items = layout.springwrap.anchors
    on_plane = sum(1 for item in items if item.twin_vertex == item.vertex_index)
    paired = sum(1 for item in items if item.twin_vertex >= 0) - on_plane
    alone = len(items) - paired - on_plane
    if alone:
        warnings.append(f"{alone} anchors have no twin across the {axis} plane (no twin vertex, or no target there)")
    return {"axis": axis, "pairs": paired // 2, "on_plane": on_plane, "alone": alone}


def wrap_sequence(layout, parameters, frames: list[int]) -> tuple:
    """Wrap ``layout`` over the frames START..END of its target's animation (``springwrap.wrap_sequence``'s
    run); the first frame's wrap result and the sequence's report block. Raises the add-on's errors when the
    first frame cannot be wrapped (nothing is written then)."""
    SequenceRun = addon_module("blender.wrap_sequence").SequenceRun  # noqa: N806 - a class of the enabled add-on
    frame_range = addon_module("core.sequence").frame_range
    run = SequenceRun(bpy.context, layout, parameters, frame_range(*frames))
    while not run.done:
        run.advance()
    outcome = run.finish()
    later = [frame.seconds for frame in outcome.outcomes[1:] if frame.ok]
    block = {
        "frames": [frame._asdict() for frame in outcome.outcomes],
        "failed": [frame.frame for frame in outcome.failed],
        "first_frame_seconds": round(outcome.outcomes[0].seconds, 4),
        "later_frame_seconds_mean": round(sum(later) / len(later), 4) if later else None,
    }
    return run.first_result, block


def feature_lines_report(layout) -> dict:
    """The feature pairs on the layout (chain ends, vertex count, confidence) and the lines left free."""
    pairs = [
        {
            "chain": [int(item.layout_vertices.split()[0]), int(item.layout_vertices.split()[-1])],
            "vertices": len(item.layout_vertices.split()),
            "confidence": round(item.confidence, 3),
        }
        for item in layout.springwrap.curve_constraints
        if item.source_kind == "FEATURE_LINE"
    ]
    free = addon_module("blender.feature_lines").free_lines(layout.name)
    return {"paired": pairs, "free": [{"line": label, "reason": reason} for label, reason in free]}


def retarget(arguments: argparse.Namespace) -> dict:
    """Load, align, detach, anchor, wrap, measure, write; the report (also written to --report)."""
    WrapSession = addon_module("blender.wrap_session").WrapSession  # noqa: N806 - a class of the enabled add-on
    ERRORS = addon_module("core.errors").ERRORS  # noqa: N806 - the add-on's tuple of error types
    WrapParameters = addon_module("core.wrap_inputs").WrapParameters  # noqa: N806 - a class of the enabled add-on
    from mathutils import Vector

    lap, warnings = Laps(), []
    timings = lap.timings

    point_cache = getattr(arguments, "point_cache", None)  # a batch's mesh has none (--batch refuses --sequence)
    check_output_paths([arguments.output_blend, arguments.output_obj, arguments.report, point_cache])  # before work
    enable_addon()
    bpy.ops.wm.read_homefile(use_empty=True)
    frame = frame_matrix(arguments.up_axis, arguments.forward_axis)
    template = load_mesh(arguments.template, arguments.template_object, "Template", frame)
    target = load_mesh(arguments.target, arguments.target_object, "Target", frame)
    anchor_pairs = (
        read_anchors(arguments.anchors, len(template.data.vertices)) if arguments.anchors is not None else None
    )
    layout = template.copy()
    layout.data = template.data.copy()
    layout.name = LAYOUT_NAME
    bpy.context.scene.collection.objects.link(layout)
    template.hide_set(True)
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    layout.springwrap.target = target
    lap("load")

    blame = f"template {arguments.template}, target {arguments.target}"
    alignment = align_bounds(layout, target, frame) if arguments.align in ("bounds", "icp") else None
    if anchor_pairs is not None:
        for vertex, point in anchor_pairs:
            location = tuple(frame.to_3x3() @ Vector(point))  # the files' frame, into Blender's
            run_operator(
                f"{arguments.anchors}",
                "anchor_add",
                vertex_index=vertex,
                location=location,
                use_location=True,
                **symmetric_anchor_properties(arguments),
            )
    if arguments.align in ("icp", "anchors"):
        alignment = (alignment or {}) | align_with_operator(layout, arguments, blame, frame)
    run_operator(blame, "detach", only_selected=False)
    lap("align and detach")

    if anchor_pairs is None:
        run_operator(
            blame,
            "anchors_auto",
            spacing=arguments.anchors_spacing or 0.0,
            replace=True,
            **symmetric_anchor_properties(arguments),
        )
    proposed = 0
    if arguments.propose_anchors:
        before = len(layout.springwrap.anchors)
        run_operator(blame, "anchors_propose", accept=True)
        proposed = len(layout.springwrap.anchors) - before
    if len(layout.springwrap.anchors) == 0:
        warnings.append("no anchors: the wrap is pulled by folding alone")
    symmetric = symmetric_anchor_report(layout, arguments, warnings)
    lap("anchors")

    if arguments.solver == "springs":
        warnings.append("--solver springs: " + wrap_defaults_module().RETIRED_SOLVER_WARNING)
    layout.springwrap.find_parts = not arguments.no_find_parts
    layout.springwrap.follow_group = arguments.follow_group
    layout.springwrap.follow_soft_group = arguments.follow_soft_group
    layout.springwrap.surface_group = arguments.surface_group
    try:
        parameters = WrapParameters(
            max_iterations=arguments.max_iterations,
            settings=wrap_settings(arguments),
            stiffness_group=arguments.stiffness_group,
            free_group=arguments.free_group,
        )
        frames = getattr(arguments, "sequence", None)  # a batch's mesh has none (--batch refuses --sequence)
        if frames is not None:
            result, sequence = wrap_sequence(layout, parameters, frames)
        else:
            session = WrapSession(bpy.context, layout, parameters, shape_keys=arguments.shape_keys)
    except ERRORS as error:
        raise ScriptError(f"{blame}: cannot wrap: {error}") from None
    if frames is None:
        session.run()
        result = session.finish()
        sequence = None
    elif sequence["failed"]:
        warnings.append(f"{len(sequence['failed'])} frames failed and keep the previous frame's shape")
    if not result.converged:
        warnings.append(
            f"did not converge within {arguments.max_iterations} iterations "
            f"(last move {result.max_displacement:.2e} of the layout's size); the result is kept"
        )
    followed = addon_module("blender.parts").read_parts(layout)  # the vertices the wrap moved as parts
    part_count = 0 if followed is None else int(followed.sum())
    if result.space_points > part_count:
        warnings.append(
            f"{result.space_points - part_count} of {result.vertex_count - part_count} surface vertices are off the "
            "surface (space-points)"
        )
    lap("wrap")
    feature_lines = None
    if getattr(arguments, "feature_lines", False) and frames is None:
        run_operator(blame, "feature_lines_pair")
        feature_lines = feature_lines_report(layout)
        try:
            session = WrapSession(bpy.context, layout, parameters, shape_keys=arguments.shape_keys)
        except ERRORS as error:
            raise ScriptError(f"{blame}: cannot wrap with the feature pairs: {error}") from None
        session.run()
        result = session.finish()
        lap("feature lines")

    subdivision_fit = None
    if arguments.fit_subdivision:
        run_operator(blame, "fit_subdivision", levels=arguments.fit_subdivision)
        subdivision_fit = fit_subdivision_report(arguments.fit_subdivision)
        lap("fit subdivision")

    quality = quality_block(layout, refresh=bool(arguments.fit_subdivision))
    report = {
        "template": str(arguments.template),
        "target": str(arguments.target),
        "vertices": result.vertex_count,
        "faces": len(layout.data.polygons),
        "anchors": len(layout.springwrap.anchors),
        "proposed_anchors": proposed,
        "symmetric_anchors": symmetric,
        "frame": {"up_axis": arguments.up_axis, "forward_axis": arguments.forward_axis},
        "alignment": alignment,
        "wrap": {
            "iterations": result.iterations,
            "converged": result.converged,
            "face_points": result.face_points,
            "space_points": result.space_points,
            "kernel_seconds": round(result.kernel_seconds, 4),
            "parts": result.parts,
        },
        "fit_subdivision": subdivision_fit,
        "feature_lines": feature_lines,
        "sequence": sequence,
        "shape_keys": shape_keys_report(layout, arguments.shape_keys),
        "metrics": distances_to_target(layout, target),
        "quality": quality,
        "timings": timings,
        "warnings": warnings,
        "blender": bpy.app.version_string,
    }
    if getattr(arguments, "fingerprint", None) is not None:  # a batch's mesh: what --resume compares
        report["inputs_fingerprint"] = arguments.fingerprint
    extra = []
    if point_cache is not None:
        file_format = point_cache_format(point_cache)
        sequence["point_cache"] = {"path": str(point_cache), "format": file_format}
        extra.append((point_cache, lambda path: export_point_cache(blame, layout, path, file_format)))
    lap("metrics")
    write_outputs(arguments, layout, report, extra)
    return report


def export_point_cache(blame: str, layout, path: Path, file_format: str) -> None:
    """Write the layout's sequence keys to ``path`` as ``file_format`` (``springwrap.export_sequence``'s work)."""
    try:
        addon_module("blender.point_cache").export_point_cache(bpy.context, layout, str(path), file_format)
    except addon_module("core.errors").ERRORS as error:
        raise ScriptError(f"{blame}: cannot write the point cache: {error}") from None


# ---------------------------------------------------------------- batch


def task_outputs(task: dict) -> dict[str, Path]:
    """A batch task's three outputs, by suffix: ``OUT/<name>.blend``, ``.obj``, ``.json``."""
    stem = Path(task["target"]).stem
    return {suffix: Path(task["output_dir"]) / f"{stem}.{suffix}" for suffix in OUTPUT_SUFFIXES}


def batch_task(arguments: argparse.Namespace, target: Path, output_dir: Path, shared_digests: dict) -> dict:
    """One mesh of the batch as plain data (JSON for a local worker's pipe, pickled for Ray): absolute paths, and
    the fingerprint of its inputs and settings (``shared_digests``: the template's and anchors' contents)."""
    import retarget_batch

    # Every per-mesh option (--sequence and --point-cache are refused with --batch: one target over time).
    settings = {
        name: getattr(arguments, name)
        for name in (
            "template_object",
            "target_object",
            "anchors_spacing",
            "symmetric_anchors",
            "propose_anchors",
            "align",
            "align_method",
            "max_iterations",
            "tolerance",
            "fairness",
            "arc_length",
            "thin_plate",
            "constraint",
            "folding",
            "solver",
            "schedule",
            "stiffness_group",
            "free_group",
            "follow_group",
            "follow_soft_group",
            "surface_group",
            "no_find_parts",
            "fit_subdivision",
            "feature_lines",
            "shape_keys",
            "up_axis",
            "forward_axis",
        )
    }
    settings["template"] = str(arguments.template.resolve())
    settings["anchors"] = str(arguments.anchors.resolve()) if arguments.anchors is not None else None
    fingerprint = retarget_batch.inputs_fingerprint(settings, shared_digests, retarget_batch.file_digest(target))
    return {
        "target": str(target.resolve()),
        "output_dir": str(output_dir),
        "settings": settings,
        "fingerprint": fingerprint,
    }


def retarget_task(task: dict) -> dict:
    """The batch's one task function, run by every worker (bpy imported, the add-on enabled): retarget onto
    ``task["target"]``, write its .blend, .obj and report (atomically) into ``task["output_dir"]``; its
    summary entry: ok (with the report's path) or failed (with the one-line error), and the seconds taken.

    Errors other than ScriptError propagate: the scheduler then retries the mesh on a fresh worker.
    """
    start = time.perf_counter()
    settings, outputs = task["settings"], task_outputs(task)
    arguments = argparse.Namespace(
        **settings
        | {
            "template": Path(settings["template"]),
            "anchors": settings["anchors"] and Path(settings["anchors"]),
            "target": Path(task["target"]),
            "output_blend": outputs["blend"],
            "output_obj": outputs["obj"],
            "report": outputs["json"],
            "fingerprint": task.get("fingerprint"),
        }
    )
    entry = {"target": task["target"]}
    try:
        report = retarget(arguments)
    except ScriptError as error:
        entry |= {"status": "failed", "error": str(error)}
    else:
        entry |= {"status": "ok", "report": str(outputs["json"]), "quality": report["quality"]}
    entry["seconds"] = round(time.perf_counter() - start, 2)
    return entry


def resume_state(task: dict) -> str:
    """For --resume: ``"done"`` when the mesh's .blend and .obj are there and its report (renamed into place
    last) reads, names this target and carries this task's fingerprint; ``"stale"`` when they are there but were
    made from other inputs or settings (another fingerprint, or none); ``"missing"`` otherwise."""
    outputs = task_outputs(task)
    if not all(outputs[suffix].is_file() and outputs[suffix].stat().st_size > 0 for suffix in ("blend", "obj")):
        return "missing"
    try:
        report = json.loads(outputs["json"].read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return "missing"
    if not (isinstance(report, dict) and report.get("target") == task["target"] and "metrics" in report):
        return "missing"
    return "done" if report.get("inputs_fingerprint") == task["fingerprint"] else "stale"


def remove_outputs(task: dict) -> None:
    """A failed mesh's outputs, left by an earlier run (they must not sit beside a summary saying it failed)."""
    for final in task_outputs(task).values():
        final.unlink(missing_ok=True)
    remove_partial_outputs(task)


def remove_partial_outputs(task: dict) -> None:
    """The temporary files a worker stopped mid-write leaves (``OUT/.<name>.partial.<suffix>``, and Blender's
    own ``...partial.blend@``: it saves to ``FILE@`` and renames that when done)."""
    for final in task_outputs(task).values():
        temporary = partial_path(final)
        temporary.unlink(missing_ok=True)
        temporary.with_name(temporary.name + "@").unlink(missing_ok=True)


def local_worker_command() -> list[str]:
    """The command of a local batch worker: this script in this same Blender or Python, ``--batch-worker``."""
    script = str(Path(__file__).resolve())
    if bpy.app.binary_path:  # inside a Blender binary: the same, and the same use of PYTHONPATH
        system_environment = [] if sys.flags.ignore_environment else ["--python-use-system-env"]
        return [
            bpy.app.binary_path,
            "-b",
            "--factory-startup",
            *system_environment,
            "--python-exit-code",
            "1",
            "--python",
            script,
            "--",
            WORKER_FLAG,
        ]
    return [sys.executable, script, WORKER_FLAG]


def batch_executor(arguments: argparse.Namespace):
    """The executor --executor names (see retarget_batch.py); ScriptError when it cannot be had here."""
    import retarget_batch

    if arguments.executor == "local":
        return retarget_batch.LocalExecutor(local_worker_command())
    if bpy.app.binary_path:
        raise ScriptError(
            "--executor ray runs with the bpy module (python retarget.py ...), not inside a Blender binary"
        )
    try:
        return retarget_batch.RayExecutor(arguments.address, arguments.jobs, SCRIPTS_FOLDER, TASK_ENTRY_POINT)
    except ImportError as error:
        raise ScriptError(str(error)) from None
    except (ConnectionError, RuntimeError, ValueError) as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        hint = (
            "; a cluster with Ray's token authentication also needs RAY_AUTH_MODE=token and its token here"
            if arguments.address and not os.environ.get("RAY_AUTH_MODE")
            else ""
        )
        raise ScriptError(
            f"Ray cannot start or connect ({arguments.address or 'a local instance'}): {first_line}{hint}"
        ) from None


def run_batch(arguments: argparse.Namespace) -> int:
    """Retarget onto every mesh file of --batch on --jobs workers; summary.json; exit code 0, 1, 3 or 130."""
    import retarget_batch

    # Everything that would fail every mesh, refused before any worker starts.
    if arguments.template.suffix.lower() == ".blend":
        check_blend_file(arguments.template)
    else:
        check_mesh_file(arguments.template)
    if arguments.anchors is not None and not arguments.anchors.is_file():
        raise ScriptError(f"{arguments.anchors}: no such file")
    if not arguments.batch.is_dir():
        raise ScriptError(f"{arguments.batch}: no such folder")
    targets = sorted(
        path for path in arguments.batch.iterdir() if path.is_file() and path.suffix.lower() in INPUT_SUFFIXES
    )
    if not targets:
        raise ScriptError(f"{arguments.batch}: no mesh files ({', '.join(INPUT_SUFFIXES)})")
    stems = [path.stem for path in targets]
    shared = sorted({stem for stem in stems if stems.count(stem) > 1})
    if shared:
        clashes = "; ".join(", ".join(path.name for path in targets if path.stem == stem) for stem in shared)
        raise ScriptError(
            f"{arguments.batch}: meshes that differ only by their suffix would write the same outputs "
            f"(OUT/<name>.blend, .obj, .json): {clashes}; rename or move one of each"
        )
    output_dir = arguments.output_dir.resolve()
    if output_dir.exists() and not output_dir.is_dir():
        raise ScriptError(f"{arguments.output_dir}: is a file; --output-dir names a folder")
    check_output_folder(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    shared_digests = {
        "template": retarget_batch.file_digest(arguments.template),
        "anchors": retarget_batch.file_digest(arguments.anchors),
    }
    tasks = [batch_task(arguments, target, output_dir, shared_digests) for target in targets]
    states = [resume_state(task) if arguments.resume else "missing" for task in tasks]
    resumed = [state == "done" for state in states]
    to_run = [task for task, skip in zip(tasks, resumed) if not skip]
    start = time.perf_counter()
    jobs, outcome = arguments.jobs, retarget_batch.BatchOutcome([], [])
    if to_run:
        executor = batch_executor(arguments)
        try:
            jobs = arguments.jobs or executor.default_jobs()
            progress = retarget_batch.Progress(len(tasks), already_done=sum(resumed))
            outcome = retarget_batch.run_tasks(executor, to_run, jobs, progress)
        finally:
            executor.close()
    ran = iter(outcome.entries)
    entries = [
        {
            "target": task["target"],
            "status": "ok",
            "report": str(task_outputs(task)["json"]),
            "resumed": True,
            "quality": json.loads(task_outputs(task)["json"].read_text()).get("quality"),
        }
        if skip
        else next(ran)
        for task, skip in zip(tasks, resumed)
    ]
    for entry, state in zip(entries, states):
        if state == "stale" and not entry.get("resumed"):
            entry["redone"] = True  # its earlier outputs came from other inputs or settings
    stand_out = retarget_batch.quality_outliers(
        {entry["target"]: entry.get("quality") for entry in entries if entry["status"] == "ok"}
    )
    for entry in entries:
        if entry["status"] == "ok":
            entry["stands_out"] = stand_out.get(entry["target"], {})
    for task, entry in zip(tasks, entries):
        if entry["status"] == "failed":  # also what an earlier run wrote for it
            remove_outputs(task)
        elif entry["status"] == "not run":
            remove_partial_outputs(task)
    counts = {status: sum(entry["status"] == status for entry in entries) for status in ("ok", "failed", "not run")}
    summary = {
        "template": str(arguments.template),
        "folder": str(arguments.batch),
        "executor": arguments.executor,
        "jobs": jobs,
        "meshes": entries,
        "ok": counts["ok"],
        "failed": counts["failed"],
        "not_run": counts["not run"],
        "resumed": sum(resumed),
        "redone": sum(state == "stale" for state in states),
        "interrupted": outcome.interrupted,
        "stopped": outcome.stopped,
        "seconds": round(time.perf_counter() - start, 2),
        "workers": outcome.workers,
        "quality_rule": retarget_batch.OUTLIER_RULE,
        "stand_out": sorted(stand_out),
    }
    write_atomically(output_dir / "summary.json", lambda path: path.write_text(json.dumps(summary, indent=2) + "\n"))
    not_run = f", {counts['not run']} not run" if counts["not run"] else ""
    redone = summary["redone"]
    redone = f", {redone} made again: their outputs came from another template, anchors, target or settings" * (
        redone > 0
    )
    print(
        f"retarget: {counts['ok']} of {len(entries)} meshes retargeted ({sum(resumed)} already done{redone}), "
        f"{counts['failed']} failed{not_run}; summary {output_dir / 'summary.json'}",
        file=sys.stderr,
    )
    for name in sorted(stand_out):
        metrics = ", ".join(
            f"{metric} {numbers['value']:.3g} (batch median {numbers['median']:.3g})"
            for metric, numbers in stand_out[name].items()
        )
        print(f"retarget: stands out from the batch: {name}: {metrics}", file=sys.stderr)
    if outcome.interrupted:
        print(
            "retarget: interrupted: the meshes not run are listed in the summary (run again with --resume to go on)",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    if outcome.stopped:
        raise ScriptError(f"the batch stopped: {outcome.stopped}")
    return EXIT_BATCH_FAILURES if counts["failed"] else EXIT_OK


def main() -> int:
    if script_arguments(sys.argv, __file__)[:1] == [WORKER_FLAG]:
        import retarget_batch

        return retarget_batch.serve(retarget_task)
    try:
        arguments = parse_arguments(sys.argv)  # reads the kernel's defaults: ScriptError without the add-on
        if arguments.batch is not None:
            return run_batch(arguments)
        report = retarget(arguments)
    except KeyboardInterrupt:
        print("retarget: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # noqa: BLE001 - any failure must become a non-zero exit code, also under `blender -b`
        return failed("retarget", error)
    metrics = report["metrics"]
    print(
        f"retarget: {report['vertices']} vertices, {report['wrap']['face_points']} on the target after "
        f"{report['wrap']['iterations']} iterations; mean distance {metrics['mean_distance']:.2e}, "
        f"max {metrics['max_distance']:.2e}" + "".join(f"\n  warning: {line}" for line in report["warnings"])
    )
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
