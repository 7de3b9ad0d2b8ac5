"""A smooth map of space through matched points, and where it places a chain along a curve (numpy, no ``bpy``).

The map is a thin-plate spline in 3-D (radial basis ``r``, the biharmonic kernel, plus an affine part) that takes
each source point exactly to its target and bends as little as it can between them: fitted on the layout's rest
shape to where its anchors (and the corners matched on the target) are, it says where any other rest point belongs
on the target, the anchors' way, without the fit's sliding. :func:`placements` maps a chain's rest points with it and
projects them onto the curve the chain follows: where along that curve each vertex goes.
"""

from typing import NamedTuple

import numpy as np

from .edge_paths import cumulative_lengths

MIN_POINTS = 4
"""Fewer matched points than this (or points all in one plane) fit no affine part: the map only moves by their mean
offset."""


class SmoothMap(NamedTuple):
    """A fitted map: ``f(x) = [x, 1] @ affine + sum_i weights[i] * |x - centres[i]|``."""

    centres: np.ndarray  # (K, 3) float64 the source points
    weights: np.ndarray  # (K, 3) float64
    affine: np.ndarray  # (4, 3) float64


def fit(sources, targets) -> SmoothMap:
    """The thin-plate map taking each of ``sources`` ((K, 3)) to the same row of ``targets``; a source given twice
    counts once (its first target). Raises ValueError when there is no point."""
    sources = np.asarray(sources, dtype=np.float64).reshape(-1, 3)
    targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    if sources.shape[0] == 0 or sources.shape != targets.shape:
        raise ValueError(f"a smooth map needs matched points: {sources.shape[0]} sources, {targets.shape[0]} targets")
    _unique, first = np.unique(sources, axis=0, return_index=True)
    first = np.sort(first)
    sources, targets = sources[first], targets[first]
    count = sources.shape[0]
    homogeneous = np.concatenate([sources, np.ones((count, 1))], axis=1)
    centred = sources - sources.mean(axis=0)
    if count < MIN_POINTS or np.linalg.matrix_rank(centred, tol=1e-9 * max(np.abs(centred).max(), 1e-300)) < 3:
        affine = np.concatenate([np.eye(3), (targets - sources).mean(axis=0)[None, :]])
        return SmoothMap(sources, np.zeros_like(sources), affine)
    kernel = np.linalg.norm(sources[:, None, :] - sources[None, :, :], axis=2)
    system = np.zeros((count + 4, count + 4))
    system[:count, :count] = kernel
    system[:count, count:] = homogeneous
    system[count:, :count] = homogeneous.T
    right = np.concatenate([targets, np.zeros((4, 3))])
    solution = np.linalg.lstsq(system, right, rcond=None)[0]
    return SmoothMap(sources, solution[:count], solution[count:])


def apply(mapping: SmoothMap, points) -> np.ndarray:
    """(P, 3) float64: ``points`` ((P, 3)) taken through the map."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    homogeneous = np.concatenate([points, np.ones((points.shape[0], 1))], axis=1)
    distances = np.linalg.norm(points[:, None, :] - mapping.centres[None, :, :], axis=2)
    return homogeneous @ mapping.affine + distances @ mapping.weights


def placements(mapping: SmoothMap, chain_rest, polyline) -> np.ndarray:
    """(C,) float64: where along ``polyline`` ((P, 3), in the chain's direction) each chain vertex goes, as a
    fraction of its length: the vertex's rest point (``chain_rest``, (C, 3)) taken through the map and projected onto
    the polyline, never going back along it (a vertex projected behind the one before it stays level with it)."""
    polyline = np.asarray(polyline, dtype=np.float64).reshape(-1, 3)
    mapped = apply(mapping, chain_rest)
    cumulative = cumulative_lengths(polyline)
    if polyline.shape[0] < 2 or not cumulative[-1] > 0.0:
        return np.linspace(0.0, 1.0, mapped.shape[0])
    starts, direction = polyline[:-1], np.diff(polyline, axis=0)
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(np.einsum("psk,sk->ps", mapped[:, None, :] - starts[None], direction) / squared, 0.0, 1.0)
    distances = np.linalg.norm(starts[None] + t[..., None] * direction[None] - mapped[:, None, :], axis=2)
    segment = np.argmin(distances, axis=1)
    rows = np.arange(mapped.shape[0])
    along = cumulative[segment] + t[rows, segment] * (cumulative[segment + 1] - cumulative[segment])
    return np.clip(np.maximum.accumulate(along / cumulative[-1]), 0.0, 1.0)
