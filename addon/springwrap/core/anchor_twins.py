"""Symmetric anchors (numpy and the kernel, no ``bpy``): each anchor and its twin across a symmetry plane.

The layout twin of an anchored vertex is its twin vertex (``symmetry.vertex_twins``: by topology, else
by position). The twin's target is the reflection of the anchor's target point across the plane (world
space), put on the closest point of the target for a face anchor; a space anchor's twin is the
reflection itself. The closest point must lie within the *reach* (``max_distance``, or
:data:`TWIN_REACH_FRACTION` of the target's bounding-box diagonal) of the reflection: farther, the target
has nothing there and the anchor stays alone. An anchor on the plane (its vertex is its own twin) is its
own twin. The pair is stored on both anchors (``Anchors.twins``: the other's vertex).
"""

from typing import NamedTuple

import numpy as np

from . import anchors as anchor_module
from . import transforms
from .anchors import FACE_ANCHOR, SPACE_ANCHOR, AnchorOutcome, Anchors
from .errors import LayoutError
from .layout_state import NO_FACE
from .mirroring import Plane, reflect
from .symmetry import HOW, Twins
from .target import Target

TWIN_REACH_FRACTION = 0.05
"""Without a maximum distance, a twin's target must lie within this fraction of the target's diagonal of the
reflection of the anchor's target point."""


class TwinReport(NamedTuple):
    """What the symmetric half of an anchor operation did, for the report."""

    paired_count: int  # anchors added as the twin of another
    on_plane_count: int  # anchors that are their own twin (their vertex on the plane)
    no_vertex_count: int  # anchors left alone: their vertex has no twin
    no_target_count: int  # anchors left alone: the target has no point near the reflection
    how: str  # add: how the twin vertex was found ("by topology", "by position", "no twin", "on the plane")
    twin_vertex: int  # add: the twin's vertex, -1 without one


def reach(target: Target, max_distance: float = 0.0) -> float:
    """How far from the reflection a twin's target may be (world units)."""
    if max_distance > 0.0:
        return float(max_distance)
    low, high = target.mesh.bounding_box()
    return TWIN_REACH_FRACTION * float(np.linalg.norm(np.asarray(high, np.float64) - np.asarray(low, np.float64)))


def twin_targets(anchor_list: Anchors, plane: Plane, target: Target, limit: float):
    """The twins' targets of ``anchor_list``: ``(kinds, triangles, barycentrics, locations, found)``.

    Face anchors: the closest target point to the reflected location, ``found`` when within ``limit``;
    space anchors: the reflected location (always found).
    """
    locations = reflect(anchor_list.locations, plane)
    count = locations.shape[0]
    kinds = anchor_list.kinds.copy()
    triangles = np.full(count, NO_FACE, dtype=np.int32)
    barycentrics = np.zeros((count, 3), dtype=np.float32)
    found = np.ones(count, dtype=bool)
    on_face = np.flatnonzero(kinds == FACE_ANCHOR)
    if on_face.size:
        hits = target.mesh.closest_points(locations[on_face])
        distances = np.linalg.norm(np.asarray(hits.positions, np.float64) - locations[on_face], axis=1)
        hit = (np.asarray(hits.triangles) >= 0) & (distances <= limit)
        found[on_face] = hit
        triangles[on_face[hit]] = np.asarray(hits.triangles)[hit]
        barycentrics[on_face[hit]] = np.asarray(hits.barycentrics).reshape(-1, 3)[hit]
        locations[on_face[hit]] = np.asarray(hits.positions, np.float64).reshape(-1, 3)[hit]
    kinds[~found] = SPACE_ANCHOR
    return kinds, triangles, barycentrics, locations, found


def add_twins(result: Anchors, new: np.ndarray, twins: Twins, plane: Plane, target: Target, limit: float):
    """``result`` with a twin anchor for each of its anchors at positions ``new``: ``(anchors, TwinReport, replaced)``,
    ``replaced`` the anchors the twins took the place of.

    A twin replaces an anchor already on its vertex (unless that anchor is one of ``new``: then both are
    paired as they are, no anchor is replaced by its own twin's twin).
    """
    new = np.asarray(new, dtype=np.int64)
    vertices = result.vertex_indices[new].astype(np.int64)
    twin_vertices = twins.twins[vertices]
    own = twin_vertices == vertices
    has_twin = (twin_vertices >= 0) & ~own
    is_new_vertex = np.isin(twin_vertices, vertices)
    mirrored = np.flatnonzero(has_twin & ~is_new_vertex)
    kinds, triangles, barycentrics, locations, found = twin_targets(
        anchor_module.take(result, new[mirrored]), plane, target, limit
    )
    added = mirrored[found]
    result_twins = result.twins.copy()
    result_twins[new[own]] = vertices[own]
    result_twins[new[added]] = twin_vertices[added]
    for position in np.flatnonzero(has_twin & is_new_vertex).tolist():  # both ends new: pair them as they are
        result_twins[new[position]] = twin_vertices[position]
    twin_anchors = anchor_module.make_anchors(
        twin_vertices[added], kinds[found], triangles[found], barycentrics[found], locations[found], vertices[added]
    )
    keep = ~np.isin(result.vertex_indices, twin_anchors.vertex_indices)
    combined = anchor_module.concatenate(anchor_module.take(result._replace(twins=result_twins), keep), twin_anchors)
    report = TwinReport(
        paired_count=int(added.size),
        on_plane_count=int(own.sum()),
        no_vertex_count=int(np.count_nonzero(twin_vertices < 0)),
        no_target_count=int(mirrored.size - added.size),
        how="",
        twin_vertex=-1,
    )
    return anchor_module.unpair_broken(combined), report, int(np.count_nonzero(~keep))


def add(twins: Twins, plane: Plane, *arguments) -> tuple[AnchorOutcome, TwinReport]:
    """``anchors.add(*arguments)``, then the anchor's twin (replacing an anchor on the twin's vertex); the anchor
    stays active. ``arguments``: those of ``anchors.add``, all seven."""
    vertex_count, _existing, target, _signature, vertex_index, _location, _on_surface = arguments
    outcome = anchor_module.add(*arguments)
    if twins.twins.shape[0] != vertex_count:
        raise LayoutError("The layout's twins were found on a different mesh")
    result = outcome.anchors
    position = anchor_module.anchor_count(result) - 1
    anchors, report, replaced = add_twins(result, [position], twins, plane, target, reach(target))
    twin_vertex = int(twins.twins[vertex_index])
    how = "on the plane" if twin_vertex == vertex_index else HOW[int(twins.how[vertex_index])]
    active = int(np.flatnonzero(anchors.vertex_indices == vertex_index)[0])
    outcome = outcome._replace(anchors=anchors, active_index=active, added_count=1 + report.paired_count)
    outcome = outcome._replace(replaced_count=outcome.replaced_count + replaced)
    return outcome, report._replace(how=how, twin_vertex=twin_vertex if report.paired_count else -1)


def auto(twins: Twins, plane: Plane, *arguments) -> tuple[AnchorOutcome, TwinReport, int]:
    """``anchors.auto(*arguments)`` on one side of the plane, mirrored: ``(outcome, TwinReport, side)``.
    ``arguments``: those of ``anchors.auto`` from ``layout`` to ``max_distance``, all nine.

    The side (``+1``: the normal's side, ``-1``) is the one with more of the kept anchors (``replace`` off),
    else ``+1``. Anchors are spread over that side's vertices that have a twin, are at least half the spacing
    from the plane (so that a vertex and its twin are the spacing apart) and whose twin is not anchored yet,
    and over the vertices on the plane; then every new anchor gets its twin. Vertices with no twin
    (an asymmetric part), on either side, are spread over last, with no twin, keeping the spacing from
    all the others. On a layout whose vertices all have twins the anchored vertices are then exactly
    symmetric (each anchored vertex's twin is anchored, paired with it).
    """
    layout, world_normals, existing, target, stored_signature, spacing, method, replace, max_distance = arguments
    vertex_count = layout.positions.shape[0]
    if twins.twins.shape[0] != vertex_count:
        raise LayoutError("The layout's twins were found on a different mesh")
    kept = anchor_module.no_anchors() if replace else existing
    kept_vertices = kept.vertex_indices[anchor_module.valid_vertex_mask(kept, vertex_count)].astype(np.int64)
    kept_sides = np.sign(twins.distances[kept_vertices] * ~twins.on_plane[kept_vertices])
    side = -1 if np.count_nonzero(kept_sides < 0) > np.count_nonzero(kept_sides > 0) else 1
    anchored = anchor_module.anchored_mask(kept, vertex_count)
    has_twin = twins.twins >= 0
    twin_anchored = np.zeros(vertex_count, dtype=bool)
    twin_anchored[has_twin] = anchored[twins.twins[has_twin]]
    itself = twins.twins == np.arange(vertex_count)
    spacing = float(spacing) if spacing > 0.0 else anchor_module.default_spacing(transforms.world_positions(layout))
    # Half the spacing from the plane at least (or on it): a vertex and its twin are then the spacing apart.
    first_side = has_twin & ~twin_anchored & (itself | (side * twins.distances >= 0.5 * spacing))
    first = anchor_module.auto(
        layout, world_normals, existing, target, stored_signature, spacing, method, replace, max_distance, first_side
    )
    count_before = anchor_module.anchor_count(first.anchors) - first.added_count
    new = np.arange(count_before, anchor_module.anchor_count(first.anchors))
    limit = reach(target, max_distance)
    paired, report, _replaced = add_twins(first.anchors, new, twins, plane, target, limit)
    lone = anchor_module.auto(
        layout, world_normals, paired, target, target.signature, first.spacing, method, False, max_distance, ~has_twin
    )
    outcome = first._replace(
        anchors=lone.anchors,
        added_count=anchor_module.anchor_count(lone.anchors) - count_before,
        missed_count=first.missed_count + lone.missed_count,
        skipped_count=first.skipped_count + lone.skipped_count,
    )
    return outcome, report._replace(no_vertex_count=lone.added_count), side
