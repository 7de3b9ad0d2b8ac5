"""Anchors on arrays (paper section 2.4): numpy and the kernel, no ``bpy``.

An anchor pairs a layout vertex with a target point: a point on the target surface (a *face*
anchor: a triangle of the evaluated target's loop-triangle order and barycentric weights, exactly
like a face-point) or a free point in 3D (a *space* anchor). Every anchor also keeps its target
point in world space (``locations``): for a space anchor it is the point itself; for a face
anchor it is a cache, recomputed from triangle + barycentric whenever an anchor operation reads
the target, and the position from which the anchor is found again when the target's topology
changed (the deleted-face rule of ``layout_state``, applied through ``target.resolve_points``).

The functions here compute complete new anchor lists and return them with what to report;
``blender.anchors`` reads and writes them, the operators in ``operators.anchors`` only call and report.
Every function returns new arrays and leaves its inputs untouched.
"""

from typing import NamedTuple

import numpy as np

from . import layout_state, transforms
from .errors import LayoutError
from .layout_state import FACE_POINT, NO_FACE, SPACE_POINT, LayoutArrays, LayoutState
from .target import Target, resolve_points

FACE_ANCHOR = FACE_POINT
"""Kind of an anchor whose target is a point of the target surface (triangle + barycentric)."""
SPACE_ANCHOR = SPACE_POINT
"""Kind of an anchor whose target is a free point in 3D."""

DEFAULT_SPACING_FRACTION = 0.1
"""``anchors_auto`` with spacing 0 uses this fraction of the layout's bounding-box diagonal."""
MAX_AUTO_ANCHORS = 10_000
"""``anchors_auto`` refuses a spacing that would create more anchors than this."""

METHODS = ("CLOSEST", "PROJECT")
"""How ``anchors_auto`` finds the target points: closest surface point, or ray along the vertex normal."""


class Anchors(NamedTuple):
    """A list of ``K`` anchors as arrays (the order is the order of the list in the panel)."""

    vertex_indices: np.ndarray  # (K,) int32 layout vertex
    kinds: np.ndarray  # (K,) int32 FACE_ANCHOR or SPACE_ANCHOR
    triangles: np.ndarray  # (K,) int32 target triangle of a face anchor, NO_FACE for a space anchor
    barycentrics: np.ndarray  # (K, 3) float32 weights of the triangle's corners, zero for a space anchor
    locations: np.ndarray  # (K, 3) float64 world-space target point
    twins: np.ndarray  # (K,) int32 the vertex of the paired (symmetric) anchor, its own vertex on the plane, -1 none
    proposed: np.ndarray  # (K,) bool a proposed pair not yet accepted (``core.proposals``); the wrap leaves it out
    confidences: np.ndarray  # (K,) float32 a proposed pair's confidence in [0, 1]; 0 for a hand pair


class AnchorOutcome(NamedTuple):
    """The result of an anchor operation: the complete new list, and what to report."""

    anchors: Anchors  # the whole new list
    active_index: int  # the anchor to make active, -1 to keep the current one (clamped)
    added_count: int = 0  # anchors created
    replaced_count: int = 0  # anchors dropped because a new one took their vertex
    missed_count: int = 0  # vertices whose query found nothing (PROJECT, or beyond max distance)
    skipped_count: int = 0  # vertices not queried (PROJECT: vertex on no face, no normal)
    spacing: float = 0.0  # the spacing used by anchors_auto (world units), 0 otherwise
    topology_detached_count: int = 0  # face anchors whose triangle is gone, now space anchors
    topology_reattached_count: int = 0  # face anchors found again on the changed target


def make_anchors(
    vertex_indices, kinds, triangles, barycentrics, locations, twins=None, proposed=None, confidences=None
):
    """:class:`Anchors` with the right dtypes and shapes, space anchors written canonically.

    Anything that is not :data:`FACE_ANCHOR` is a space anchor (triangle -1, weights 0), so a hand-edited list
    cannot produce a half-attached anchor. Defaults: no twin (-1), not proposed, confidence 0.
    """
    vertex_indices = np.asarray(vertex_indices).reshape(-1).astype(np.int32)
    count = vertex_indices.shape[0]
    state = layout_state.normalized_state(
        np.asarray(kinds).reshape(count),
        np.asarray(triangles).reshape(count),
        np.asarray(barycentrics).reshape(count, 3),
    )
    return Anchors(
        vertex_indices=vertex_indices,
        kinds=state.states,
        triangles=state.faces,
        barycentrics=state.barycentrics,
        locations=np.asarray(locations, dtype=np.float64).reshape(count, 3).copy(),
        twins=np.full(count, -1, np.int32) if twins is None else np.asarray(twins).reshape(count).astype(np.int32),
        proposed=np.zeros(count, bool) if proposed is None else np.asarray(proposed, bool).reshape(count),
        confidences=np.zeros(count, np.float32) if confidences is None else np.asarray(confidences, np.float32).ravel(),
    )


def no_anchors() -> Anchors:
    """An empty anchor list."""
    return make_anchors(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))


def anchor_count(anchors: Anchors) -> int:
    """Number of anchors in the list."""
    return int(anchors.vertex_indices.shape[0])


def take(anchors: Anchors, indices) -> Anchors:
    """The anchors at ``indices`` (an index array or a boolean mask), in that order."""
    return Anchors(*(np.asarray(field)[indices].copy() for field in anchors))


def concatenate(first: Anchors, second: Anchors) -> Anchors:
    """``first`` followed by ``second``."""
    return Anchors(*(np.concatenate([a, b]) for a, b in zip(first, second)))


def as_state(anchors: Anchors) -> LayoutState:
    """The anchors' targets as a :class:`~.layout_state.LayoutState` (one row per anchor)."""
    return LayoutState(anchors.kinds.copy(), anchors.triangles.copy(), anchors.barycentrics.copy())


def with_state(anchors: Anchors, state: LayoutState) -> Anchors:
    """The anchors with their kinds, triangles and barycentrics taken from ``state``."""
    return make_anchors(anchors.vertex_indices, state.states, state.faces, state.barycentrics, *anchors[4:])


def partner_indices(anchors: Anchors) -> np.ndarray:
    """(K,) int64 the list position of each anchor's twin anchor (itself on the plane), -1 when it has none.

    A pair counts only when both anchors name each other's vertex; anything else is no pair.
    """
    vertices, twins = anchors.vertex_indices.astype(np.int64), anchors.twins.astype(np.int64)
    order = np.argsort(vertices, kind="stable")
    candidates = order[np.clip(np.searchsorted(vertices[order], twins), 0, max(vertices.size - 1, 0))]
    mutual = (twins >= 0) & (vertices[candidates] == twins) & (twins[candidates] == vertices)
    return np.where(mutual, candidates, -1)


def unpair_broken(anchors: Anchors) -> Anchors:
    """The anchors with the twin cleared (-1) where the pair is not mutual any more (one half removed or replaced)."""
    twins = np.where(partner_indices(anchors) >= 0, anchors.twins, -1).astype(np.int32)
    return anchors._replace(twins=twins)


def kind_counts(anchors: Anchors) -> tuple[int, int]:
    """``(face_anchor_count, space_anchor_count)``."""
    return layout_state.point_counts(anchors.kinds)


def anchored_mask(anchors: Anchors, vertex_count: int) -> np.ndarray:
    """(N,) bool: the layout vertices that have an anchor (indices out of range are ignored)."""
    mask = np.zeros(vertex_count, dtype=bool)
    indices = anchors.vertex_indices
    mask[indices[(indices >= 0) & (indices < vertex_count)]] = True
    return mask


def valid_vertex_mask(anchors: Anchors, vertex_count: int) -> np.ndarray:
    """(K,) bool: the anchors whose vertex exists in a layout of ``vertex_count`` vertices."""
    return (anchors.vertex_indices >= 0) & (anchors.vertex_indices < vertex_count)


# ---------------------------------------------------------------- validation


def check_vertex_index(vertex_index: int, vertex_count: int) -> int:
    """``vertex_index`` as an int; raises :class:`LayoutError` when it is not a vertex of the layout."""
    vertex_index = int(vertex_index)
    if not 0 <= vertex_index < vertex_count:
        raise LayoutError(f"Vertex index {vertex_index} is out of range: the layout has {vertex_count} vertices")
    return vertex_index


def check_anchor_vertices(anchor_list, vertex_count: int) -> None:
    """Raise :class:`~.errors.LayoutError` naming the anchors whose vertex the layout no longer has (the wrap
    and the alignment both refuse them: an anchor refers to a vertex index)."""
    vertex_indices = np.asarray(anchor_list.vertex_indices, dtype=np.int64).reshape(-1)
    missing = np.flatnonzero((vertex_indices < 0) | (vertex_indices >= vertex_count))
    if missing.size:
        shown = ", ".join(f"anchor {int(index)} (vertex {int(vertex_indices[index])})" for index in missing[:5])
        more = f" and {missing.size - 5} more" if missing.size > 5 else ""
        raise LayoutError(
            f"{missing.size} anchors are on vertices the layout no longer has (it has {vertex_count}): "
            f"{shown}{more}: the layout lost vertices after they were anchored. Remove those anchors (or Clear "
            "Anchors) and anchor again; Update Anchors re-reads target points only and keeps them on missing vertices"
        )


def check_location(location, what: str = "The anchor location") -> np.ndarray:
    """``location`` as a (3,) float64 array; raises :class:`LayoutError` when it is not three finite numbers."""
    location = np.asarray(location, dtype=np.float64).reshape(-1)
    if location.shape != (3,) or not np.all(np.isfinite(location)):
        raise LayoutError(f"{what} has a NaN or infinite coordinate: {tuple(location.tolist())}")
    return location


def check_anchor_locations(anchors: Anchors, mask: np.ndarray | None = None) -> None:
    """Raise :class:`LayoutError` naming the first anchor (in ``mask``) whose target location is not finite."""
    finite = np.all(np.isfinite(anchors.locations), axis=1)
    if mask is not None:
        finite |= ~np.asarray(mask, dtype=bool)
    bad = np.flatnonzero(~finite)
    if bad.size:
        raise LayoutError(
            f"Anchor {int(bad[0])} (vertex {int(anchors.vertex_indices[bad[0]])}) has a NaN or infinite "
            f"target location ({bad.size} such anchors): remove it"
        )


def pick_vertex(selection: np.ndarray, active_vertex: int) -> int:
    """The vertex an anchor is added to when none is given: the active vertex, or the only selected one.

    ``active_vertex`` is the last vertex of the selection history (-1 for none); it counts only
    when it is selected. Raises :class:`LayoutError` when no vertex, or several vertices and no
    active one, are selected.
    """
    selection = np.asarray(selection, dtype=bool).reshape(-1)
    if 0 <= active_vertex < selection.size and selection[active_vertex]:
        return int(active_vertex)
    selected = np.flatnonzero(selection)
    if selected.size == 1:
        return int(selected[0])
    if selected.size == 0:
        raise LayoutError("No selected vertex: select the layout vertex to anchor (or give a vertex index)")
    raise LayoutError(f"{selected.size} vertices are selected and none is active: select the one to anchor")


# ---------------------------------------------------------------- target changes


def resolve(anchors: Anchors, target: Target, stored_signature: str) -> tuple[Anchors, layout_state.Resolution]:
    """Apply the deleted-face rule to the face anchors, then refresh every face anchor's location.

    When the target's topology changed since the anchors were written (``stored_signature``), or
    an anchor's triangle does not exist, the face anchor is looked up on the current surface at
    its cached location: close enough it re-attaches, otherwise it becomes a space anchor at that
    location. Returns the new anchors and the :class:`~.layout_state.Resolution` counts.
    """
    state = as_state(anchors)
    mask = layout_state.face_points_to_resolve(state, target.mesh.triangle_count, stored_signature, target.signature)
    check_anchor_locations(anchors, mask)
    resolution = resolve_points(state, mask, anchors.locations[mask], target)
    resolved = with_state(anchors, resolution.state)
    return refresh_locations(resolved, target), resolution


def refresh_locations(anchors: Anchors, target: Target) -> Anchors:
    """The anchors with each face anchor's location recomputed on the target (triangle + barycentric).

    The triangles must exist on the target (:func:`resolve` sees to it).
    """
    is_face = anchors.kinds == FACE_ANCHOR
    if not is_face.any():
        return anchors
    positions = target.mesh.face_point_positions(
        np.ascontiguousarray(anchors.triangles[is_face], dtype=np.uint32),
        np.ascontiguousarray(anchors.barycentrics[is_face], dtype=np.float32),
    )
    locations = anchors.locations.copy()
    locations[is_face] = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    return anchors._replace(locations=locations)


# ---------------------------------------------------------------- spacing


def default_spacing(points: np.ndarray) -> float:
    """:data:`DEFAULT_SPACING_FRACTION` of the bounding-box diagonal of the finite points (1.0 when it is 0)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if not points.shape[0]:
        return 1.0
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    return DEFAULT_SPACING_FRACTION * diagonal if diagonal > 0.0 else 1.0


def spaced_indices(
    points: np.ndarray,
    spacing: float,
    candidates: np.ndarray | None = None,
    seeds: np.ndarray | None = None,
) -> np.ndarray:
    """Greedy Poisson-disk choice of points: no two chosen (or seed) points closer than ``spacing``.

    Candidates are visited in index order (deterministic); a candidate is chosen when no point
    chosen so far and no seed lies closer than ``spacing``. The choice is maximal: every
    candidate ends within ``spacing`` of a chosen point or a seed. A grid hash with cells of
    size ``spacing`` keeps it linear (each point looks at its 27 neighbouring cells).

    ``points``: (N, 3); ``candidates``: (N,) bool, default all; ``seeds``: (S, 3) points that
    count as already chosen (existing anchors). Returns the chosen indices, ascending.
    Non-finite candidates must be excluded by the caller.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    spacing = float(spacing)
    if not (np.isfinite(spacing) and spacing > 0.0):
        raise LayoutError(f"The anchor spacing must be a positive distance, not {spacing!r}")
    indices = np.arange(points.shape[0]) if candidates is None else np.flatnonzero(np.asarray(candidates, dtype=bool))
    seeds = np.zeros((0, 3)) if seeds is None else np.asarray(seeds, dtype=np.float64).reshape(-1, 3)
    seeds = seeds[np.all(np.isfinite(seeds), axis=1)]
    if not indices.size:
        return indices.astype(np.int64)
    everything = np.concatenate([seeds, points[indices]])
    if not np.all(np.isfinite(everything)):
        raise LayoutError("A candidate point for an anchor has a NaN or infinite coordinate")
    origin = everything.min(axis=0)
    scaled = (everything - origin) / spacing
    if scaled.max() > 1e12:
        raise LayoutError(f"The anchor spacing {spacing:.3g} is too small for the size of the layout")
    cells = np.floor(scaled).astype(np.int64) + 1  # >= 1, so every neighbour cell is >= 0
    extent = int(cells.max()) + 2
    keys = ((cells[:, 0] * extent + cells[:, 1]) * extent + cells[:, 2]).tolist()
    steps = (-1, 0, 1)
    neighbour_offsets = [(dx * extent + dy) * extent + dz for dx in steps for dy in steps for dz in steps]
    grid: dict[int, list[tuple[float, float, float]]] = {}
    for key, seed in zip(keys, seeds.tolist()):
        grid.setdefault(key, []).append(seed)
    squared_spacing = spacing * spacing
    chosen = []
    seed_count = seeds.shape[0]
    for position, (key, (x, y, z)) in enumerate(zip(keys[seed_count:], points[indices].tolist())):
        free = True
        for offset in neighbour_offsets:
            bucket = grid.get(key + offset)
            if bucket is None:
                continue
            for qx, qy, qz in bucket:
                if (x - qx) ** 2 + (y - qy) ** 2 + (z - qz) ** 2 < squared_spacing:
                    free = False
                    break
            if not free:
                break
        if free:
            grid.setdefault(key, []).append((x, y, z))
            chosen.append(indices[position])
    return np.asarray(chosen, dtype=np.int64)


# ---------------------------------------------------------------- operations


def add(
    vertex_count: int,
    existing: Anchors,
    target: Target,
    stored_signature: str,
    vertex_index: int,
    location,
    on_surface: bool = True,
) -> AnchorOutcome:
    """Anchor one layout vertex to the target point closest to ``location`` (world space).

    With ``on_surface=False`` the anchor is a space anchor at ``location`` itself. An anchor
    already on that vertex is replaced. The existing anchors are resolved and refreshed first.
    """
    vertex_index = check_vertex_index(vertex_index, vertex_count)
    location = check_location(location)
    anchors, resolution = resolve(existing, target, stored_signature)
    if on_surface:
        hits = target.mesh.closest_points(location)
        triangle = int(hits.triangles[0])
        if triangle < 0:
            raise LayoutError(f"No point of target '{target.name}' found near {tuple(location.tolist())}")
        new = make_anchors([vertex_index], [FACE_ANCHOR], [triangle], hits.barycentrics, hits.positions)
    else:
        new = make_anchors([vertex_index], [SPACE_ANCHOR], [NO_FACE], np.zeros((1, 3)), location)
    kept = anchors.vertex_indices != vertex_index
    result = unpair_broken(concatenate(take(anchors, kept), new))
    return AnchorOutcome(
        anchors=result,
        active_index=anchor_count(result) - 1,
        added_count=1,
        replaced_count=int(np.count_nonzero(~kept)),
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )


def auto(
    layout: LayoutArrays,
    world_normals: np.ndarray | None,
    existing: Anchors,
    target: Target,
    stored_signature: str,
    spacing: float,
    method: str,
    replace: bool,
    max_distance: float = 0.0,
    candidates: np.ndarray | None = None,
) -> AnchorOutcome:
    """Anchors spread evenly over the layout: no two closer than ``spacing`` (world units), on the vertices
    ``candidates`` (N,) bool allows (default all).

    ``spacing`` 0 means :func:`default_spacing` of the layout. Vertices are chosen by
    :func:`spaced_indices` in index order; their targets are the closest surface points
    (``'CLOSEST'``) or the nearer ray hit along the vertex normal, both ways (``'PROJECT'``;
    ``world_normals`` (N, 3), zero for vertices on no face, which are skipped). Misses, and hits
    farther than ``max_distance`` (0 = unlimited), are counted and get no anchor.
    ``replace`` drops the existing anchors first; otherwise they are kept, their vertices are
    not anchored again, and new anchors keep ``spacing`` from them too.
    """
    if method not in METHODS:
        raise ValueError(f"unknown anchor method {method!r}")
    if not (np.isfinite(max_distance) and max_distance >= 0.0):
        raise LayoutError(f"The maximum distance must not be negative, not {max_distance!r}")
    vertex_count = layout.positions.shape[0]
    world = transforms.world_positions(layout)
    if replace:
        kept, resolution = no_anchors(), layout_state.Resolution(as_state(no_anchors()), 0, 0)
    else:
        kept, resolution = resolve(existing, target, stored_signature)
    spacing = float(spacing) if spacing > 0.0 else default_spacing(world)
    candidates = ~anchored_mask(kept, vertex_count) & (True if candidates is None else np.asarray(candidates, bool))
    layout_state.check_finite(layout, candidates)
    seeds = world[kept.vertex_indices[valid_vertex_mask(kept, vertex_count)]]
    chosen = spaced_indices(world, spacing, candidates, seeds)
    if chosen.size > MAX_AUTO_ANCHORS:
        raise LayoutError(
            f"A spacing of {spacing:.4g} would create {chosen.size} anchors (more than {MAX_AUTO_ANCHORS}): "
            "use a larger spacing"
        )
    skipped_count = 0
    limit = {"max_distance": float(max_distance)} if max_distance > 0.0 else {}
    if method == "CLOSEST" or not chosen.size:
        hits = target.mesh.closest_points(world[chosen], **limit)
        queried = chosen
    else:
        if world_normals is None:
            raise ValueError("PROJECT needs the layout's world normals")
        directions = transforms.normalize_or_zero(np.asarray(world_normals)[chosen])
        has_direction = np.any(directions != 0.0, axis=1)
        skipped_count = int(np.count_nonzero(~has_direction))
        queried = chosen[has_direction]
        hits = target.mesh.ray_cast(
            world[queried],
            directions[has_direction],
            both_directions=True,
            **limit,
        )
    hit = np.asarray(hits.triangles) >= 0
    if max_distance > 0.0:
        hit &= np.abs(np.asarray(hits.distances, dtype=np.float64)) <= max_distance
    new = make_anchors(
        queried[hit],
        np.full(int(np.count_nonzero(hit)), FACE_ANCHOR),
        np.asarray(hits.triangles)[hit],
        np.asarray(hits.barycentrics).reshape(-1, 3)[hit],
        np.asarray(hits.positions, dtype=np.float64).reshape(-1, 3)[hit],
    )
    result = concatenate(kept, new)
    return AnchorOutcome(
        anchors=result,
        active_index=-1,
        added_count=anchor_count(new),
        replaced_count=0 if not replace else anchor_count(existing),
        missed_count=int(np.count_nonzero(~hit)),
        skipped_count=skipped_count,
        spacing=spacing,
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )


def update(existing: Anchors, target: Target, stored_signature: str) -> AnchorOutcome:
    """The anchors resolved on the current target and their locations refreshed; nothing added."""
    anchors, resolution = resolve(existing, target, stored_signature)
    return AnchorOutcome(
        anchors,
        -1,
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )


def remove(existing: Anchors, index: int, with_twin: bool = False) -> Anchors:
    """The list without the anchor at ``index`` (and its twin anchor, ``with_twin``); raises :class:`LayoutError`
    when there is none. A twin left alone is unpaired."""
    count = anchor_count(existing)
    if not 0 <= index < count:
        raise LayoutError(f"There is no anchor {index}: the layout has {count} anchors")
    keep = np.ones(count, dtype=bool)
    keep[index] = False
    if with_twin and partner_indices(existing)[index] >= 0:
        keep[partner_indices(existing)[index]] = False
    return unpair_broken(take(existing, keep))


def clamp_active_index(active_index: int, count: int) -> int:
    """An active-anchor index that points into a list of ``count`` anchors (-1 when it is empty)."""
    if count == 0:
        return -1
    return min(max(int(active_index), 0), count - 1)


def segments(anchors: Anchors, world_vertex_positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the viewport draws: (K', 3) float32 layout points and their (K', 3) target points.

    ``world_vertex_positions`` are the positions of the anchors' vertices, one row per anchor
    (NaN for a vertex that no longer exists); anchors with a non-finite end are left out.
    """
    starts = np.asarray(world_vertex_positions, dtype=np.float64).reshape(-1, 3)
    ends = anchors.locations
    drawable = np.all(np.isfinite(starts), axis=1) & np.all(np.isfinite(ends), axis=1)
    return transforms.as_float32_points(starts[drawable]), transforms.as_float32_points(ends[drawable])
