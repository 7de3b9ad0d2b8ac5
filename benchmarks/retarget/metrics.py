"""Metrics of a retargeted layout against the ground truth. numpy only.

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

For a scan without a known answer (:func:`scan_metrics`): the distance to the scan of the
vertices over its surface (not over a hole: their closest scan point is not on a hole's rim,
:func:`on_boundary`), quads turned over against the aligned template and against the scan's
triangle under their centre, and the stretch (quad area and edge length over the template's).

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
        for name in (
            "error",
            "error_percent",
            "error_on_surface_percent",
            "error_over_holes_percent",
            "error_in_cavities_percent",
            "surface_distance_percent",
        ):
            stats = getattr(self, name)
            flat.update(
                {
                    f"{name}_mean": stats.mean,
                    f"{name}_p95": stats.p95,
                    f"{name}_max": stats.max,
                    f"{name}_count": stats.count,
                }
            )
        flat.update(
            flipped_quads=self.flipped_quads,
            degenerate_quads=self.degenerate_quads,
            quad_count=self.quad_count,
            angle_distortion_degrees=self.angle_distortion_degrees,
            anchor_error_percent=self.anchor_error_percent,
            nonfinite_vertices=self.nonfinite_vertices,
        )
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


# ---------------------------------------------------------------- scans: no known answer

# A closest point whose barycentric for a corner is below this lies on the edge opposite it.
EDGE_BARYCENTRIC = 1e-4
# Stretch ratios (result / rest) outside [1 / STRETCH_LIMIT, STRETCH_LIMIT] are counted apart.
STRETCH_LIMIT = 10.0
# A vertex (or a quad's centre) farther than this from the scan, in % of its diagonal, is off it.
OFF_SURFACE_PERCENT = 0.1


def triangle_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) unnormalised triangle normals (right-handed about the corner order; length twice the area)."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles, dtype=np.int64)]
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def on_boundary(
    triangles: np.ndarray, hit_triangles: np.ndarray, barycentrics: np.ndarray, tolerance: float = EDGE_BARYCENTRIC
) -> np.ndarray:
    """(K,) bool: closest points (a triangle index and barycentrics each) that lie on the rim of a hole.

    A point is on the rim when it is on an edge used by one triangle only (the barycentric of the
    corner opposite that edge below ``tolerance``), or at a corner (two barycentrics below it) that
    such an edge ends at. A point floating over a hole has its closest point there."""
    triangles = np.asarray(triangles, dtype=np.int64)
    hit_triangles = np.asarray(hit_triangles, dtype=np.int64)
    barycentrics = np.asarray(barycentrics, dtype=np.float64)
    count = int(triangles.max()) + 1 if len(triangles) else 0
    pairs = np.sort(np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    keys = pairs[:, 0] * count + pairs[:, 1]
    unique, uses = np.unique(keys, return_counts=True)
    rim = unique[uses == 1]
    rim_vertices = np.zeros(count, dtype=bool)
    rim_vertices[pairs[np.isin(keys, rim)].ravel()] = True
    corners = triangles[hit_triangles]
    small = barycentrics < tolerance
    result = np.zeros(len(hit_triangles), dtype=bool)
    for corner in range(3):
        first, second = corners[:, (corner + 1) % 3], corners[:, (corner + 2) % 3]
        edge_keys = np.minimum(first, second) * count + np.maximum(first, second)
        result |= small[:, corner] & np.isin(edge_keys, rim)
    at_corner = small.sum(axis=1) >= 2
    nearest_corner = corners[np.arange(len(corners)), np.argmax(barycentrics, axis=1)]
    result |= at_corner & rim_vertices[nearest_corner]
    return result


def quad_areas(positions: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(F,) quad areas (half the diagonals' cross product)."""
    return np.linalg.norm(quad_normals(positions, quads), axis=1) / 2.0


def quad_edges(quads: np.ndarray) -> np.ndarray:
    """(E, 2) int64 unique undirected edges of (F, 4) quads, smaller index first."""
    quads = np.asarray(quads, dtype=np.int64)
    pairs = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(pairs, axis=1), axis=0)


def edge_length_ratios(result: np.ndarray, rest: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(E,) length of each layout edge in ``result`` over its length in ``rest`` (the template)."""
    edges = quad_edges(quads)
    result = np.asarray(result, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    lengths = np.linalg.norm(result[edges[:, 1]] - result[edges[:, 0]], axis=1)
    rest_lengths = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return lengths / rest_lengths


@dataclass(frozen=True)
class RatioStats:
    """The spread of stretch ratios (result / rest): 5th, 50th and 95th percentiles, and how many lie
    below ``1 / STRETCH_LIMIT`` (collapsed) or above ``STRETCH_LIMIT`` (blown up); non-finite ratios
    count as blown up."""

    count: int
    p5: float
    median: float
    p95: float
    below: int
    above: int

    @classmethod
    def of(cls, ratios: np.ndarray, limit: float = STRETCH_LIMIT) -> RatioStats:
        ratios = np.asarray(ratios, dtype=np.float64)
        finite = ratios[np.isfinite(ratios)]
        if len(finite) == 0:
            return cls(len(ratios), float("nan"), float("nan"), float("nan"), 0, len(ratios))
        p5, median, p95 = (float(value) for value in np.percentile(finite, [5, 50, 95]))
        return cls(
            len(ratios),
            p5,
            median,
            p95,
            int((finite < 1.0 / limit).sum()),
            int((finite > limit).sum() + (len(ratios) - len(finite))),
        )


@dataclass
class ScanMetrics:
    """What can be measured of a layout wrapped onto a scan without a known answer."""

    diagonal: float  # the scan's bounding-box diagonal
    distance_percent: ErrorStats  # to the scan, % of the diagonal, vertices over its surface
    over_surface: int  # vertices whose closest scan point is not on a hole's rim
    off_surface: int  # of those, the ones farther than OFF_SURFACE_PERCENT from the scan
    flipped_vs_template: int  # quads turned more than 90 degrees from the (aligned) template's quad
    flipped_vs_target: int  # quads facing against the scan's triangle under their centre (centre over the surface)
    flipped_vs_target_on_surface: int  # of those, the ones whose centre is within OFF_SURFACE_PERCENT of the scan
    quads_over_surface: int  # quads whose centre's closest scan point is not on a hole's rim
    area: RatioStats  # quad area, result / template
    edge: RatioStats  # edge length, result / template
    nonfinite_vertices: int = 0

    def row(self) -> dict:
        """A flat dict (for JSON and tables)."""
        flat = {
            "diagonal": self.diagonal,
            "distance_mean": self.distance_percent.mean,
            "distance_p95": self.distance_percent.p95,
            "distance_max": self.distance_percent.max,
            "over_surface": self.over_surface,
            "off_surface": self.off_surface,
            "flipped_vs_template": self.flipped_vs_template,
            "flipped_vs_target": self.flipped_vs_target,
            "flipped_vs_target_on_surface": self.flipped_vs_target_on_surface,
            "quads_over_surface": self.quads_over_surface,
            "nonfinite_vertices": self.nonfinite_vertices,
        }
        for name in ("area", "edge"):
            stats = getattr(self, name)
            flat.update(
                {
                    f"{name}_p5": stats.p5,
                    f"{name}_median": stats.median,
                    f"{name}_p95": stats.p95,
                    f"{name}_below": stats.below,
                    f"{name}_above": stats.above,
                }
            )
        return flat


def target_facing_flips(
    positions: np.ndarray,
    quads: np.ndarray,
    target,
    target_vertices: np.ndarray,
    target_triangles: np.ndarray,
    vertex_normals: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F,) bool quads facing against the target triangle under their centre's closest point, (F,)
    bool quads whose centre's closest point is over the target's surface (not on a hole's rim; flips
    are only counted there), and (F,) the distance of each centre to the target. Non-finite quads are
    neither, at an infinite distance. With ``vertex_normals`` ((V, 3), e.g. smoothed) the facing is
    judged against them, interpolated at the closest point, instead of the triangle's own normal."""
    positions = np.asarray(positions, dtype=np.float64)
    centres = positions[np.asarray(quads, dtype=np.int64)].mean(axis=1)
    finite = np.isfinite(centres).all(axis=1)
    flipped = np.zeros(len(quads), dtype=bool)
    over = np.zeros(len(quads), dtype=bool)
    distances = np.full(len(quads), np.inf)
    if finite.any():
        hits = target.closest_points(np.ascontiguousarray(centres[finite], dtype=np.float32))
        distances[finite] = hits.distances
        corners = np.asarray(target_triangles, dtype=np.int64)[hits.triangles]
        if vertex_normals is None:
            normals = triangle_normals(target_vertices, corners)
        else:
            weights = np.asarray(hits.barycentrics, dtype=np.float64)[:, :, None]
            normals = (np.asarray(vertex_normals, dtype=np.float64)[corners] * weights).sum(axis=1)
        facing = (quad_normals(positions, quads)[finite] * normals).sum(axis=1)
        over[finite] = ~on_boundary(target_triangles, hits.triangles, hits.barycentrics)
        flipped[finite] = over[finite] & (facing < 0.0)
    return flipped, over, distances


def scan_metrics(
    result: np.ndarray,
    template: np.ndarray,
    quads: np.ndarray,
    target,
    target_vertices: np.ndarray,
    target_triangles: np.ndarray,
) -> ScanMetrics:
    """Every metric of ``result`` ((N, 3) positions) wrapped from ``template`` (the aligned template, the
    same quads) onto a scan: ``target`` is its kernel ``TargetMesh``, built from ``target_vertices``
    and ``target_triangles``. Distances count the vertices over the surface only (see :func:`on_boundary`)."""
    result = np.asarray(result, dtype=np.float64)
    diagonal = float(np.linalg.norm(np.ptp(np.asarray(target_vertices, dtype=np.float64), axis=0)))
    finite = np.isfinite(result).all(axis=1)
    distances = np.full(len(result), np.inf)
    over = np.zeros(len(result), dtype=bool)
    if finite.any():
        hits = target.closest_points(np.ascontiguousarray(result[finite], dtype=np.float32))
        distances[finite] = hits.distances
        over[finite] = ~on_boundary(target_triangles, hits.triangles, hits.barycentrics)
    facing_flips, quads_over, centre_distances = target_facing_flips(
        result, quads, target, target_vertices, target_triangles
    )
    near = OFF_SURFACE_PERCENT * diagonal / 100.0
    with np.errstate(divide="ignore", invalid="ignore"):
        area_ratios = quad_areas(result, quads) / quad_areas(template, quads)
    return ScanMetrics(
        diagonal=diagonal,
        distance_percent=ErrorStats.of(distances, over).scaled(100.0 / diagonal),
        over_surface=int(over.sum()),
        off_surface=int((over & (distances > near)).sum()),
        flipped_vs_template=int(flipped_quads(result, template, quads).sum()),
        flipped_vs_target=int(facing_flips.sum()),
        flipped_vs_target_on_surface=int((facing_flips & (centre_distances <= near)).sum()),
        quads_over_surface=int(quads_over.sum()),
        area=RatioStats.of(area_ratios),
        edge=RatioStats.of(edge_length_ratios(result, template, quads)),
        nonfinite_vertices=int((~finite).sum()),
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
