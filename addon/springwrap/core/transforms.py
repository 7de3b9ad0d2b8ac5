"""Transforms between a layout's local space and world space, on numpy arrays (no ``bpy``).

Every computation is in float64; points go to the kernel as float32 (:func:`as_float32_points`).
"""

import numpy as np

from .errors import LayoutError


def matrix_array(matrix) -> np.ndarray:
    """A 4x4 matrix (a ``mathutils.Matrix``, nested lists...) as a float64 numpy array (rows are rows)."""
    return np.array(matrix, dtype=np.float64).reshape(4, 4)


def transform_points(matrix, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 affine matrix to (N, 3) points; computed in float64, returned as float64."""
    matrix = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return add_offset(points @ matrix[:3, :3].T, matrix[:3, 3], copy=False)


def add_offset(points: np.ndarray, offset, copy: bool = True) -> np.ndarray:
    """(N, 3) float64 ``points + offset`` ((3,)), column by column: the same sums as numpy's broadcast, several
    times faster on a million points. ``copy=False``: added in place when ``points`` is float64 already."""
    points = (np.array if copy else np.asarray)(points, dtype=np.float64).reshape(-1, 3)
    for axis in range(3):
        points[:, axis] += offset[axis]
    return points


def transform_directions(matrix, directions: np.ndarray) -> np.ndarray:
    """Apply the linear part of a 4x4 matrix to (N, 3) directions (no translation, not normalized)."""
    matrix = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    return np.asarray(directions, dtype=np.float64).reshape(-1, 3) @ matrix[:3, :3].T


def transform_normals(matrix, normals: np.ndarray) -> np.ndarray:
    """Transform (N, 3) normals by the normal matrix (inverse transpose of the linear part), unit length.

    Zero normals stay zero. Raises ``numpy.linalg.LinAlgError`` for a singular matrix.
    """
    matrix = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    normal_matrix = np.linalg.inv(matrix[:3, :3]).T
    transformed = np.asarray(normals, dtype=np.float64).reshape(-1, 3) @ normal_matrix.T
    return normalize_or_zero(transformed)


def normalize_or_zero(vectors: np.ndarray) -> np.ndarray:
    """Unit-length rows; rows of zero (or non-finite) length become zero."""
    vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    lengths = np.linalg.norm(vectors, axis=1)
    valid = np.isfinite(lengths) & (lengths > 0.0)
    result = np.zeros_like(vectors)
    result[valid] = vectors[valid] / lengths[valid, None]
    return result


def is_invertible(matrix) -> bool:
    """Whether a 4x4 affine matrix can be inverted (finite, no zero scale)."""
    matrix = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    if not np.all(np.isfinite(matrix)):
        return False
    linear = matrix[:3, :3]
    scale = max(float(np.abs(linear).max()), 1e-300)
    return abs(float(np.linalg.det(linear / scale))) > 1e-12


def inverse_matrix(matrix) -> np.ndarray:
    """Inverse of a 4x4 affine matrix (float64). Raises ``numpy.linalg.LinAlgError`` when singular."""
    return np.linalg.inv(np.asarray(matrix, dtype=np.float64).reshape(4, 4))


def axis_direction(axis: str) -> np.ndarray:
    """The unit vector of an axis name ``'X'``, ``'-Y'``, ...; raises ``ValueError`` for another name."""
    axes = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
    sign = -1.0 if axis.startswith("-") else 1.0
    name = axis.lstrip("-")
    if name not in axes or axis.count("-") > 1:
        raise ValueError(f"unknown axis {axis!r}")
    return sign * np.array(axes[name], dtype=np.float64)


def as_float32_points(points: np.ndarray) -> np.ndarray:
    """(N, 3) float32 C-contiguous: the kernel's array contract."""
    return np.ascontiguousarray(np.asarray(points).reshape(-1, 3), dtype=np.float32)


def world_positions(layout) -> np.ndarray:
    """(N, 3) float64 world-space positions of the layout vertices."""
    return transform_points(layout.matrix_world, layout.positions)


def to_local(matrix_world: np.ndarray, world_points: np.ndarray, dtype=np.float32) -> np.ndarray:
    """(N, 3) world points in the layout's local space; raises :class:`~.errors.LayoutError` for zero scale."""
    if not is_invertible(matrix_world):
        raise LayoutError(
            "The layout object's transform cannot be inverted (zero scale): cannot write world positions back"
        )
    inverse = inverse_matrix(matrix_world)
    return transform_points(inverse, world_points).astype(dtype)
