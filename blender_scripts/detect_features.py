"""Detect feature curves on a mesh, headless: open a .blend, run ``springwrap.detect_features``, save, report.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python blender_scripts/detect_features.py --blend FILE.blend --object NAME [options]
    blender -b FILE.blend --python blender_scripts/detect_features.py -- --object NAME [options]

Options: ``--object NAME`` (the mesh to analyse; default: the active object's Springwrap target, else the active
mesh), ``--layout NAME`` (the layout whose median edge length sets the automatic scale; default: the active object
when it is a layout of that mesh), ``--scale S`` (0, the default: automatic), ``--flat-threshold``,
``--ridge-threshold``, ``--hysteresis``, ``--min-length`` (default: the kernel's), ``--no-colors`` (do not write the
region colours), ``--output FILE.blend`` (default: nothing is saved), ``--json REPORT.json`` (the scale used and
why, the counts, every curve's kind, length and points in world space). Exits non-zero on any failure (a plane,
a bad scale, a missing object).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import bpy

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import (
    ScriptError,
    addon_module,
    check_output_arguments,
    check_output_paths,
    finite_number,
    script_arguments,
    script_main,
    write_all_or_nothing,
)
from scene_io import find_mesh, open_blend


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's own arguments (see the module docstring)."""
    parser = argparse.ArgumentParser(prog="detect_features.py", description=__doc__.splitlines()[0])
    parser.add_argument("--blend", type=Path, help="the .blend to open (not needed under `blender -b FILE.blend`)")
    parser.add_argument("--object", help="the mesh to analyse (default: the active object's target, or itself)")
    parser.add_argument("--layout", help="the layout whose median edge length sets the automatic scale")
    parser.add_argument("--scale", type=finite_number, default=0.0, help="fitting radius (default 0: automatic)")
    parser.add_argument("--flat-threshold", type=finite_number, help="|k| x scale below which a direction is flat")
    parser.add_argument("--ridge-threshold", type=finite_number, help="k x scale a ridge or valley must reach")
    parser.add_argument("--hysteresis", type=finite_number, help="fraction of the ridge threshold kept along a curve")
    scales = addon_module("core.features").feature_defaults()["min_length_scales"]  # the kernel's
    parser.add_argument(
        "--min-length", type=finite_number, help=f"shorter curves are dropped (default: {scales:g} times the scale)"
    )
    parser.add_argument("--no-colors", action="store_true", help="do not write the region colours")
    parser.add_argument("--output", type=Path, help="the .blend to save the result to")
    parser.add_argument("--json", type=Path, help="the report to write (JSON)")
    arguments = parser.parse_args(script_arguments(argv, __file__))
    check_output_arguments(parser, {"--output": arguments.output, "--json": arguments.json}, [])
    for name in ("scale", "flat_threshold", "ridge_threshold", "hysteresis", "min_length"):
        value = getattr(arguments, name)
        if value is not None and not (np.isfinite(value) and value >= 0.0):
            parser.error(f"--{name.replace('_', '-')} must be a finite number >= 0, not {value}")
    if arguments.hysteresis is not None and arguments.hysteresis > 1.0:
        parser.error(f"--hysteresis must be within [0, 1], not {arguments.hysteresis}")
    return arguments


def prepare(arguments: argparse.Namespace):
    """Open the file; the mesh to analyse and the layout for the scale (or None), in object mode."""
    open_blend(arguments.blend)
    active = bpy.context.view_layer.objects.active
    if active is not None and active.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    if arguments.object is not None:
        source = find_mesh(arguments.object, "mesh to analyse")
    else:
        source = addon_module("operators.features").feature_object(bpy.context)
        if source is None:
            raise ScriptError("no --object given and the active object is not a mesh")
    if arguments.layout is not None:
        layout = find_mesh(arguments.layout, "layout")
    else:
        layout = addon_module("operators.features").scale_layout(bpy.context, source)
    return source, layout


def curve_records(source: bpy.types.Object) -> list[dict]:
    """Every spline of the feature curve objects of ``source``: kind, point count, length, points (world)."""
    features = addon_module("blender.features")
    records = []
    for obj in features.feature_objects(source.name):
        matrix = np.array(obj.matrix_world)
        for spline in obj.data.splines:
            values = np.empty(len(spline.points) * 4, dtype=np.float64)
            spline.points.foreach_get("co", values)
            points = values.reshape(-1, 4)[:, :3] @ matrix[:3, :3].T + matrix[:3, 3]
            records.append(
                {
                    "kind": obj[features.FEATURE_KIND_PROPERTY],
                    "points": points.round(6).tolist(),
                    "length": float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()),
                }
            )
    return records


def run(arguments: argparse.Namespace) -> None:
    """Everything: open, choose the scale, detect, report, save."""
    start = time.perf_counter()
    check_output_paths([arguments.output, arguments.json])  # before any work
    source, layout = prepare(arguments)
    features = addon_module("blender.features")
    ERRORS = addon_module("core.errors").ERRORS  # noqa: N806
    # The scale the operator will use, chosen here the same way (the kernel's automatic scale) so that the
    # report can say it; then passed to the operator explicitly.
    try:
        feature_mesh = features.read_feature_mesh(bpy.context.evaluated_depsgraph_get(), source)
        edge_length = features.layout_edge_length(layout) if layout is not None and not arguments.scale else 0.0
        kernel = addon_module("core.features").springwrap_kernel
        mesh = kernel.TargetMesh(feature_mesh.vertices, feature_mesh.triangles)
        scale = arguments.scale or mesh.automatic_feature_scale(edge_length)
    except ERRORS as error:
        raise ScriptError(f"'{source.name}': {error}") from error
    if arguments.scale:
        chosen = "given"
    elif edge_length > 0.0:
        chosen = f"automatic, from the edges of '{layout.name}' (median {edge_length:.4g})"
    else:
        chosen = "automatic, from the target"
    print(f"'{source.name}': {len(feature_mesh.vertices)} vertices; scale {scale:.4g} ({chosen})")
    options = {
        "object_name": source.name,
        "scale": scale,
        "write_colors": not arguments.no_colors,
        "write_curves": True,
    }
    for name in ("flat_threshold", "ridge_threshold", "hysteresis", "min_length"):
        if getattr(arguments, name) is not None:
            options[name] = getattr(arguments, name)
    try:
        result = bpy.ops.springwrap.detect_features(**options)
    except RuntimeError as error:
        raise ScriptError(str(error).strip().removeprefix("Error: ")) from None
    if result != {"FINISHED"}:
        raise ScriptError(f"detect_features returned {result}")
    curves = curve_records(source)
    kinds = [curve["kind"] for curve in curves]
    lengths = [curve["length"] for curve in curves]
    summary = f"{kinds.count('RIDGE')} ridges, {kinds.count('VALLEY')} valleys" + (
        f", median length {np.median(lengths):.4g}" if lengths else ""
    )
    print(summary)
    report = {
        "object": source.name,
        "layout": layout.name if edge_length > 0.0 else None,
        "layout_edge_length": edge_length,
        "scale": scale,
        "scale_chosen": chosen,
        "ridges": kinds.count("RIDGE"),
        "valleys": kinds.count("VALLEY"),
        "median_length": float(np.median(lengths)) if lengths else 0.0,
        "curves": curves,
        "seconds": time.perf_counter() - start,
    }
    outputs = []
    if arguments.json is not None:
        outputs.append((arguments.json, lambda path: path.write_text(json.dumps(report, indent=1))))
    if arguments.output is not None:

        def save(path: Path) -> None:
            if bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, copy=True) != {"FINISHED"}:
                raise ScriptError(f"{arguments.output}: could not save")

        outputs.append((arguments.output, save))
    for path in write_all_or_nothing(outputs):
        print(f"wrote {path}")
    if arguments.output is None:
        print("not saved (no --output)")
    print(f"done in {time.perf_counter() - start:.1f} s")


def main() -> int:
    return script_main("detect_features", parse_arguments, run)


if __name__ == "__main__":
    sys.exit(main())
