"""Metrics of a retargeted layout against the ground truth (issue 4, item 3). numpy only.

For a result (the layout's vertex positions after a method ran) and a case:

- **error**: per-vertex distance to the true position; mean, 95th percentile and max, in model
  units and in % of the truth's bounding-box diagonal; over all vertices, over those with target
  surface under them, over hole regions, over cavities;
- **surface distance**: distance from each vertex to the target surface (the kernel's exact
  ``closest_points``), for the vertices where the surface exists (not over a hole, not in a cavity);
- **flipped quads**: the result's quad normal points against the true layout's quad normal;
- **degenerate quads**: a result quad whose area is below :data:`DEGENERATE_AREA_FRACTION` of its
  true area (collapsed), or that is not finite;
- **angle distortion**: mean absolute difference of the quads' corner angles, in degrees;
- **non-finite vertices**: result vertices with a NaN or infinite coordinate (their error counts
  as infinite, so the mean and the max are then ``inf``);
- **time** and **peak memory** (:class:`Measurement`).

Quad normals and areas use the diagonals: ``n = (p2 - p0) x (p3 - p1)``, area ``|n| / 2`` (exact
for planar quads, the area of the mean plane's projection otherwise).
"""

from __future__ import annotations

import os
import time
import tracemalloc
from dataclasses import dataclass, field

import numpy as np

DEGENERATE_AREA_FRACTION = 0.01


@dataclass(frozen=True)
class ErrorStats:
    """Summary of non-negative per-vertex values (distances)."""

    count: int
    mean: float
    p95: float
    max: float

    @classmethod
    def of(cls, values: np.ndarray, mask: np.ndarray | None = None) -> ErrorStats:
        """Stats of ``values[mask]``; NaN fields when nothing is selected."""
        selected = np.asarray(values, dtype=np.float64)
        if mask is not None:
            selected = selected[mask]
        if len(selected) == 0:
            return cls(0, float("nan"), float("nan"), float("nan"))
        with np.errstate(invalid="ignore"):  # inf errors (non-finite results) interpolate to nan or inf
            p95 = float(np.percentile(selected, 95))
        return cls(len(selected), float(selected.mean()), p95, float(selected.max()))

    def scaled(self, factor: float) -> ErrorStats:
        """The same stats multiplied by ``factor`` (e.g. 100 / diagonal for percent)."""
        return ErrorStats(self.count, self.mean * factor, self.p95 * factor, self.max * factor)


def vertex_errors(result: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(N,) distance of each result vertex to its true position (``inf`` for non-finite results)."""
    errors = np.linalg.norm(np.asarray(result, dtype=np.float64) - truth, axis=1)
    return np.where(np.isfinite(errors), errors, np.inf)


def quad_normals(positions: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(F, 3) unnormalised quad normals from the diagonals; their length is twice the quad's area."""
    corners = np.asarray(positions, dtype=np.float64)[quads]
    return np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])


def flipped_quads(result: np.ndarray, truth: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(F,) bool: the result's quad normal points against the true quad's (degenerate ones excluded)."""
    result_normals, true_normals = quad_normals(result, quads), quad_normals(truth, quads)
    return (result_normals * true_normals).sum(axis=1) < 0.0


def degenerate_quads(result: np.ndarray, truth: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(F,) bool: the result's quad has collapsed below the fraction of its true area, or is not finite."""
    result_area = np.linalg.norm(quad_normals(result, quads), axis=1) / 2.0
    true_area = np.linalg.norm(quad_normals(truth, quads), axis=1) / 2.0
    return ~np.isfinite(result_area) | (result_area < DEGENERATE_AREA_FRACTION * true_area)


def corner_angles(positions: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(F, 4) interior angle (radians) at each corner of each quad, between its two edges."""
    corners = np.asarray(positions, dtype=np.float64)[quads]
    to_next = np.roll(corners, -1, axis=1) - corners
    to_previous = np.roll(corners, 1, axis=1) - corners
    cosine = (to_next * to_previous).sum(axis=2)
    sine = np.linalg.norm(np.cross(to_next, to_previous), axis=2)
    return np.arctan2(sine, cosine)


def angle_distortion_degrees(result: np.ndarray, truth: np.ndarray, quads: np.ndarray) -> float:
    """Mean absolute difference (degrees) between the result's and the truth's quad corner angles."""
    difference = np.abs(corner_angles(result, quads) - corner_angles(truth, quads))
    finite = np.isfinite(difference)
    return float(np.degrees(difference[finite].mean())) if finite.any() else float("nan")


def surface_distances(points: np.ndarray, target) -> np.ndarray:
    """(N,) distance of each point to the target surface (a ``springwrap_kernel.TargetMesh``)."""
    points = np.ascontiguousarray(points, dtype=np.float32)
    finite = np.isfinite(points).all(axis=1)
    distances = np.full(len(points), np.inf)
    if finite.any():
        distances[finite] = target.closest_points(np.ascontiguousarray(points[finite])).distances
    return distances


@dataclass
class CaseMetrics:
    """All accuracy and quality metrics of one result on one case."""

    diagonal: float
    error: ErrorStats  # all vertices, model units
    error_percent: ErrorStats  # all vertices, % of the diagonal
    error_on_surface_percent: ErrorStats  # vertices with target surface under their true position
    error_over_holes_percent: ErrorStats
    error_in_cavities_percent: ErrorStats
    surface_distance_percent: ErrorStats  # vertices where the surface exists
    flipped_quads: int
    degenerate_quads: int
    quad_count: int
    angle_distortion_degrees: float
    anchor_error_percent: float  # mean error at the landmark (anchor) vertices
    nonfinite_vertices: int = 0  # result vertices with a NaN or infinite coordinate (their error is inf)

    def row(self) -> dict:
        """A flat dict (for JSON and tables)."""
        flat = {"diagonal": self.diagonal}
        for name in ("error", "error_percent", "error_on_surface_percent", "error_over_holes_percent",
                     "error_in_cavities_percent", "surface_distance_percent"):
            stats = getattr(self, name)
            flat.update({f"{name}_mean": stats.mean, f"{name}_p95": stats.p95, f"{name}_max": stats.max,
                         f"{name}_count": stats.count})
        flat.update(flipped_quads=self.flipped_quads, degenerate_quads=self.degenerate_quads,
                    quad_count=self.quad_count, angle_distortion_degrees=self.angle_distortion_degrees,
                    anchor_error_percent=self.anchor_error_percent, nonfinite_vertices=self.nonfinite_vertices)
        return flat


def evaluate(
    result: np.ndarray,
    truth: np.ndarray,
    quads: np.ndarray,
    target,
    over_hole: np.ndarray,
    in_cavity: np.ndarray,
    anchor_vertices: np.ndarray,
) -> CaseMetrics:
    """Every metric of ``result`` ((N, 3) positions) against ``truth`` on a target (a kernel ``TargetMesh``)."""
    result = np.asarray(result, dtype=np.float64)
    diagonal = float(np.linalg.norm(truth.max(axis=0) - truth.min(axis=0)))
    percent = 100.0 / diagonal
    errors = vertex_errors(result, truth)
    on_surface = ~over_hole & ~in_cavity
    surface = surface_distances(result, target)
    return CaseMetrics(
        diagonal=diagonal,
        error=ErrorStats.of(errors),
        error_percent=ErrorStats.of(errors).scaled(percent),
        error_on_surface_percent=ErrorStats.of(errors, on_surface).scaled(percent),
        error_over_holes_percent=ErrorStats.of(errors, over_hole).scaled(percent),
        error_in_cavities_percent=ErrorStats.of(errors, in_cavity).scaled(percent),
        surface_distance_percent=ErrorStats.of(surface, on_surface).scaled(percent),
        flipped_quads=int(flipped_quads(result, truth, quads).sum()),
        degenerate_quads=int(degenerate_quads(result, truth, quads).sum()),
        quad_count=len(quads),
        angle_distortion_degrees=angle_distortion_degrees(result, truth, quads),
        anchor_error_percent=float(errors[anchor_vertices].mean() * percent) if len(anchor_vertices) else float("nan"),
        nonfinite_vertices=int((~np.isfinite(result).all(axis=1)).sum()),
    )


# ---------------------------------------------------------------- time and memory


def _status_kilobytes(field_name: str) -> int | None:
    """A ``kB`` field of ``/proc/self/status`` (Linux), or None."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field_name + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _reset_peak_rss() -> bool:
    """Reset the process's peak resident size (Linux: write 5 to /proc/self/clear_refs)."""
    try:
        with open("/proc/self/clear_refs", "w") as clear_refs:
            clear_refs.write("5")
        return True
    except OSError:
        return False


@dataclass
class Measurement:
    """Wall time and peak memory of a block: ``with Measurement() as measured: ...``.

    Peak memory is the growth of the process's peak resident set over the block (Linux
    ``VmHWM``, reset at entry: native allocations of Blender and the kernel count). Where that
    is not available it falls back to Python allocations only (``tracemalloc``) and says so in
    ``memory_source``."""

    seconds: float = 0.0
    peak_megabytes: float = float("nan")
    memory_source: str = ""
    _start: float = field(default=0.0, repr=False)
    _rss_before: int | None = field(default=None, repr=False)

    def __enter__(self) -> Measurement:
        if os.name == "posix" and _reset_peak_rss():
            self._rss_before = _status_kilobytes("VmRSS")
        if self._rss_before is None:
            tracemalloc.start()
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exc_info) -> None:
        self.seconds = time.perf_counter() - self._start
        if self._rss_before is not None:
            peak = _status_kilobytes("VmHWM")
            self.peak_megabytes = max(0.0, (peak - self._rss_before) / 1024.0) if peak is not None else float("nan")
            self.memory_source = "peak RSS growth (VmHWM)"
        else:
            _current, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            self.peak_megabytes = peak / (1024.0 * 1024.0)
            self.memory_source = "Python allocations (tracemalloc)"
