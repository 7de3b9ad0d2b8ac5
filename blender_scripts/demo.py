"""Springwrap demo: retarget Suzanne's own quad layout onto a displaced, holed Suzanne.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python blender_scripts/demo.py [--output PATH]
    blender -b --factory-startup --python blender_scripts/demo.py -- [--output PATH]

The target is Suzanne with a few forehead faces cut out, subdivided and displaced by a live
modifier stack (so the add-on must use the evaluated target) and moved off the origin. The
layout is a second Suzanne (the same quads, a template) placed a little off and larger. The
script runs detach -> project (NORMAL, both directions) -> snap (SURFACE) on it, then, on a
second copy of the template ("Wrapped"), detach -> anchors_auto -> wrap (the spring
optimisation, paper section 2.5), and prints, per step, the time, how many layout vertices are
face-points and how far the layout vertices are from the evaluated target surface. Distances
are measured independently of Springwrap with ``mathutils.bvhtree.BVHTree.FromObject``, in
world space. It saves the scene as a .blend and exits non-zero on any failure.
"""

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes bmesh and mathutils importable

# isort: split
import bmesh
import numpy as np
from mathutils import Euler, Matrix, Vector
from mathutils.bvhtree import BVHTree

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import EXIT_OK, addon_module, enable_addon, failed, script_arguments

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUTPUT = REPOSITORY_ROOT / "out" / "demo.blend"

# Where the hole is cut: base-mesh faces whose centre lies within this ball (Suzanne's forehead).
HOLE_CENTER = Vector((0.0, -0.79, 0.45))
HOLE_RADIUS = 0.17
SUBDIVISION_LEVELS = 2
DISPLACE_STRENGTH = 0.06
TARGET_MATRIX = Matrix.LocRotScale(Vector((0.4, -0.3, 0.2)), Euler((0.25, -0.1, 0.6)), Vector((1.2, 1.2, 1.2)))
# The template sits off the target: moved 0.15 (in the target's frame) and scaled by 1.08.
LAYOUT_OFFSET = Vector((0.15, 0.0, 0.0))
LAYOUT_SCALE = 1.08
# Relative to the target's bounding-box diagonal: "on the surface" and "on the hole rim".
SURFACE_TOLERANCE = 1e-4
# Projection range (world units, ~10% of the target's size): vertices over the forehead hole find no
# surface that close and stay space-points, instead of shooting through the hole to the back of the
# head; the final snap then lays them on the hole's rim.
PROJECT_MAX_DISTANCE = 0.3
# The wrap: anchors every WRAP_ANCHOR_SPACING (world units) by closest point, then at most
# the wrap's default iteration limit; at least WRAP_MIN_FACE_FRACTION of the vertices must land
# (the rest are space-points over the hole and Suzanne's own open borders, the eye sockets).
WRAP_ANCHOR_SPACING = 0.3
WRAP_MIN_FACE_FRACTION = 0.8


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's own arguments: those after ``--`` if any, else all after the script's path.

    Under ``blender -b --python demo.py`` without ``--``, ``sys.argv`` holds Blender's own
    arguments; the script then has none."""
    argv = script_arguments(argv, __file__)
    parser = argparse.ArgumentParser(prog="demo.py", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--output", type=Path, default=DEFAULT_OUTPUT, help=f"the .blend to write (default {DEFAULT_OUTPUT})"
    )
    return parser.parse_args(argv)


# ---------------------------------------------------------------- scene


def add_monkey(name: str) -> bpy.types.Object:
    """Add a Suzanne at the origin, named ``name`` (object and mesh)."""
    result = bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0.0, 0.0, 0.0))
    if result != {"FINISHED"}:
        raise RuntimeError(f"primitive_monkey_add returned {result}")
    monkey = bpy.context.active_object
    monkey.name = name
    monkey.data.name = name
    return monkey


def cut_hole(mesh: bpy.types.Mesh) -> tuple[list[int], Vector]:
    """Delete the faces of ``mesh`` whose centre is inside the hole ball.

    Returns the indices (before deletion) of the deleted faces and their mean centre."""
    bm = bmesh.new()
    bm.from_mesh(mesh)
    doomed = [face for face in bm.faces if (face.calc_center_median() - HOLE_CENTER).length < HOLE_RADIUS]
    if not doomed:
        raise RuntimeError("cut_hole: no face inside the hole ball")
    deleted_indices = [face.index for face in doomed]
    hole_centroid = sum((face.calc_center_median() for face in doomed), Vector()) / len(doomed)
    bmesh.ops.delete(bm, geom=doomed, context="FACES")
    bm.to_mesh(mesh)
    bm.free()
    mesh.update()
    return deleted_indices, hole_centroid


def build_target() -> tuple[bpy.types.Object, Vector, int]:
    """Suzanne with a forehead hole, a live Subdivision + cloud Displace stack, moved and turned.

    Returns the object, the hole centre (object space) and how many base faces were cut."""
    target = add_monkey("Target")
    deleted_faces, hole_centroid = cut_hole(target.data)
    subdivision = target.modifiers.new("Subdivision", "SUBSURF")
    subdivision.levels = SUBDIVISION_LEVELS
    subdivision.render_levels = SUBDIVISION_LEVELS
    clouds = bpy.data.textures.new("SpringwrapClouds", "CLOUDS")
    clouds.noise_scale = 0.3
    displace = target.modifiers.new("Displace", "DISPLACE")
    displace.texture = clouds
    displace.strength = DISPLACE_STRENGTH
    target.matrix_world = TARGET_MATRIX
    return target, hole_centroid, len(deleted_faces)


def build_layout(target: bpy.types.Object, name: str = "Layout") -> bpy.types.Object:
    """Suzanne's own quads as a template, placed off the target (moved and scaled)."""
    layout = add_monkey(name)
    layout.matrix_world = target.matrix_world @ Matrix.Translation(LAYOUT_OFFSET) @ Matrix.Scale(LAYOUT_SCALE, 4)
    return layout


def new_scene() -> tuple[bpy.types.Object, Vector, int]:
    """An empty file with the add-on enabled and the demo's target in it (:func:`build_target`'s result)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    enable_addon()
    return build_target()


def attach_and_activate(layout: bpy.types.Object, target: bpy.types.Object) -> None:
    """Give ``layout`` its Springwrap target and make it the only selected, active object (what the operators
    act on)."""
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout


def wrap_with_auto_anchors(layout: bpy.types.Object, target: bpy.types.Object, *execution) -> float:
    """The demo's wrap of a template: :func:`attach_and_activate`, then through the operators detach, automatic
    anchors (WRAP_ANCHOR_SPACING) and the wrap (its default iteration limit; ``execution``: the wrap's execution
    context, e.g. ``"EXEC_DEFAULT"``). The wrap's seconds; raises when an operator does not finish."""
    attach_and_activate(layout, target)
    for operator, properties in (
        (bpy.ops.springwrap.detach, {"only_selected": False}),
        (bpy.ops.springwrap.anchors_auto, {"spacing": WRAP_ANCHOR_SPACING, "method": "CLOSEST", "replace": True}),
    ):
        if operator(**properties) != {"FINISHED"}:
            raise RuntimeError(f"{operator.idname_py()} did not finish")
    start = time.perf_counter()
    if bpy.ops.springwrap.wrap(*execution) != {"FINISHED"}:
        raise RuntimeError("springwrap.wrap did not finish")
    return time.perf_counter() - start


# ---------------------------------------------------------------- measuring


@dataclass
class TargetProbe:
    """The evaluated target, for measuring layout vertices against it (independently of Springwrap)."""

    tree: BVHTree
    matrix_world: Matrix
    matrix_inverse: Matrix
    rim_starts: np.ndarray  # (R, 3) world-space ends of the hole rim's edges
    rim_ends: np.ndarray
    triangle_count: int
    tolerance: float  # world-space length under which two points are "the same"


def hole_rim_edges(mesh: bpy.types.Mesh, hole_centroid: Vector) -> np.ndarray:
    """Edges of the evaluated mesh's boundary loop nearest the hole centre, as (R, 2, 3) object-space ends.

    Suzanne has open borders of her own (the eye sockets); the hole is the boundary loop that
    passes nearest to the centre of the cut faces."""
    bm = bmesh.new()
    bm.from_mesh(mesh)
    boundary = [edge for edge in bm.edges if edge.is_boundary]
    if not boundary:
        bm.free()
        raise RuntimeError("the evaluated target has no boundary edge: the hole is missing")
    # Group boundary edges into loops (components through shared vertices).
    edges_of_vertex: dict[int, list[int]] = {}
    for position, edge in enumerate(boundary):
        for vertex in edge.verts:
            edges_of_vertex.setdefault(vertex.index, []).append(position)
    component = [-1] * len(boundary)
    for seed in range(len(boundary)):
        if component[seed] != -1:
            continue
        component[seed] = seed
        stack = [seed]
        while stack:
            edge = boundary[stack.pop()]
            for vertex in edge.verts:
                for neighbour in edges_of_vertex[vertex.index]:
                    if component[neighbour] == -1:
                        component[neighbour] = seed
                        stack.append(neighbour)
    ends = np.array([[tuple(vertex.co) for vertex in edge.verts] for edge in boundary], dtype=np.float64)
    bm.free()
    midpoints = ends.mean(axis=1)
    nearest = int(np.argmin(np.linalg.norm(midpoints - np.array(hole_centroid), axis=1)))
    in_hole = np.array(component) == component[nearest]
    return ends[in_hole]


def probe_target(target: bpy.types.Object, hole_centroid: Vector) -> TargetProbe:
    """Build the independent measuring tree over the evaluated target."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = target.evaluated_get(depsgraph)
    tree = BVHTree.FromObject(target, depsgraph)  # object space of the evaluated mesh
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        triangle_count = len(mesh.loop_triangles)
        rim = hole_rim_edges(mesh, hole_centroid)
        corners = np.array([tuple(target.matrix_world @ Vector(corner)) for corner in evaluated.bound_box])
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(target.matrix_world)
    rim_world = rim @ matrix[:3, :3].T + matrix[:3, 3]
    diagonal = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
    return TargetProbe(
        tree=tree,
        matrix_world=target.matrix_world.copy(),
        matrix_inverse=target.matrix_world.inverted(),
        rim_starts=rim_world[:, 0],
        rim_ends=rim_world[:, 1],
        triangle_count=triangle_count,
        tolerance=SURFACE_TOLERANCE * diagonal,
    )


def distance_to_segments(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """For each point (K, 3), the distance to the nearest of the segments (R, 3)-(R, 3)."""
    direction = ends - starts  # (R, 3)
    length_squared = np.maximum((direction * direction).sum(axis=1), 1e-30)
    relative = points[:, None, :] - starts[None, :, :]  # (K, R, 3)
    parameter = np.clip((relative * direction[None]).sum(axis=2) / length_squared, 0.0, 1.0)
    nearest = starts[None] + parameter[..., None] * direction[None]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2).min(axis=1)


def layout_world_positions(layout: bpy.types.Object) -> np.ndarray:
    """(N, 3) float64 world-space positions of the layout mesh's vertices."""
    mesh = layout.data
    local = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", local)
    matrix = np.array(layout.matrix_world)
    return local.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def face_point_count(layout: bpy.types.Object) -> int:
    """How many layout vertices are face-points (``springwrap_state == 1``); 0 before any step."""
    return int(face_point_states(layout).sum())


@dataclass
class StepReport:
    """One row of the demo's table."""

    step: str
    seconds: float | None  # None for the template, before any step
    face_points: int
    mean_distance: float
    max_distance: float
    over_hole: int
    on_rim: int


def nearest_target_points(points: np.ndarray, probe: TargetProbe) -> np.ndarray:
    """(N, 3) world-space nearest points of the evaluated target to the (N, 3) world-space ``points``."""
    nearest = np.empty_like(points)
    for index, point in enumerate(points):
        location, _normal, _face, _distance = probe.tree.find_nearest(probe.matrix_inverse @ Vector(point))
        if location is None:
            raise RuntimeError(f"find_nearest found nothing for layout vertex {index}")
        nearest[index] = probe.matrix_world @ location
    return nearest


def face_point_states(layout: bpy.types.Object) -> np.ndarray:
    """(N,) bool: which layout vertices are face-points (all False before any step)."""
    attribute = layout.data.attributes.get("springwrap_state")
    states = np.zeros(len(layout.data.vertices), dtype=np.int32)
    if attribute is not None:
        attribute.data.foreach_get("value", states)
    return states == 1


def measure(step: str, seconds: float | None, layout: bpy.types.Object, probe: TargetProbe) -> StepReport:
    """Distances of the layout vertices to the evaluated target (world space), and how many lie over the hole.

    A vertex lies over the hole when its nearest target point is on the hole's rim while the
    vertex itself is off the surface: there is no surface under it. A vertex on the surface at
    the rim counts as on the rim."""
    points = layout_world_positions(layout)
    nearest = nearest_target_points(points, probe)
    distances = np.linalg.norm(points - nearest, axis=1)
    on_rim = distance_to_segments(nearest, probe.rim_starts, probe.rim_ends) < probe.tolerance
    off_surface = distances > probe.tolerance
    return StepReport(
        step,
        seconds,
        face_point_count(layout),
        float(distances.mean()),
        float(distances.max()),
        over_hole=int((on_rim & off_surface).sum()),
        on_rim=int((on_rim & ~off_surface).sum()),
    )


def run_step(step: str, operator, layout: bpy.types.Object, probe: TargetProbe, **properties) -> StepReport:
    """Run one Springwrap operator on the layout (the active object), timed, and measure the result."""
    start = time.perf_counter()
    result = operator(**properties)
    seconds = time.perf_counter() - start
    if result != {"FINISHED"}:
        raise RuntimeError(f"{step}: the operator returned {result}")
    return measure(step, seconds, layout, probe)


def print_table(reports: list[StepReport], vertex_count: int) -> None:
    """Print the per-step table."""
    header = (
        f"{'step':<26} {'time (s)':>9} {'face-points':>13} {'mean dist':>10} {'max dist':>10} "
        f"{'over hole':>10} {'on rim':>7}"
    )
    print(header)
    print("-" * len(header))
    for report in reports:
        seconds = "" if report.seconds is None else f"{report.seconds:.4f}"
        print(
            f"{report.step:<26} {seconds:>9} {report.face_points:>6}/{vertex_count:<6} "
            f"{report.mean_distance:>10.5f} {report.max_distance:>10.5f} {report.over_hole:>10} {report.on_rim:>7}"
        )


def check_wrap(wrapped: bpy.types.Object, probe: TargetProbe, vertex_count: int) -> None:
    """The wrapped layout: enough face-points, every face-point on the target, every anchor met."""
    on_face = face_point_states(wrapped)
    if on_face.sum() < WRAP_MIN_FACE_FRACTION * vertex_count:
        raise RuntimeError(f"after the wrap only {on_face.sum()} of {vertex_count} vertices are face-points")
    points = layout_world_positions(wrapped)
    off_surface = np.linalg.norm(points - nearest_target_points(points, probe), axis=1)[on_face].max()
    if off_surface > probe.tolerance:
        raise RuntimeError(f"after the wrap a face-point is {off_surface:.3g} off the target")
    anchors = wrapped.springwrap.anchors
    vertices = np.array([anchor.vertex_index for anchor in anchors], dtype=np.int64)
    locations = np.array([tuple(anchor.location) for anchor in anchors], dtype=np.float64).reshape(-1, 3)
    missed = np.linalg.norm(points[vertices] - locations, axis=1).max() if len(anchors) else 0.0
    if missed > probe.tolerance:
        raise RuntimeError(f"after the wrap an anchored vertex is {missed:.3g} from its anchor")
    print(
        f"wrap: {on_face.sum()} of {vertex_count} vertices on the target (face-points within "
        f"{off_surface:.2e}), {len(anchors)} anchors met within {missed:.2e}"
    )


# ---------------------------------------------------------------- main


def run(output: Path) -> None:
    """Build the scene, retarget the layout step by step, print the table and save ``output``."""
    start = time.perf_counter()
    target, hole_centroid, cut_faces = new_scene()
    layout = build_layout(target)
    attach_and_activate(layout, target)
    probe = probe_target(target, hole_centroid)
    vertex_count = len(layout.data.vertices)
    print(
        f"target: Suzanne, {cut_faces} faces cut, subdivision {SUBDIVISION_LEVELS} + cloud displace, "
        f"{probe.triangle_count} evaluated triangles, {len(probe.rim_starts)} hole-rim edges"
    )
    print(
        f"layout: Suzanne's quads, {vertex_count} vertices, {len(layout.data.polygons)} faces, "
        f"moved {LAYOUT_OFFSET.length:g} and scaled {LAYOUT_SCALE:g}"
    )
    print(f"distances: world space, to the evaluated target (mathutils BVHTree); tolerance {probe.tolerance:.2e}\n")

    operators = bpy.ops.springwrap
    reports = [measure("template (as placed)", None, layout, probe)]
    reports.append(run_step("detach", operators.detach, layout, probe, only_selected=False))
    reports.append(
        run_step(
            f"project (NORMAL, <={PROJECT_MAX_DISTANCE:g})",
            operators.project,
            layout,
            probe,
            direction="NORMAL",
            only_selected=False,
            both_directions=True,
            max_distance=PROJECT_MAX_DISTANCE,
        )
    )
    reports.append(
        run_step("snap (SURFACE)", operators.snap, layout, probe, mode="SURFACE", only_selected=False, max_distance=0.0)
    )
    snapped = reports[-1]

    # The wrap, on a second copy of the template.
    wrapped = build_layout(target, "Wrapped")
    attach_and_activate(wrapped, target)
    reports.append(measure("copy of the template", None, wrapped, probe))
    reports.append(run_step("detach (copy)", operators.detach, wrapped, probe, only_selected=False))
    reports.append(
        run_step(
            f"anchors_auto (spacing {WRAP_ANCHOR_SPACING:g})",
            operators.anchors_auto,
            wrapped,
            probe,
            spacing=WRAP_ANCHOR_SPACING,
            method="CLOSEST",
            replace=True,
        )
    )
    reports.append(
        run_step(
            f"wrap (<={addon_module('core.defaults').MAX_ITERATIONS} iterations)",
            operators.wrap,
            wrapped,
            probe,
        )
    )
    print()
    print_table(reports, vertex_count)
    print("over hole: vertices off the surface whose nearest target point is on the hole's rim (no surface under them)")
    print("on rim: vertices on the surface, on the hole's rim")
    print("from 'copy of the template' on: a second copy of the template, 'Wrapped', for the wrap")

    if snapped.face_points != vertex_count:
        raise RuntimeError(f"after snap only {snapped.face_points} of {vertex_count} vertices are face-points")
    if snapped.max_distance > probe.tolerance:
        raise RuntimeError(
            f"after snap a vertex is {snapped.max_distance:.3g} off the target (tolerance {probe.tolerance:.3g})"
        )
    check_wrap(wrapped, probe, vertex_count)

    output = output.resolve()
    output.parent.mkdir(parents=True, exist_ok=True)
    result = bpy.ops.wm.save_as_mainfile(filepath=str(output), check_existing=False)
    if result != {"FINISHED"} or not output.exists():
        raise RuntimeError(f"could not save {output}")
    print(f"\nsaved {output}  ({time.perf_counter() - start:.1f} s in all)")


def main() -> int:
    arguments = parse_arguments(sys.argv)
    try:
        run(arguments.output)
    except Exception as error:  # noqa: BLE001 - any failure must become a non-zero exit code, also under `blender -b`
        return failed("demo", error)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
