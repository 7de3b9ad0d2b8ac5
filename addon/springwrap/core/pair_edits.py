"""The pair tool's edits of an anchor list (numpy and the kernel, no ``bpy``): place a pair, move its target
end, move its layout end to another vertex, remove it; with the symmetric setting, the twin with it.

Each edit is an ``anchors.add`` / ``anchor_twins.add`` / ``anchors.remove`` (the same rules as the Add and
Remove Anchor operators: a pair on a vertex that has one replaces it, a face anchor's end is a triangle and
barycentric weights of the target), with one addition an artist dragging a numbered pair expects: an edited
pair keeps its place in the list, so its number does not change (a new pair comes last).
"""

import numpy as np

from . import anchor_twins, anchors
from .anchors import FACE_ANCHOR, AnchorOutcome, Anchors
from .errors import LayoutError


def in_list_order(before: Anchors, after: Anchors, renamed: dict[int, int] | None = None) -> Anchors:
    """``after`` ordered as ``before``: the anchors whose vertex (or, through ``renamed`` (old vertex: new vertex),
    whose former vertex) had an anchor in ``before`` at that anchor's place, the others after them in their own
    order."""
    renamed = renamed or {}
    vertices = before.vertex_indices.tolist()
    place = {int(vertex): row for row, vertex in enumerate(vertices)}
    place |= {renamed[vertex]: row for row, vertex in enumerate(vertices) if vertex in renamed}  # the moved ones win
    count = anchors.anchor_count(before)
    keys = [place.get(int(vertex), count + row) for row, vertex in enumerate(after.vertex_indices.tolist())]
    return anchors.take(after, np.argsort(np.asarray(keys, dtype=np.int64), kind="stable"))


def anchor_of(anchor_list: Anchors, vertex: int) -> int:
    """The list position of the anchor on ``vertex``, -1 when it has none."""
    found = np.flatnonzero(anchor_list.vertex_indices == int(vertex))
    return int(found[0]) if found.size else -1


def place(vertex_count, existing, target, signature, vertex, location, on_surface=True, symmetry=None):
    """Anchor ``vertex`` to the target point at ``location`` (the closest surface point; a space anchor at
    ``location`` itself with ``on_surface`` off), replacing its anchor in place; with ``symmetry``
    (``(symmetry.Twins, mirroring.Plane)``) its twin too. ``(AnchorOutcome, anchor_twins.TwinReport or None)``,
    the pair's anchor active."""
    arguments = (vertex_count, existing, target, signature, vertex, location, on_surface)
    if symmetry is None:
        outcome, report = anchors.add(*arguments), None
    else:
        outcome, report = anchor_twins.add(*symmetry, *arguments)
    ordered = in_list_order(existing, outcome.anchors)
    return outcome._replace(anchors=ordered, active_index=anchor_of(ordered, vertex)), report


def repick(vertex_count, existing, target, signature, index, vertex, symmetry=None):
    """The anchor at ``index`` moved onto layout ``vertex``, its target kept (and its twin's, with ``symmetry``,
    onto ``vertex``'s twin), at its place in the list. An anchor already on ``vertex`` is replaced.
    ``(AnchorOutcome, TwinReport or None)``."""
    count = anchors.anchor_count(existing)
    if not 0 <= index < count:
        raise LayoutError(f"There is no anchor {index}: the layout has {count} anchors")
    vertex = anchors.check_vertex_index(vertex, vertex_count)
    old = int(existing.vertex_indices[index])
    if vertex == old:
        return AnchorOutcome(existing, index), None
    on_surface = int(existing.kinds[index]) == FACE_ANCHOR
    location = existing.locations[index].copy()
    renamed = {old: vertex}
    old_twin = int(existing.twins[index])
    if symmetry is not None and old_twin >= 0 and old_twin != old:
        new_twin = int(symmetry[0].twins[vertex])
        if new_twin >= 0:
            renamed[old_twin] = new_twin
    remaining = anchors.remove(existing, index, with_twin=symmetry is not None)
    outcome, report = place(vertex_count, remaining, target, signature, vertex, location, on_surface, symmetry)
    ordered = in_list_order(existing, outcome.anchors, renamed)
    return outcome._replace(anchors=ordered, active_index=anchor_of(ordered, vertex)), report


def remove(existing: Anchors, index: int, symmetric: bool = False) -> AnchorOutcome:
    """The list without the anchor at ``index`` (and its twin with ``symmetric``); the next one active."""
    remaining = anchors.remove(existing, index, with_twin=symmetric)
    count = anchors.anchor_count(remaining)
    return AnchorOutcome(remaining, anchors.clamp_active_index(min(index, count - 1), count))
