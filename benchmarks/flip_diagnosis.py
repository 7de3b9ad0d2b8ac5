"""Where a method's flipped quads are and how they turned: one line per quad flipped against the truth.

    .venv/bin/python -m benchmarks.flip_diagnosis CASE POSITIONS.npz [--method "Springwrap wrap"]

``POSITIONS.npz`` is what ``benchmarks.retarget.run --positions FOLDER`` saves per case (every method's layout
positions, the truth, the quads); the case's target is read from the benchmark's cache. For each quad whose
normal points against the true quad's (the retargeting metric's *flipped quads*) it prints the corners' mean
error (% of the diagonal), the angles between the result's quad normal and the true one, the target's normal
under the result's centre and the aligned template's quad, the true quad's angle to the target's normal under
its own centre, the result's area over the true one, and how deep the true quad's deepest corner lies under the
target's surface (% of the diagonal, along the normal of its closest target triangle; 0 when no corner is under
it). A quad flipped by a fold of the wrap faces away from the target; one that lies flat on the wrong wall of a
crease faces the target and its template, while its true quad is turned far from both — and sinks under the
surface where the target (a voxel remesh) fills the crease: no result on the surface can face as it does. No
``bpy`` here.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.retarget import cases
from benchmarks.retarget.metrics import flipped_quads, quad_normals

TEMPLATE = "aligned template"
"""The method whose quads stand for the template's orientation."""


@dataclass(frozen=True)
class FlippedQuad:
    """One quad of a result flipped against the truth, and how it sits (angles in degrees)."""

    quad: int
    centre: tuple[float, float, float]
    error_percent: float
    to_truth: float
    to_target: float
    to_template: float
    truth_to_target: float
    area_ratio: float
    truth_depth_percent: float = 0.0

    def line(self) -> str:
        x, y, z = self.centre
        return (
            f"quad {self.quad:>6} at ({x:.3f}, {y:.3f}, {z:.3f}): error {self.error_percent:.2f} %, "
            f"against the truth {self.to_truth:.0f}°, the target {self.to_target:.0f}°, the template "
            f"{self.to_template:.0f}°; the truth against the target {self.truth_to_target:.0f}°; "
            f"area {self.area_ratio:.2f}× the true one; the truth {self.truth_depth_percent:.2f} % under the target"
        )


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two vectors (90 when either has no length)."""
    lengths = np.linalg.norm(a) * np.linalg.norm(b)
    if lengths == 0.0:
        return 90.0
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b) / lengths, -1.0, 1.0))))


def _nearest_triangle_normal(triangle_centres: np.ndarray, triangle_normals: np.ndarray, point: np.ndarray):
    """The normal of the target triangle whose centre is nearest ``point``."""
    return triangle_normals[int(np.argmin(((triangle_centres - point) ** 2).sum(axis=1)))]


def depths_under(points: np.ndarray, target_vertices: np.ndarray, target_triangles: np.ndarray) -> np.ndarray:
    """(N,) how far each point lies under the target's surface: its distance to its closest target point when it is
    on the inner side of that triangle (against the winding's normal), else 0."""
    import springwrap_kernel

    target = springwrap_kernel.TargetMesh(
        np.ascontiguousarray(target_vertices, dtype=np.float32), np.ascontiguousarray(target_triangles, dtype=np.uint32)
    )
    points = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
    hits = target.closest_points(points)
    normals = target.face_normals()[hits.triangles]
    inside = ((points - hits.positions) * normals).sum(axis=1) < 0.0
    return np.where(inside, hits.distances, 0.0).astype(np.float64)


def diagnose(
    result: np.ndarray,
    truth: np.ndarray,
    template: np.ndarray,
    quads: np.ndarray,
    target_vertices: np.ndarray,
    target_triangles: np.ndarray,
) -> list[FlippedQuad]:
    """The quads of ``result`` flipped against ``truth``, each with how it sits (see the module docstring)."""
    result, truth, template = (np.asarray(p, dtype=np.float64) for p in (result, truth, template))
    corners = np.asarray(target_vertices, dtype=np.float64)[np.asarray(target_triangles)]
    triangle_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    triangle_centres = corners.mean(axis=1)
    diagonal = cases.bounding_box_diagonal(truth)
    result_normals, true_normals = quad_normals(result, quads), quad_normals(truth, quads)
    template_normals = quad_normals(template, quads)
    found = []
    flipped = np.flatnonzero(flipped_quads(result, truth, quads))
    if len(flipped) == 0:
        return found
    depths = depths_under(truth[quads[flipped]], target_vertices, target_triangles).reshape(len(flipped), -1)
    for quad, depth in zip(flipped, depths.max(axis=1), strict=True):
        centre = result[quads[quad]].mean(axis=0)
        true_centre = truth[quads[quad]].mean(axis=0)
        errors = np.linalg.norm(result[quads[quad]] - truth[quads[quad]], axis=1)
        true_area = np.linalg.norm(true_normals[quad])
        found.append(
            FlippedQuad(
                quad=int(quad),
                centre=tuple(float(c) for c in centre),
                error_percent=float(errors.mean() / diagonal * 100.0),
                to_truth=_angle(result_normals[quad], true_normals[quad]),
                to_target=_angle(
                    result_normals[quad], _nearest_triangle_normal(triangle_centres, triangle_normals, centre)
                ),
                to_template=_angle(result_normals[quad], template_normals[quad]),
                truth_to_target=_angle(
                    true_normals[quad], _nearest_triangle_normal(triangle_centres, triangle_normals, true_centre)
                ),
                area_ratio=float(np.linalg.norm(result_normals[quad]) / true_area) if true_area > 0.0 else float("inf"),
                truth_depth_percent=float(depth / diagonal * 100.0),
            )
        )
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="flip_diagnosis.py", description=__doc__.splitlines()[0])
    parser.add_argument("case", help="the case's name (its target is read from the benchmark's cache)")
    parser.add_argument("positions", type=Path, help="the case's .npz saved by benchmarks.retarget.run --positions")
    parser.add_argument("--method", default="Springwrap wrap")
    arguments = parser.parse_args(argv)
    case, _ = cases.get_case(cases.case_specs([arguments.case])[0])
    with np.load(arguments.positions) as stored:
        methods = [str(name) for name in stored["methods"]]
        for needed in (arguments.method, TEMPLATE):
            if needed not in methods:
                parser.error(f"{arguments.positions} has no {needed!r} positions (it has: {', '.join(methods)})")
        result = stored[f"positions_{methods.index(arguments.method)}"]
        template = stored[f"positions_{methods.index(TEMPLATE)}"]
        truth, quads = stored["true_positions"], stored["layout_quads"]
    found = diagnose(result, truth, template, quads, case.target_vertices, case.target_triangles)
    template_flips = int(flipped_quads(template, truth, quads).sum())
    print(f"{arguments.case}, {arguments.method}: {len(found)} flipped quads (the aligned template: {template_flips})")
    for flipped in found:
        print("  " + flipped.line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
