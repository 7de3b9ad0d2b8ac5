"""Per-vertex layout state as plain numpy arrays: no ``bpy`` here, so it is unit-tested without Blender.

A layout vertex is either a *space-point* (free in 3D) or a *face-point* (on a target triangle,
given by the triangle index in the evaluated target's loop-triangle order and the barycentric
weights of its three corners). The state lives in three POINT-domain mesh attributes, named
below; ``blender.attributes`` moves them between the mesh and the :class:`LayoutState` arrays used here.

Every function returns new arrays and leaves its inputs untouched.
"""

import hashlib
from typing import NamedTuple

import numpy as np

from . import transforms
from .errors import LayoutError

STATE_ATTRIBUTE = "springwrap_state"
"""INT attribute: :data:`SPACE_POINT` or :data:`FACE_POINT`."""
FACE_ATTRIBUTE = "springwrap_face"
"""INT attribute: the target triangle of a face-point, :data:`NO_FACE` for a space-point."""
BARYCENTRIC_ATTRIBUTE = "springwrap_bary"
"""FLOAT_VECTOR attribute: the barycentric weights of a face-point, zero for a space-point."""
REST_ATTRIBUTE = "springwrap_rest"
"""FLOAT_VECTOR attribute: the template's shape as made (local), which the wrap's springs rest in."""

SPACE_POINT = 0
"""State value of a vertex free in space."""
FACE_POINT = 1
"""State value of a vertex attached to a target triangle."""
NO_FACE = -1
"""Triangle index of a space-point (and of a query that found nothing)."""

REATTACH_TOLERANCE = 1e-5
"""A face-point whose face is gone re-attaches when the surface is this close, relative to the
target's bounding-box diagonal; farther away it becomes a space-point (paper section 2.1)."""


class LayoutState(NamedTuple):
    """The per-vertex state of a layout: three arrays of the same length ``N``."""

    states: np.ndarray  # (N,) int32, SPACE_POINT or FACE_POINT
    faces: np.ndarray  # (N,) int32, triangle index or NO_FACE
    barycentrics: np.ndarray  # (N, 3) float32


class LayoutArrays(NamedTuple):
    """Everything an operation reads from the layout object, as arrays."""

    positions: np.ndarray  # (N, 3) float32 vertex coordinates in the layout's local space, as stored
    matrix_world: np.ndarray  # (4, 4) float64 layout object to world
    selection: np.ndarray  # (N,) bool vertex selection
    state: LayoutState


class Resolution(NamedTuple):
    """The outcome of :func:`resolve_face_points`."""

    state: LayoutState
    reattached_count: int  # face-points moved to a triangle of the current target
    detached_count: int  # face-points whose face is gone, now space-points


def space_state(vertex_count: int) -> LayoutState:
    """The state of a layout with no attributes yet: every vertex a space-point."""
    return LayoutState(
        states=np.full(vertex_count, SPACE_POINT, dtype=np.int32),
        faces=np.full(vertex_count, NO_FACE, dtype=np.int32),
        barycentrics=np.zeros((vertex_count, 3), dtype=np.float32),
    )


def normalized_state(states, faces, barycentrics) -> LayoutState:
    """A :class:`LayoutState` with the right dtypes and shapes, space-points written canonically.

    Anything that is not :data:`FACE_POINT` counts as a space-point (face -1, weights 0), so a
    hand-edited attribute cannot produce a half-attached vertex.
    """
    states = np.asarray(states).reshape(-1)
    vertex_count = states.shape[0]
    faces = np.asarray(faces).reshape(vertex_count).astype(np.int32)
    barycentrics = np.asarray(barycentrics).reshape(vertex_count, 3).astype(np.float32)
    is_face = states == FACE_POINT
    return LayoutState(
        states=np.where(is_face, FACE_POINT, SPACE_POINT).astype(np.int32),
        faces=np.where(is_face, faces, NO_FACE).astype(np.int32),
        barycentrics=np.where(is_face[:, None], barycentrics, 0.0).astype(np.float32),
    )


def point_counts(states: np.ndarray) -> tuple[int, int]:
    """``(face_point_count, space_point_count)`` of a state array."""
    face_count = int(np.count_nonzero(np.asarray(states) == FACE_POINT))
    return face_count, int(np.asarray(states).size) - face_count


def target_signature(triangles: np.ndarray, vertex_count: int) -> str:
    """Topology signature of a target: blake2b over its counts and triangle index array, as hex.

    It changes when faces are deleted, added or re-triangulated, and not when vertices only move,
    so face-points (triangle + barycentric) stay valid exactly as long as it is unchanged.
    """
    triangles = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
    digest = hashlib.blake2b(digest_size=16)
    digest.update(np.array([vertex_count, triangles.shape[0]], dtype=np.int64).tobytes())
    digest.update(triangles.tobytes())
    return digest.hexdigest()


def content_hash(vertices: np.ndarray, triangles: np.ndarray) -> str:
    """blake2b over vertex and triangle bytes (shapes included): the key of a built target mesh.

    The arrays' memory is hashed where it is (no ``tobytes()`` copy: 18 bytes per triangle of a target).
    """
    digest = hashlib.blake2b(digest_size=16)
    for array in (vertices, triangles):
        array = np.ascontiguousarray(array)
        digest.update(np.array(array.shape, dtype=np.int64).tobytes())
        digest.update(str(array.dtype).encode())
        digest.update(memoryview(array).cast("B"))
    return digest.hexdigest()


def face_points_to_resolve(
    state: LayoutState, triangle_count: int, stored_signature: str, current_signature: str
) -> np.ndarray:
    """Mask of the face-points that must be checked against the current target surface.

    All face-points when the target's topology changed since they were written (a stored
    signature that differs from the current one); in any case those whose triangle index is not
    a triangle of the current target.
    """
    is_face = state.states == FACE_POINT
    invalid = (state.faces < 0) | (state.faces >= triangle_count)
    topology_changed = bool(stored_signature) and stored_signature != current_signature
    if topology_changed:
        return is_face.copy()
    return is_face & invalid


def reattach_tolerance(bounding_box_min, bounding_box_max) -> float:
    """Distance within which a face-point whose face is gone re-attaches: see :data:`REATTACH_TOLERANCE`."""
    diagonal = np.asarray(bounding_box_max, dtype=np.float64) - np.asarray(bounding_box_min, dtype=np.float64)
    return REATTACH_TOLERANCE * float(np.linalg.norm(diagonal))


def resolve_face_points(
    state: LayoutState,
    mask: np.ndarray,
    hit_triangles: np.ndarray,
    hit_barycentrics: np.ndarray,
    hit_distances: np.ndarray,
    tolerance: float,
) -> Resolution:
    """Apply the deleted-face rule to the face-points in ``mask`` (paper section 2.1).

    ``hit_*`` are the closest-point results on the current target for the masked vertices, in
    mask order. A point within ``tolerance`` of the surface re-attaches to the hit triangle;
    otherwise (farther, or no hit) it becomes a space-point. Positions are not involved.
    """
    mask = np.asarray(mask, dtype=bool)
    hit_triangles = np.asarray(hit_triangles).reshape(-1)
    hit_distances = np.asarray(hit_distances, dtype=np.float64).reshape(-1)
    hit_barycentrics = np.asarray(hit_barycentrics, dtype=np.float32).reshape(-1, 3)
    close = (hit_triangles >= 0) & np.isfinite(hit_distances) & (hit_distances <= tolerance)
    indices = np.flatnonzero(mask)
    reattach = indices[close]
    detach = indices[~close]
    states = state.states.copy()
    faces = state.faces.copy()
    barycentrics = state.barycentrics.copy()
    faces[reattach] = hit_triangles[close]
    barycentrics[reattach] = hit_barycentrics[close]
    states[detach] = SPACE_POINT
    faces[detach] = NO_FACE
    barycentrics[detach] = 0.0
    return Resolution(LayoutState(states, faces, barycentrics), int(reattach.size), int(detach.size))


def detach_points(state: LayoutState, mask: np.ndarray) -> LayoutState:
    """The state with the vertices in ``mask`` made space-points."""
    mask = np.asarray(mask, dtype=bool)
    states = state.states.copy()
    faces = state.faces.copy()
    barycentrics = state.barycentrics.copy()
    states[mask] = SPACE_POINT
    faces[mask] = NO_FACE
    barycentrics[mask] = 0.0
    return LayoutState(states, faces, barycentrics)


def hit_mask(mask: np.ndarray, hit_triangles: np.ndarray) -> np.ndarray:
    """Full-length mask of the vertices in ``mask`` whose query (in mask order) found a triangle."""
    mask = np.asarray(mask, dtype=bool)
    result = np.zeros(mask.shape, dtype=bool)
    result[np.flatnonzero(mask)] = np.asarray(hit_triangles).reshape(-1) >= 0
    return result


def attach_points(
    state: LayoutState, mask: np.ndarray, hit_triangles: np.ndarray, hit_barycentrics: np.ndarray
) -> LayoutState:
    """Merge query results (in ``mask`` order) into the state: hits become face-points.

    Vertices outside ``mask`` and masked vertices whose query found nothing (triangle -1) keep
    their state.
    """
    mask = np.asarray(mask, dtype=bool)
    hit_triangles = np.asarray(hit_triangles).reshape(-1)
    hit_barycentrics = np.asarray(hit_barycentrics, dtype=np.float32).reshape(-1, 3)
    hit = hit_triangles >= 0
    indices = np.flatnonzero(mask)[hit]
    states = state.states.copy()
    faces = state.faces.copy()
    barycentrics = state.barycentrics.copy()
    states[indices] = FACE_POINT
    faces[indices] = hit_triangles[hit]
    barycentrics[indices] = hit_barycentrics[hit]
    return LayoutState(states, faces, barycentrics)


def merge_positions(
    positions: np.ndarray, mask: np.ndarray, hit_triangles: np.ndarray, hit_positions: np.ndarray
) -> np.ndarray:
    """``positions`` with the masked vertices whose query found a triangle moved to the hit.

    Untouched rows are copied bit for bit (their dtype is kept), so a vertex that does not move
    keeps exactly its coordinates.
    """
    mask = np.asarray(mask, dtype=bool)
    hit = np.asarray(hit_triangles).reshape(-1) >= 0
    result = np.array(positions, copy=True)
    result[np.flatnonzero(mask)[hit]] = np.asarray(hit_positions).reshape(-1, 3)[hit]
    return result


def operation_mask(layout: LayoutArrays, only_selected: bool) -> np.ndarray:
    """The vertices an operation acts on: the selected ones, or all."""
    if only_selected:
        return np.asarray(layout.selection, dtype=bool).copy()
    return np.ones(layout.positions.shape[0], dtype=bool)


def check_finite(layout: LayoutArrays, mask: np.ndarray) -> None:
    """Raise :class:`~.errors.LayoutError` naming the first masked vertex that is not finite in world space."""
    world = transforms.world_positions(layout)
    bad = np.flatnonzero(mask & ~np.all(np.isfinite(world), axis=1))
    if bad.size:
        raise LayoutError(f"Layout vertex {int(bad[0])} has a NaN or infinite coordinate ({bad.size} such vertices)")
