"""What the quality read-out costs and what it says, on the demo and on a body; not a test.

1. **Demo**: the scene of ``blender_scripts/demo.py`` (Suzanne subdivided and displaced with a hole in the
   forehead; Suzanne's own quads moved and scaled as the template): detach, automatic anchors, wrap.
2. **Body**: the MakeHuman quad body (13,380 vertices) onto the retarget benchmark's ``heavy`` case (and its
   ``-holes`` variant), aligned by its landmarks, detached, anchored at 24 landmarks and wrapped through the
   operators (``benchmarks.retarget.springwrap_methods``). There the truth is known, so the read-out's flips
   are compared with the faces turned against the true layout's.

For each: the wrap's time with the read-out, the read-out's own time (measure, then write; the median of
five), and its numbers (``core.quality.summary``). Run: ``.venv/bin/python benchmarks/quality_readout.py
[--json out/bench/quality_readout.json]``; needs the benchmark's data (``.cache/springwrap-bench``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))

from benchmarks._machine import write_json  # noqa: E402 - after the path is set

ANCHORS = 24
REPEATS = 5


def readout_costs(layout) -> dict:
    """The read-out of ``layout`` measured and written again ``REPEATS`` times: median seconds of each."""
    import bpy

    from springwrap.blender import quality as quality_data
    from springwrap.blender import target as target_data

    target = target_data.read_target(bpy.context.evaluated_depsgraph_get(), layout)
    measure, write = [], []
    for _ in range(REPEATS):
        start = time.perf_counter()
        readout = quality_data.measure_layout(layout, target)
        middle = time.perf_counter()
        quality_data.write_readout(layout, readout)
        measure.append(middle - start)
        write.append(time.perf_counter() - middle)
    return {"measure_seconds": statistics.median(measure), "write_seconds": statistics.median(write)}


def stored_summary(layout) -> dict:
    from springwrap.blender import quality as quality_data
    from springwrap.core import quality

    return quality.summary(quality_data.read_readout(layout))


def demo() -> dict:
    import bpy

    import demo as demo_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    target, _hole, _cut = demo_scene.build_target()
    layout = demo_scene.build_layout(target, "Wrapped")
    wrap_seconds = demo_scene.wrap_with_auto_anchors(layout, target)
    return {
        "layout_vertices": len(layout.data.vertices),
        "layout_faces": len(layout.data.polygons),
        "wrap_seconds": wrap_seconds,
        **readout_costs(layout),
        "quality": stored_summary(layout),
    }


def body(name: str) -> dict:
    import bpy

    from benchmarks.retarget import baselines, cases, metrics, springwrap_methods

    case, _cached = cases.get_case(cases.case_specs([name])[0])
    marks = case.landmarks(ANCHORS)
    anchors = case.true_positions[marks.vertices]
    matrix = baselines.umeyama(case.layout_vertices[marks.vertices], anchors)
    aligned = baselines.apply_matrix(matrix, case.layout_vertices)
    baselines.clear_scene()
    target = baselines.mesh_object("Target", case.target_vertices, case.target_triangles)
    start = time.perf_counter()
    positions, _notes, report = springwrap_methods.springwrap_wrap(
        aligned, case.layout_quads, target, marks.vertices, anchors
    )
    operators_seconds = time.perf_counter() - start
    layout = bpy.context.view_layer.objects.active
    truth_flipped = metrics.flipped_quads(positions, case.true_positions, case.layout_quads)
    from springwrap.blender import quality as quality_data

    flipped = quality_data.read_readout(layout).flipped
    return {
        "case": name,
        "target_triangles": int(len(case.target_triangles)),
        "layout_vertices": int(len(case.layout_vertices)),
        "diagonal": case.diagonal,
        "operators_seconds": operators_seconds,
        "wrap_seconds": report.as_dict().get("wrap_seconds"),
        **readout_costs(layout),
        "quality": stored_summary(layout),
        "flipped_against_truth": int(truth_flipped.sum()),
        "flipped_both": int((truth_flipped & flipped).sum()),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, default=REPOSITORY / "out" / "bench" / "quality_readout.json")
    parser.add_argument("--cases", nargs="*", default=["heavy", "heavy-holes"])
    arguments = parser.parse_args()

    import bpy  # noqa: F401

    import addon_utils

    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        print("quality_readout: the springwrap add-on does not enable: run `make setup`", file=sys.stderr)
        return 1
    results = {"demo": demo()}
    print(json.dumps(results["demo"], indent=1), flush=True)
    for name in arguments.cases:
        results[name] = body(name)
        print(json.dumps(results[name], indent=1), flush=True)
    write_json(arguments.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
