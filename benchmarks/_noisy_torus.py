"""Deterministic benchmark geometry, no ``bpy``: a noise-displaced torus and query points near it.

A torus is a closed surface with no poles, so a regular (major x minor) grid of any size
tessellates it without degenerate triangles; the displacement (a sum of periodic waves with
fixed random frequencies and phases) makes the triangles uneven in size and orientation.
The query points are the vertices of a *second*, differently sized grid over the same
displaced surface, jittered and pushed off it along the normal: in row-major order they
are spatially coherent, as the vertices of a real mesh are.
"""

import numpy as np

MAJOR_RADIUS = 1.0
MINOR_RADIUS = 0.3
# Wave amplitudes sum to about this (relative to MINOR_RADIUS it is 15 %).
DISPLACEMENT = 0.045
WAVE_COUNT = 24
# The query points lie within this distance off the surface (both sides).
QUERY_OFFSET = 0.02


def _grid_shape(cell_count: int) -> tuple[int, int]:
    """(major, minor) segment counts with about ``cell_count`` cells of about square shape."""
    aspect = MAJOR_RADIUS / MINOR_RADIUS
    minor = max(3, round(np.sqrt(cell_count / aspect)))
    major = max(3, round(cell_count / minor))
    return major, minor


def _waves(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integer frequencies (so the waves are periodic on the torus), amplitudes and phases."""
    rng = np.random.default_rng(seed)
    major_frequency = rng.integers(-24, 25, WAVE_COUNT)
    minor_frequency = rng.integers(-8, 9, WAVE_COUNT)
    amplitude = rng.uniform(0.5, 1.0, WAVE_COUNT) / (1.0 + np.hypot(major_frequency, minor_frequency))
    amplitude *= DISPLACEMENT / amplitude.sum()
    phase = rng.uniform(0.0, 2.0 * np.pi, WAVE_COUNT)
    return major_frequency, minor_frequency, amplitude, phase


def _surface(major_angle: np.ndarray, minor_angle: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions on the displaced torus and the undisplaced torus normals, float64 (..., 3)."""
    major_frequency, minor_frequency, amplitude, phase = _waves(seed)
    arguments = (
        np.multiply.outer(major_angle, major_frequency) + np.multiply.outer(minor_angle, minor_frequency) + phase
    )
    height = (np.sin(arguments) * amplitude).sum(axis=-1)
    normal = np.stack(
        [np.cos(minor_angle) * np.cos(major_angle), np.cos(minor_angle) * np.sin(major_angle), np.sin(minor_angle)],
        axis=-1,
    )
    ring_center = np.stack(
        [MAJOR_RADIUS * np.cos(major_angle), MAJOR_RADIUS * np.sin(major_angle), np.zeros_like(major_angle)], axis=-1
    )
    return ring_center + (MINOR_RADIUS + height)[..., None] * normal, normal


def _torus_grid(cell_count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """float32 (N, 3) vertices and (N, 4) quads of a (major x minor) grid of about ``cell_count`` cells."""
    major, minor = _grid_shape(max(1, cell_count))
    major_angle = np.arange(major) * (2.0 * np.pi / major)
    minor_angle = np.arange(minor) * (2.0 * np.pi / minor)
    positions, _normal = _surface(*np.meshgrid(major_angle, minor_angle, indexing="ij"), seed=seed)
    vertices = np.ascontiguousarray(positions.reshape(-1, 3), dtype=np.float32)

    ring = np.arange(major)[:, None]
    around = np.arange(minor)[None, :]
    corner_00 = ring * minor + around
    corner_10 = (ring + 1) % major * minor + around
    corner_11 = (ring + 1) % major * minor + (around + 1) % minor
    corner_01 = ring * minor + (around + 1) % minor
    quads = np.stack([corner_00, corner_10, corner_11, corner_01], axis=-1).reshape(-1, 4)
    return vertices, quads


def noisy_torus(triangle_count: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A displaced torus with about ``triangle_count`` triangles.

    Returns float32 (N, 3) vertices and uint32 (M, 3) triangles, C-contiguous, counter-clockwise
    seen from outside; M = 2 * N exactly."""
    vertices, quads = _torus_grid(triangle_count // 2, seed)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    return vertices, np.ascontiguousarray(triangles, dtype=np.uint32)


def torus_layout(quad_count: int, seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A quad layout over a displaced torus (another ``seed``: another displacement than the target's).

    Returns float32 (N, 3) vertices and int32 (N, 4) quads (N = quad count, about ``quad_count``),
    counter-clockwise seen from outside."""
    vertices, quads = _torus_grid(quad_count, seed)
    return vertices, np.ascontiguousarray(quads, dtype=np.int32)


def query_points(point_count: int, seed: int = 1) -> np.ndarray:
    """``point_count`` float32 (K, 3) points near the torus of :func:`noisy_torus` (same ``seed``), coherent order.

    They are the vertices of a second grid (another resolution than any target's), row-major,
    jittered by up to half a cell and moved off the surface by up to ``QUERY_OFFSET``."""
    major, minor = _grid_shape(point_count)
    while major * minor < point_count:
        major += 1
    rng = np.random.default_rng(seed + 1_000_003)
    major_angle, minor_angle = np.meshgrid(
        np.arange(major) * (2.0 * np.pi / major), np.arange(minor) * (2.0 * np.pi / minor), indexing="ij"
    )
    major_angle = major_angle.ravel()[:point_count] + rng.uniform(-0.5, 0.5, point_count) * (2.0 * np.pi / major)
    minor_angle = minor_angle.ravel()[:point_count] + rng.uniform(-0.5, 0.5, point_count) * (2.0 * np.pi / minor)
    positions, normal = _surface(major_angle, minor_angle, seed=seed)
    positions += normal * rng.uniform(-QUERY_OFFSET, QUERY_OFFSET, point_count)[:, None]
    return np.ascontiguousarray(positions, dtype=np.float32)
