"""The layout operations detach, snap and project on arrays: numpy and the kernel, no ``bpy``.

Each operation takes what ``blender.layout`` and ``blender.target`` read (:class:`~.layout_state.LayoutArrays`
and a :class:`~.target.Target`), computes everything, and returns an :class:`Outcome` holding the complete
new positions and state. Nothing is written here: the operator writes the outcome only when every
step succeeded, so a failure leaves the layout exactly as it was.

All geometry is in world space; the outcome's positions are back in the layout's local space,
and vertices that do not move keep their stored coordinates bit for bit.
"""

from typing import NamedTuple

import numpy as np

from . import layout_state, transforms
from .errors import LayoutError
from .layout_state import LayoutArrays, LayoutState, check_finite, operation_mask
from .target import Target, resolve_topology
from .transforms import world_positions


class Outcome(NamedTuple):
    """The result of an operation: what to write, and what to report."""

    positions: np.ndarray  # (N, 3) float32 new local coordinates (all vertices)
    state: LayoutState  # new state (all vertices)
    changed_count: int  # vertices snapped, projected or detached
    missed_count: int = 0  # vertices whose query found nothing (within max distance); untouched
    skipped_count: int = 0  # vertices not queried (NORMAL projection: vertex on no face)
    moved_distance: float = 0.0  # largest distance a vertex moved, world units
    topology_detached_count: int = 0  # face-points whose target face is gone, now space-points
    topology_reattached_count: int = 0  # face-points re-attached on the changed target


def detach(layout: LayoutArrays, target: Target | None, stored_signature: str, only_selected: bool) -> Outcome:
    """Make the vertices space-points; positions are unchanged."""
    resolution = _resolve_or_keep(layout, target, stored_signature)
    mask = operation_mask(layout, only_selected)
    state = layout_state.detach_points(resolution.state, mask)
    return Outcome(
        positions=layout.positions,
        state=state,
        changed_count=int(np.count_nonzero(mask)),
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )


def snap(
    layout: LayoutArrays,
    target: Target,
    stored_signature: str,
    only_selected: bool,
    mode: str,
    max_distance: float,
) -> Outcome:
    """Move vertices to the target and make them face-points.

    ``mode`` ``'SURFACE'``: the exact closest surface point; ``'VERTEX'``: the nearest target
    vertex. Vertices farther than ``max_distance`` (world units, 0 = unlimited) are untouched.
    """
    if mode not in ("SURFACE", "VERTEX"):
        raise ValueError(f"unknown snap mode {mode!r}")
    resolution = resolve_topology(layout, target, stored_signature)
    mask = operation_mask(layout, only_selected)
    check_finite(layout, mask)
    origins = world_positions(layout)[mask]
    if not origins.shape[0]:
        return _outcome(layout, resolution, mask, _no_hits(0), origins, 0)
    points = origins  # float64 world: the target's frame keeps the precision
    limit = _max_distance_arguments(max_distance)
    if mode == "SURFACE":
        hits = target.mesh.closest_points(points, **limit)
        triangles = np.asarray(hits.triangles, dtype=np.int32)
    else:
        hits = target.mesh.nearest_vertices(points, **limit)
        triangles = np.where(np.asarray(hits.vertices) >= 0, hits.triangles, -1).astype(np.int32)
    if max_distance > 0.0:
        triangles = np.where(np.asarray(hits.distances) <= max_distance, triangles, -1).astype(np.int32)
    query = _Hits(triangles, hits.barycentrics, hits.positions)
    return _outcome(layout, resolution, mask, query, origins, 0)


def project(
    layout: LayoutArrays,
    target: Target,
    stored_signature: str,
    only_selected: bool,
    directions: np.ndarray,
    both_directions: bool,
    max_distance: float,
) -> Outcome:
    """Cast a ray from each vertex along its world-space direction; hits become face-points.

    ``directions`` is one (3,) direction for every vertex or an (N, 3) array, one per layout
    vertex; a zero (or non-finite) direction skips that vertex. Rays that miss, or hit farther
    than ``max_distance`` (0 = unlimited), leave their vertex untouched.
    """
    resolution = resolve_topology(layout, target, stored_signature)
    mask = operation_mask(layout, only_selected)
    vertex_count = layout.positions.shape[0]
    directions = np.asarray(directions, dtype=np.float64)
    if directions.shape == (3,):
        directions = np.broadcast_to(directions, (vertex_count, 3))
    directions = transforms.normalize_or_zero(directions)
    has_direction = np.any(directions != 0.0, axis=1)
    skipped_count = int(np.count_nonzero(mask & ~has_direction))
    mask &= has_direction
    check_finite(layout, mask)
    origins = world_positions(layout)[mask]
    if not origins.shape[0]:
        return _outcome(layout, resolution, mask, _no_hits(0), origins, skipped_count)
    hits = target.mesh.ray_cast(
        origins,
        directions[mask],
        both_directions=both_directions,
        **_max_distance_arguments(max_distance),
    )
    triangles = np.asarray(hits.triangles, dtype=np.int32)
    if max_distance > 0.0:
        triangles = np.where(np.abs(np.asarray(hits.distances)) <= max_distance, triangles, -1).astype(np.int32)
    query = _Hits(triangles, hits.barycentrics, hits.positions)
    return _outcome(layout, resolution, mask, query, origins, skipped_count)


class _Hits(NamedTuple):
    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray


def _no_hits(count: int) -> _Hits:
    return _Hits(
        np.full(count, -1, dtype=np.int32),
        np.zeros((count, 3), dtype=np.float32),
        np.zeros((count, 3), dtype=np.float32),
    )


def _max_distance_arguments(max_distance: float) -> dict:
    """Keyword arguments for a kernel query: none when unlimited (0), so the kernel's default applies."""
    if max_distance < 0.0:
        raise ValueError("max_distance must not be negative")
    return {"max_distance": float(max_distance)} if max_distance > 0.0 else {}


def _resolve_or_keep(layout: LayoutArrays, target: Target | None, stored_signature: str) -> layout_state.Resolution:
    if target is None:
        return layout_state.Resolution(layout.state, 0, 0)
    return resolve_topology(layout, target, stored_signature)


def _outcome(
    layout: LayoutArrays,
    resolution: layout_state.Resolution,
    mask: np.ndarray,
    hits: _Hits,
    origins: np.ndarray,
    skipped_count: int,
) -> Outcome:
    """Merge query results (in mask order) into complete new positions and state."""
    hit = np.asarray(hits.triangles) >= 0
    hit_world = np.asarray(hits.positions, dtype=np.float64).reshape(-1, 3)
    moved_distance = float(np.linalg.norm(hit_world[hit] - origins[hit], axis=1).max()) if hit.any() else 0.0
    hit_local = np.zeros_like(hit_world)
    if hit.any():
        if not transforms.is_invertible(layout.matrix_world):
            raise LayoutError(
                "The layout object's transform cannot be inverted (zero scale): cannot write world positions back"
            )
        inverse = transforms.inverse_matrix(layout.matrix_world)
        hit_local[hit] = transforms.transform_points(inverse, hit_world[hit])
    positions = layout_state.merge_positions(
        layout.positions, mask, hits.triangles, hit_local.astype(layout.positions.dtype)
    )
    state = layout_state.attach_points(resolution.state, mask, hits.triangles, hits.barycentrics)
    hit_count = int(np.count_nonzero(hit))
    return Outcome(
        positions=positions,
        state=state,
        changed_count=hit_count,
        missed_count=int(hit.size) - hit_count,
        skipped_count=skipped_count,
        moved_distance=moved_distance,
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )
