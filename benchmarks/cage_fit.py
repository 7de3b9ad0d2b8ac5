"""The subdivision cage fit on the benchmark's bodies: how far the layout's Subdivision Surface lies from the
target before and after ``springwrap.fit_subdivision``, and how long the fit takes.

For each case (``benchmarks/retarget/cases.py``; by default the heavy man, with and without holes): the
layout is the case's truth (MakeHuman's base quads where they belong on the morphed body, the answer a
perfect wrap would give) snapped onto the target, i.e. a cage on the target as a wrap leaves it. Its level-L
Subdivision Surface (Blender's modifier, limit surface) then lies inside convex parts and outside concave
ones; the fit moves the cage so that the surface lies on the target. Rows: no anchors, and the case's
landmarks as anchors (their limit points held on the truth's closest target point). Distances are Blender's
subdivided points to the target (world units; % of the truth's bounding-box diagonal): mean, p95, max, before
and after, and the fit's seconds (one run, the operator's wall time, 2 shared cores here).

    .venv/bin/python benchmarks/cage_fit.py [--cases heavy heavy-holes] [--levels 2] [--json out/bench/cage_fit.json]

A step of ``make bench`` (``out/bench/cage_fit.json``; ``QUICK=1``: the heavy case only); ``benchmarks/report.py``
makes its table in ``docs/benchmarks.md`` (*After the wrap*).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))

from benchmarks.retarget import cases  # noqa: E402 - after the path is set
from benchmarks.retarget.baselines import mesh_object  # noqa: E402
from headless import enable_addon  # noqa: E402

DEFAULT_CASES = ("heavy", "heavy-holes")
LANDMARK_COUNT = 12


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="case names (cases.py)")
    parser.add_argument("--levels", type=int, default=2, help="subdivision level fitted (default 2)")
    parser.add_argument("--rounds", type=int, default=5, help="Gauss-Newton rounds (default 5)")
    parser.add_argument("--json", type=Path, help="write the rows here")
    return parser.parse_args(argv)


def surface_distances(layout, target_mesh, levels: int) -> np.ndarray:
    """Distances of Blender's Subdivision Surface points of ``layout`` (a modifier added, evaluated, removed) to
    the target (a kernel mesh in world space)."""
    modifier = layout.modifiers.new("Measure", "SUBSURF")
    modifier.levels = levels
    try:
        evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        points = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", points)
        evaluated.to_mesh_clear()
    finally:
        layout.modifiers.remove(modifier)
    matrix = np.array(layout.matrix_world)
    world = points.reshape(-1, 3) @ matrix[:3, :3].T.astype(np.float32) + matrix[:3, 3].astype(np.float32)
    return np.asarray(target_mesh.closest_points(np.ascontiguousarray(world)).distances, dtype=np.float64)


def statistics(distances: np.ndarray, diagonal: float) -> dict:
    """Mean, p95 and max, in world units and % of the diagonal."""
    values = {
        "mean": float(distances.mean()),
        "p95": float(np.percentile(distances, 95)),
        "max": float(distances.max()),
    }
    return values | {f"{name}_percent": 100.0 * value / diagonal for name, value in list(values.items())}


def run_case(name: str, levels: int, rounds: int, anchored: bool) -> dict:
    import springwrap_kernel

    (spec,) = cases.case_specs([name])
    case, _cached = cases.get_case(spec)
    bpy.ops.wm.read_homefile(use_empty=True)
    enable_addon()
    target = mesh_object("Target", case.target_vertices, case.target_triangles)
    layout = mesh_object("Layout", case.true_positions, case.layout_quads)
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}
    target_mesh = springwrap_kernel.TargetMesh(
        np.ascontiguousarray(case.target_vertices, dtype=np.float32),
        np.ascontiguousarray(case.target_triangles, dtype=np.uint32),
    )
    anchors = 0
    if anchored:
        landmarks = case.landmarks(LANDMARK_COUNT)
        points = np.asarray(
            target_mesh.closest_points(
                np.ascontiguousarray(case.true_positions[landmarks.vertices], dtype=np.float32)
            ).positions
        )
        for vertex, point in zip(landmarks.vertices.tolist(), points.tolist()):
            assert bpy.ops.springwrap.anchor_add(vertex_index=int(vertex), location=point, use_location=True) == {
                "FINISHED"
            }
        anchors = len(layout.springwrap.anchors)
    before = surface_distances(layout, target_mesh, levels)
    start = time.perf_counter()
    assert bpy.ops.springwrap.fit_subdivision(levels=levels, rounds=rounds) == {"FINISHED"}
    seconds = time.perf_counter() - start
    after = surface_distances(layout, target_mesh, levels)
    outcome = bpy.types.SPRINGWRAP_OT_fit_subdivision.last_outcome
    diagonal = case.diagonal
    return {
        "case": name,
        "levels": levels,
        "rounds": rounds,
        "anchors": anchors,
        "cage_vertices": len(case.true_positions),
        "surface_points": int(before.size),
        "blender_surface": bool(outcome.exact),
        "before": statistics(before, diagonal),
        "after": statistics(after, diagonal),
        "seconds": round(seconds, 2),
        "diagonal": diagonal,
    }


def table(rows: list[dict]) -> str:
    lines = [
        "| case | anchors | surface points | mean before → after (%) | p95 before → after (%) | max before → after (%) | seconds |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        before, after = row["before"], row["after"]
        cells = [f"{before[name + '_percent']:.4f} → {after[name + '_percent']:.4f}" for name in ("mean", "p95", "max")]
        lines.append(
            f"| {row['case']} (level {row['levels']}) | {row['anchors']} | {row['surface_points']:,} | "
            + " | ".join(cells)
            + f" | {row['seconds']:.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    arguments = parse_arguments(sys.argv[1:] if argv is None else argv)
    rows = [
        run_case(name, arguments.levels, arguments.rounds, anchored)
        for name in arguments.cases
        for anchored in (False, True)
    ]
    print(table(rows))
    if arguments.json is not None:
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
