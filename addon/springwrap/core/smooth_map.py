"""A smooth map of space through matched points, and where it places a chain along a curve (numpy, no ``bpy``).

The map is a polyharmonic spline in 3-D (radial basis ``r``, the biharmonic kernel, plus a polynomial part) that
takes each source point exactly to its target and bends as little as it can between them: fitted on the layout's
rest shape to where its anchors (and the corners matched on the target) are, it says where any other rest point
belongs on the target, the anchors' way, without the fit's sliding. Its polynomial part is affine (a thin-plate
spline) or quadratic (:func:`fit`'s degree 2: it follows a smooth design change that bends or tapers a part
between few points, where it holds; the caller decides, from evidence the points do not give, whether it does).
:func:`placements` maps a chain's rest points with it and projects them onto the curve the chain follows: where
along that curve each vertex goes.
"""

from typing import NamedTuple

import numpy as np

from .edge_paths import cumulative_lengths

MIN_POINTS = 4
"""Fewer matched points than this (or points all in one plane) fit no affine part: the map only moves by their mean
offset."""
MIN_QUADRATIC_POINTS = 20
"""The fewest matched points through which a quadratic part is fitted (twice its ten terms a coordinate)."""


class SmoothMap(NamedTuple):
    """A fitted map: ``f(x) = basis(y) @ polynomial + sum_i weights[i] * |y - (centres[i] - origin) / scale|``
    with ``y = (x - origin) / scale`` and ``basis(y)`` ``[1, y]`` (affine, 4 rows of ``polynomial``) or ``[1, y,
    y_i y_j (i <= j)]`` (quadratic, 10 rows); plus, with ``bumps``, ``sum_j bump_weights[j] * exp(-|x - bumps[j]|² /
    bump_width²)``."""

    centres: np.ndarray  # (K, 3) float64 the source points
    weights: np.ndarray  # (K, 3) float64
    polynomial: np.ndarray  # (4, 3) or (10, 3) float64
    origin: np.ndarray  # (3,) float64
    scale: float
    bumps: np.ndarray | None = None  # (B, 3) float64 centres of a correction (``line_placement.corrected``)
    bump_weights: np.ndarray | None = None  # (B, 3) float64
    bump_width: float = 0.0

    @property
    def degree(self) -> int:
        """1 for an affine polynomial part, 2 for a quadratic one."""
        return 1 if self.polynomial.shape[0] == 4 else 2


def _basis(normalized: np.ndarray, degree: int) -> np.ndarray:
    """(P, 4) or (P, 10): the polynomial terms of ``normalized`` points ((P, 3)) up to ``degree`` (1 or 2)."""
    columns = [np.ones(normalized.shape[0])] + [normalized[:, axis] for axis in range(3)]
    if degree == 2:
        columns += [normalized[:, i] * normalized[:, j] for i in range(3) for j in range(i, 3)]
    return np.stack(columns, axis=1)


def _solve(kernel: np.ndarray, basis: np.ndarray, targets: np.ndarray):
    """``(weights (K, 3), polynomial (B, 3))`` of the spline through ``targets`` with the polynomial terms ``basis``
    ((K, B)), or None when the points do not fix those terms (too few, or all on one plane or quadric)."""
    count, terms = basis.shape
    if count < terms or np.linalg.matrix_rank(basis, tol=1e-9 * max(np.abs(basis).max(), 1e-300)) < terms:
        return None
    system = np.zeros((count + terms, count + terms))
    system[:count, :count] = kernel
    system[:count, count:] = basis
    system[count:, :count] = basis.T
    solution = np.linalg.lstsq(system, np.concatenate([targets, np.zeros((terms, 3))]), rcond=None)[0]
    if not np.all(np.isfinite(solution)):
        return None
    return solution[:count], solution[count:]


def fit(sources, targets, degree: int = 1) -> SmoothMap | None:
    """The map taking each of ``sources`` ((K, 3)) to the same row of ``targets``; a source given twice counts once
    (its first target). ``degree``: 1, an affine part (fewer than :data:`MIN_POINTS` points, or points in one plane:
    the map moves everything by their mean offset); 2, a quadratic part, or None when there are fewer than
    :data:`MIN_QUADRATIC_POINTS` points or they do not fix it. Raises ValueError when there is no point."""
    sources = np.asarray(sources, dtype=np.float64).reshape(-1, 3)
    targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    if sources.shape[0] == 0 or sources.shape != targets.shape:
        raise ValueError(f"a smooth map needs matched points: {sources.shape[0]} sources, {targets.shape[0]} targets")
    _unique, first = np.unique(sources, axis=0, return_index=True)
    first = np.sort(first)
    sources, targets = sources[first], targets[first]
    count = sources.shape[0]
    origin = sources.mean(axis=0)
    scale = float(np.abs(sources - origin).max())
    if degree == 2 and count < MIN_QUADRATIC_POINTS:
        return None
    if count < MIN_POINTS or not scale > 0.0:
        return None if degree == 2 else _moved(sources, targets)
    normalized = (sources - origin) / scale
    kernel = np.linalg.norm(normalized[:, None, :] - normalized[None, :, :], axis=2)
    solved = _solve(kernel, _basis(normalized, degree), targets)
    if solved is None:
        return None if degree == 2 else _moved(sources, targets)
    return SmoothMap(sources, solved[0], solved[1], origin, scale)


def _moved(sources: np.ndarray, targets: np.ndarray) -> SmoothMap:
    """The map that moves everything by the points' mean offset (too few points, or all in one plane)."""
    polynomial = np.zeros((4, 3))
    polynomial[0] = (targets - sources).mean(axis=0)
    polynomial[1:] = np.eye(3)
    return SmoothMap(sources, np.zeros_like(sources), polynomial, np.zeros(3), 1.0)


def apply(mapping: SmoothMap, points) -> np.ndarray:
    """(P, 3) float64: ``points`` ((P, 3)) taken through the map."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    normalized = (points - mapping.origin) / mapping.scale
    centres = (mapping.centres - mapping.origin) / mapping.scale
    distances = np.linalg.norm(normalized[:, None, :] - centres[None, :, :], axis=2)
    mapped = _basis(normalized, mapping.degree) @ mapping.polynomial + distances @ mapping.weights
    if mapping.bumps is not None:
        mapped += bumps(points, mapping.bumps, mapping.bump_width) @ mapping.bump_weights
    return mapped


def bumps(points, centres, width: float) -> np.ndarray:
    """(P, B) float64: the Gaussian bump ``exp(-|p - c|² / width²)`` of each of ``centres`` ((B, 3)) at each of
    ``points`` ((P, 3))."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    gap = points[:, None, :] - np.asarray(centres, dtype=np.float64)[None, :, :]
    return np.exp(-np.einsum("pbk,pbk->pb", gap, gap) / width**2)


def placements(mapping: SmoothMap, chain_rest, polyline) -> np.ndarray:
    """(C,) float64: where along ``polyline`` ((P, 3), in the chain's direction) each chain vertex goes, as a
    fraction of its length: the vertex's rest point (``chain_rest``, (C, 3)) taken through the map and projected onto
    the polyline, never going back along it (a vertex projected behind the one before it stays level with it)."""
    polyline = np.asarray(polyline, dtype=np.float64).reshape(-1, 3)
    mapped = apply(mapping, chain_rest)
    cumulative = cumulative_lengths(polyline)
    if polyline.shape[0] < 2 or not cumulative[-1] > 0.0:
        return np.linspace(0.0, 1.0, mapped.shape[0])
    segment, t = nearest_segments(mapped, polyline)
    along = cumulative[segment] + t * (cumulative[segment + 1] - cumulative[segment])
    return np.clip(np.maximum.accumulate(along / cumulative[-1]), 0.0, 1.0)


def nearest_segments(points, polyline) -> tuple[np.ndarray, np.ndarray]:
    """``(segment (P,) int64, t (P,) float64)``: for each of ``points`` ((P, 3)), the segment of ``polyline``
    ((K, 3), K >= 2) its nearest point lies on and where along it (0 at its start, 1 at its end)."""
    points, polyline = np.asarray(points, dtype=np.float64), np.asarray(polyline, dtype=np.float64)
    starts, direction = polyline[:-1], np.diff(polyline, axis=0)
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(np.einsum("psk,sk->ps", points[:, None, :] - starts[None], direction) / squared, 0.0, 1.0)
    distances = np.linalg.norm(starts[None] + t[..., None] * direction[None] - points[:, None, :], axis=2)
    segment = np.argmin(distances, axis=1)
    return segment, t[np.arange(points.shape[0]), segment]
