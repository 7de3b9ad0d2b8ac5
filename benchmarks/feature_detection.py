"""Feature detection timings (not a test): ``TargetMesh.principal_curvatures`` and ``detect_features``.

    .venv/bin/python benchmarks/feature_detection.py [--off MESH.off ...] [--repeats 3]

Always times a cube sphere of about 200k triangles (radius 1) and a rounded box (half-size 1,
blend radius 0.25) of about 200k triangles at two scales; ``--off`` adds real meshes (e.g.
``fandisk.off`` / ``bunny00.off`` from Debian's ``libcgal-demo``, see /work/shared/DATA.md), at
3 mean edge lengths. Prints the best of ``--repeats`` runs per line (wall time, and CPU time over all threads).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import springwrap_kernel as sk

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from helpers import rounded_box


def read_off(path: Path):
    """Vertices and triangles of an OFF file (polygons fanned into triangles)."""
    words = path.read_text().split()
    assert words[0] == "OFF", f"{path} is not an OFF file"
    vertex_count, face_count = int(words[1]), int(words[2])
    numbers = words[4:]
    vertices = np.array(numbers[: 3 * vertex_count], dtype=np.float32).reshape(-1, 3)
    triangles, at = [], 3 * vertex_count
    for _ in range(face_count):
        size = int(numbers[at])
        corners = [int(x) for x in numbers[at + 1 : at + 1 + size]]
        triangles += [(corners[0], corners[i], corners[i + 1]) for i in range(1, size - 1)]
        at += 1 + size
    return np.ascontiguousarray(vertices), np.ascontiguousarray(np.array(triangles, dtype=np.uint32))


def mean_edge(vertices, triangles):
    corners = vertices[triangles.astype(np.int64)]
    return float(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean())


def best_time(work, repeats):
    """(best wall time, its CPU time over all threads, result): CPU time says more on a shared machine."""
    runs = []
    for _ in range(repeats):
        start, cpu_start = time.perf_counter(), time.process_time()
        result = work()
        runs.append((time.perf_counter() - start, time.process_time() - cpu_start))
    wall, cpu = min(runs)
    return (wall, cpu), result


def measure(name, vertices, triangles, scale, repeats):
    mesh = sk.TargetMesh(vertices, triangles)
    mesh.prepare_all()
    (curvature_time, curvature_cpu), _ = best_time(lambda: mesh.principal_curvatures(scale), repeats)
    try:
        (detect_time, detect_cpu), features = best_time(lambda: mesh.detect_features(scale), repeats)
        counts = np.bincount(features.regions, minlength=4)
        kinds = [curve.kind for curve in features.curves]
        found = (
            f"{counts[0]} flat / {counts[1]} convex / {counts[2]} concave / {counts[3]} saddle, "
            f"{kinds.count('RIDGE')} ridges, {kinds.count('VALLEY')} valleys"
        )
    except sk.FlatSurfaceError:
        detect_time, detect_cpu, found = float("nan"), float("nan"), "flat"
    print(
        f"{name}: {vertices.shape[0]} vertices, {triangles.shape[0]} triangles, scale {scale:.4g} "
        f"({scale / mean_edge(vertices, triangles):.1f} edges): curvatures {curvature_time:.3f} s "
        f"(CPU {curvature_cpu:.2f} s), detect_features {detect_time:.3f} s (CPU {detect_cpu:.2f} s); {found}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--off", type=Path, nargs="*", default=[])
    parser.add_argument("--repeats", type=int, default=3)
    arguments = parser.parse_args()
    vertices, triangles = rounded_box(1.0, 1.0, 129)
    for scale_edges in (3.0, 10.0):
        measure("cube sphere", vertices, triangles, scale_edges * mean_edge(vertices, triangles), arguments.repeats)
    vertices, triangles = rounded_box(1.0, 0.25, 129)
    for scale in (0.05, 0.25):
        measure("rounded box", vertices, triangles, scale, arguments.repeats)
    for path in arguments.off:
        vertices, triangles = read_off(path)
        measure(path.name, vertices, triangles, 3.0 * mean_edge(vertices, triangles), arguments.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
