"""Closest-point ("snap") throughput: the Springwrap kernel against Blender's own tools.

    .venv/bin/python benchmarks/snap_throughput.py [--quick] [--triangles N] [--points N] [--json PATH]

One target (a deterministic noise-displaced torus, ~1M triangles by default) and one set of
query points (~1M, the vertices of a second grid over the same surface, pushed off it), asked
in two orders: *coherent* (mesh-vertex order) and *random* (the same points shuffled).

- kernel: ``springwrap_kernel.TargetMesh(vertices, triangles)`` build (the face tree; the
  closest-point tree, vertex tree, adjacency and normals are built on first use and timed apart
  with ``prepare_all()``),
  then ``closest_points`` and ``nearest_vertices`` (best of ``--repeat`` runs).
- Blender's Shrinkwrap modifier (``NEAREST_SURFACEPOINT``) on a vertices-only mesh holding the
  points: the timed part is the depsgraph evaluation plus reading the positions back. Its
  "build" is a first evaluation with a few points, which builds and caches Blender's BVH of the
  target.
- the operator: ``springwrap.snap`` on a quad layout of about as many vertices over the target, its quality
  read-out included (its share timed apart), against Shrinkwrap on the same layout (``_snap_operator.py``).
- ``mathutils.bvhtree.BVHTree``: ``FromPolygons`` build, then ``find_nearest`` once per point in
  a Python loop, on the first ``--mathutils-points`` (200k) points of each order; the time for
  all points is extrapolated from it and the table says so.

Every result is checked against the others; the script exits non-zero on a mismatch.
"""

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils.bvhtree import BVHTree
from mathutils.kdtree import KDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _machine
from _noisy_torus import QUERY_OFFSET, noisy_torus, query_points

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "blender_scripts"))
from headless import script_arguments

SEED = 1
# Distances may differ by float32 rounding; relative to the target's bounding-box diagonal.
DISTANCE_TOLERANCE = 1e-5
# The Python loop over find_nearest takes about a minute per million random points on a small
# machine; its cost per query does not depend on how many are asked, so a subset is timed.
MATHUTILS_POINTS = 200_000
# How many points the nearest-vertex result is checked on (against mathutils.kdtree).
VERTEX_CHECK_POINTS = 10_000


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the script's arguments (those after ``--`` when run under ``blender``)."""
    argv = script_arguments(argv, __file__)
    parser = argparse.ArgumentParser(prog="snap_throughput.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100k triangles and 100k points")
    parser.add_argument("--triangles", type=int, help="target triangle count (default 1,000,000; --quick 100,000)")
    parser.add_argument("--points", type=int, help="query point count (default 1,000,000; --quick 100,000)")
    parser.add_argument(
        "--mathutils-points",
        type=int,
        default=MATHUTILS_POINTS,
        help=f"time mathutils find_nearest on at most this many points per order and extrapolate "
        f"(default {MATHUTILS_POINTS:,}; 0 for all)",
    )
    parser.add_argument(
        "--repeat", type=int, default=3, help="kernel runs per measurement, the best is kept (default 3)"
    )
    parser.add_argument("--json", type=Path, help="also write the numbers to this JSON file")
    arguments = parser.parse_args(argv)
    default_size = 100_000 if arguments.quick else 1_000_000
    arguments.triangles = arguments.triangles or default_size
    arguments.points = arguments.points or default_size
    if arguments.triangles < 8 or arguments.points < 1 or arguments.repeat < 1:
        parser.error("--triangles must be >= 8, --points and --repeat >= 1")
    if arguments.mathutils_points <= 0:
        arguments.mathutils_points = arguments.points
    arguments.mathutils_points = min(arguments.mathutils_points, arguments.points)
    return arguments


# ---------------------------------------------------------------- environment


def machine_description() -> dict:
    """CPU, core count and platform of this machine."""
    cpu_model = _machine.cpu_model()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu_model,
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "platform": platform.platform(),
        "python": platform.python_version(),
        # Other work on the machine skews the numbers; the 1-minute load average at the start says how much.
        "load_average": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None,
    }


def versions(kernel) -> dict:
    """Versions of everything measured, which build of the kernel's native module, and the git commit."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from benchmarks.retarget.run import git_commit, kernel_build

    return {
        "bpy": bpy.app.version_string,
        "numpy": np.__version__,
        "springwrap_kernel": kernel.__version__,
        "kernel_build": kernel_build(),
        "git_commit": git_commit(),
    }


# ---------------------------------------------------------------- measurements


@dataclass
class Row:
    """One line of the result table."""

    method: str
    order: str
    queries: int  # the number the seconds are for
    measured_queries: int  # the number actually run (smaller when extrapolated)
    seconds: float
    build_seconds: float

    @property
    def queries_per_second(self) -> float:
        return self.queries / self.seconds if self.seconds > 0 else float("inf")

    @property
    def extrapolated(self) -> bool:
        return self.measured_queries != self.queries


def best_time(function, repeat: int):
    """Run ``function`` ``repeat`` times; return (the shortest time, the last result)."""
    best = float("inf")
    result = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result


def measure_kernel(kernel, vertices, triangles, orders: dict[str, np.ndarray], repeat: int):
    """Build a TargetMesh and time closest_points / nearest_vertices per order.

    Returns (rows, the mesh, {order: SurfaceHits}, {order: VertexHits})."""
    build_seconds, mesh = best_time(lambda: kernel.TargetMesh(vertices, triangles), repeat)
    # The closest-point tree, vertex tree, adjacency and normals are built on first use;
    # time them on their own.
    start = time.perf_counter()
    mesh.prepare_all()
    prepare_seconds = time.perf_counter() - start
    print(
        f"kernel: TargetMesh(...) {build_seconds:.3f} s (face tree); "
        f"prepare_all() {prepare_seconds:.3f} s (closest-point tree, vertex tree, adjacency, normals)"
    )
    mesh.closest_points(orders["coherent"][:64])  # start the thread pool outside the timing
    rows, surface_hits, vertex_hits = [], {}, {}
    for order, points in orders.items():
        seconds, surface_hits[order] = best_time(lambda points=points: mesh.closest_points(points), repeat)
        rows.append(Row("kernel closest_points", order, len(points), len(points), seconds, build_seconds))
    for order, points in orders.items():
        seconds, vertex_hits[order] = best_time(lambda points=points: mesh.nearest_vertices(points), repeat)
        rows.append(Row("kernel nearest_vertices", order, len(points), len(points), seconds, build_seconds))
    return rows, mesh, surface_hits, vertex_hits


def mesh_object(name: str, vertices: np.ndarray, triangles: np.ndarray | None = None) -> bpy.types.Object:
    """A new object linked to the scene, its mesh filled with foreach_set (vertices only if no triangles)."""
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", vertices.ravel())
    if triangles is not None:
        mesh.loops.add(triangles.size)
        mesh.loops.foreach_set("vertex_index", triangles.ravel().astype(np.int32))
        mesh.polygons.add(len(triangles))
        mesh.polygons.foreach_set("loop_start", np.arange(0, triangles.size, 3, dtype=np.int32))
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def evaluated_positions(obj: bpy.types.Object) -> np.ndarray:
    """Evaluate the depsgraph and read ``obj``'s evaluated vertex positions, (N, 3) float32."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    positions = np.empty(len(evaluated.data.vertices) * 3, dtype=np.float32)
    evaluated.data.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3)


def measure_shrinkwrap(vertices, triangles, orders: dict[str, np.ndarray]):
    """Time Blender's Shrinkwrap (NEAREST_SURFACEPOINT) per order.

    Returns (rows, {order: evaluated positions})."""
    target = mesh_object("SnapTarget", vertices, triangles)
    clouds = {"warm-up": mesh_object("SnapWarmUp", orders["coherent"][:64])}
    clouds.update({order: mesh_object(f"SnapPoints_{order}", points) for order, points in orders.items()})
    modifiers = {}
    for name, cloud in clouds.items():
        modifier = cloud.modifiers.new("Shrinkwrap", "SHRINKWRAP")
        modifier.wrap_method = "NEAREST_SURFACEPOINT"
        modifier.target = target
        modifier.show_viewport = False
        modifiers[name] = modifier
    bpy.context.evaluated_depsgraph_get()  # everything evaluated once, every Shrinkwrap off

    # The first Shrinkwrap on this target builds Blender's BVH of it, cached on the evaluated target.
    modifiers["warm-up"].show_viewport = True
    start = time.perf_counter()
    evaluated_positions(clouds["warm-up"])
    build_seconds = time.perf_counter() - start

    rows, positions = [], {}
    for order, points in orders.items():
        modifiers[order].show_viewport = True
        start = time.perf_counter()
        positions[order] = evaluated_positions(clouds[order])
        seconds = time.perf_counter() - start
        rows.append(Row("Shrinkwrap NEAREST_SURFACEPOINT", order, len(points), len(points), seconds, build_seconds))
    return rows, positions


def measure_mathutils(vertices, triangles, orders: dict[str, np.ndarray], subset_size: int):
    """Time mathutils BVHTree.FromPolygons and find_nearest in a Python loop, per order.

    Returns (rows, the vertices as a list, {order: distances of the subset})."""
    vertex_list = vertices.tolist()
    triangle_list = triangles.tolist()
    start = time.perf_counter()
    tree = BVHTree.FromPolygons(vertex_list, triangle_list, all_triangles=True)
    build_seconds = time.perf_counter() - start
    find_nearest = tree.find_nearest
    rows, distances = [], {}
    for order, points in orders.items():
        subset = points[:subset_size].tolist()
        start = time.perf_counter()
        subset_distances = [find_nearest(point)[3] for point in subset]
        seconds = time.perf_counter() - start
        distances[order] = np.array(subset_distances, dtype=np.float64)  # None (no hit) becomes nan
        rows.append(
            Row(
                "mathutils BVHTree.find_nearest",
                order,
                len(points),
                len(subset),
                seconds * len(points) / len(subset),
                build_seconds,
            )
        )
    return rows, vertex_list, distances


# ---------------------------------------------------------------- checks


@dataclass
class Check:
    """One correctness comparison."""

    name: str
    compared: int
    max_difference: float
    tolerance: float

    @property
    def passed(self) -> bool:
        return bool(self.max_difference <= self.tolerance)


def run_checks(
    orders,
    permutation,
    mesh,
    surface_hits,
    vertex_hits,
    shrinkwrap_positions,
    mathutils_distances,
    vertex_list,
    tolerance,
) -> list[Check]:
    """Compare the kernel with Shrinkwrap, mathutils BVHTree and mathutils KDTree."""
    checks = []
    for order, hits in surface_hits.items():
        if (hits.triangles < 0).any():
            checks.append(
                Check(
                    f"kernel closest_points {order}: queries without a hit",
                    len(hits.triangles),
                    float((hits.triangles < 0).sum()),
                    0.0,
                )
            )
    coherent = surface_hits["coherent"]
    # The random order is the coherent one shuffled: its answers must be the same answers, shuffled.
    checks.append(
        Check(
            "kernel closest_points, random vs coherent order (distance)",
            len(permutation),
            float(np.abs(surface_hits["random"].distances - coherent.distances[permutation]).max()),
            tolerance,
        )
    )
    for order, _points in orders.items():
        distances = mathutils_distances[order]
        kernel_distances = surface_hits[order].distances[: len(distances)]
        checks.append(
            Check(
                f"|kernel - mathutils find_nearest| distance, {order}",
                len(distances),
                float(np.nan_to_num(np.abs(kernel_distances - distances), nan=np.inf).max()),
                tolerance,
            )
        )
    for order, points in orders.items():
        positions = shrinkwrap_positions[order]
        moved = np.linalg.norm(positions - points, axis=1)
        checks.append(
            Check(
                f"|kernel - Shrinkwrap| distance, {order}",
                len(points),
                float(np.abs(moved - surface_hits[order].distances).max()),
                tolerance,
            )
        )
    # Shrinkwrap really ran: its outputs lie on the surface (a no-op would leave them off it).
    on_surface = mesh.closest_points(shrinkwrap_positions["random"])
    checks.append(
        Check(
            "Shrinkwrap output's distance to the surface (kernel), random",
            len(on_surface.distances),
            float(on_surface.distances.max()),
            tolerance,
        )
    )
    # Nearest vertex against a KD-tree, on a sample.
    tree = KDTree(len(vertex_list))
    for index, position in enumerate(vertex_list):
        tree.insert(position, index)
    tree.balance()
    sample = orders["random"][:VERTEX_CHECK_POINTS]
    kd_distances = np.array([tree.find(point)[2] for point in sample.tolist()])
    checks.append(
        Check(
            "|kernel nearest_vertices - mathutils KDTree| distance, random",
            len(sample),
            float(np.abs(vertex_hits["random"].distances[: len(sample)] - kd_distances).max()),
            tolerance,
        )
    )
    return checks


# ---------------------------------------------------------------- report


def print_report(machine, version_info, sizes, rows: list[Row], checks: list[Check]) -> None:
    """Print the environment, the throughput table and the checks."""
    print(
        f"machine:  {machine['cpu']}, {machine['cpu_count']} CPUs ({machine['usable_cpus']} usable), "
        f"{machine['platform']}, Python {machine['python']}, load average {machine['load_average']}"
    )
    print("versions: " + ", ".join(f"{name} {version}" for name, version in version_info.items()))
    print(
        f"target:   noisy torus, {sizes['target_vertices']:,} vertices, {sizes['target_triangles']:,} triangles; "
        f"queries: {sizes['points']:,} points within {sizes['query_offset']} of the surface\n"
    )
    header = f"{'method':<32} {'order':<9} {'queries':>10} {'seconds':>9} {'queries/s':>12} {'build (s)':>10}  note"
    print(header)
    print("-" * (len(header) + 24))
    for row in rows:
        note = f"extrapolated from {row.measured_queries:,}" if row.extrapolated else ""
        print(
            f"{row.method:<32} {row.order:<9} {row.queries:>10,} {row.seconds:>9.3f} "
            f"{row.queries_per_second:>12,.0f} {row.build_seconds:>10.3f}  {note}"
        )
    print(
        "\ncoherent: the points in mesh-vertex order (a second grid over the surface); "
        "random: the same points shuffled."
    )
    print(
        "kernel: best of the repeats; build = TargetMesh(...) (the face tree; the closest-point and vertex trees are built by prepare_all(), printed above)."
    )
    print("Shrinkwrap: depsgraph evaluation + reading positions; build = first evaluation (Blender's target BVH).")
    print("mathutils: one find_nearest call per point in a Python loop; build = FromPolygons from Python lists.")
    print(
        "layout: a quad layout over another displaced torus, snapped by the operator (detach, snap, the quality "
        "read-out measured and written) and by Shrinkwrap on the same vertices; best of the repeats.\n"
    )
    print("checks:")
    for check in checks:
        status = "ok" if check.passed else "MISMATCH"
        print(
            f"  {status:<8} {check.name}: max {check.max_difference:.3g} over {check.compared:,} "
            f"(tolerance {check.tolerance:.3g})"
        )


def main() -> int:
    arguments = parse_arguments(sys.argv)
    machine = machine_description()  # before the work, for the load average
    try:
        import springwrap_kernel as kernel
    except ImportError as error:
        print(f"snap_throughput: cannot import springwrap_kernel ({error}); run `make setup` first", file=sys.stderr)
        return 2

    bpy.ops.wm.read_factory_settings(use_empty=True)
    vertices, triangles = noisy_torus(arguments.triangles, seed=SEED)
    coherent = query_points(arguments.points, seed=SEED)
    permutation = np.random.default_rng(SEED).permutation(len(coherent))
    orders = {"coherent": coherent, "random": np.ascontiguousarray(coherent[permutation])}
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    sizes = {
        "target_vertices": len(vertices),
        "target_triangles": len(triangles),
        "points": len(coherent),
        "mathutils_points": arguments.mathutils_points,
        "query_offset": QUERY_OFFSET,
        "seed": SEED,
    }

    kernel_rows, mesh, surface_hits, vertex_hits = measure_kernel(kernel, vertices, triangles, orders, arguments.repeat)
    shrinkwrap_rows, shrinkwrap_positions = measure_shrinkwrap(vertices, triangles, orders)
    mathutils_rows, vertex_list, mathutils_distances = measure_mathutils(
        vertices, triangles, orders, arguments.mathutils_points
    )
    import _snap_operator

    operator = _snap_operator.measure(bpy, vertices, triangles, arguments.points, arguments.repeat)
    rows = kernel_rows + shrinkwrap_rows + mathutils_rows
    count = operator["layout_vertices"]
    rows += [
        Row("springwrap.snap operator (read-out incl.)", "layout", count, count, operator["seconds"], 0.0),
        Row("  of which the read-out", "layout", count, count, operator["readout_seconds"], 0.0),
        Row("Shrinkwrap modifier, same layout", "layout", count, count, operator["shrinkwrap_seconds"], 0.0),
    ]
    checks = run_checks(
        orders,
        permutation,
        mesh,
        surface_hits,
        vertex_hits,
        shrinkwrap_positions,
        mathutils_distances,
        vertex_list,
        DISTANCE_TOLERANCE * diagonal,
    )

    version_info = versions(kernel)
    print_report(machine, version_info, sizes, rows, checks)
    if arguments.json:
        report = {
            "machine": machine,
            "versions": version_info,
            "finished_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "sizes": sizes,
            "results": [
                asdict(row) | {"queries_per_second": row.queries_per_second, "extrapolated": row.extrapolated}
                for row in rows
            ],
            "checks": [asdict(check) | {"passed": check.passed} for check in checks],
            "operator": operator,
        }
        arguments.json.parent.mkdir(parents=True, exist_ok=True)
        arguments.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"\nwrote {arguments.json}")
    if not all(check.passed for check in checks):
        print("snap_throughput: a check failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
