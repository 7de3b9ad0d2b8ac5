"""Pieces of a free feature line, paired on their own (numpy, no ``bpy``).

A layout line that no single target curve takes whole may still run along features for most of its length: on
a scan a crease is often traced in pieces (a rounded valley broken where its bend dips), so the line runs
along two or three curves in turn and is as long as none of them; and a retopology's line often jogs where it
reaches a corner (QuadriFlow's lines turn through a few edges there), so that the mean direction of the whole
line is not its feature's. :func:`pieces` cuts such a line where it turns sharply and where the nearest curve of
its kind changes, and keeps the runs that lie beside one curve; :func:`feature_lines.pair_lines` pairs those
runs as lines of their own (the kernel's tests of closeness, direction and length apply to each), so the
stretches along features are held and the jogs stay free.
"""

from typing import NamedTuple

import numpy as np

SPLIT_DEGREES = 60.0
"""A line that turns by more than this at a vertex (on the rest shape) is cut there, the vertex left out: a jog,
not a feature's bend."""
MIN_PIECE = 4
"""The fewest vertices of a piece: shorter runs say too little about where a feature runs."""
PIECE_REACH = 0.5
"""A vertex runs along a curve only within this share of the max distance of it under the fit: the whole line's
test (the max distance, on the mean) lets a line that leaves its crease for a few vertices stay beside it, a
piece's vertices must each be near."""
RETRIED = ("LOW_CONFIDENCE", "LENGTH_DIFFERS", "NOT_PARALLEL", "NONE_NEARBY")
"""Why a free line is cut into pieces and tried again (a line already within its curve's accuracy, or whose
vertices another constraint holds, is not)."""
CURVE_KINDS = {"RIDGE": ("RIDGE",), "VALLEY": ("VALLEY",), "BORDER": ("BORDER",)}
"""The target curve kinds a line of each kind may follow (a marked line, kind ANY, any curve): the kernel's rule."""


def turning_degrees(points) -> np.ndarray:
    """(P,) float64: how far a polyline ((P, 3)) turns at each point, in degrees (0 at its ends and where an edge
    has no length)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    turning = np.zeros(points.shape[0])
    if points.shape[0] < 3:
        return turning
    steps = np.diff(points, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    unit = steps / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    cosine = np.clip(np.einsum("ij,ij->i", unit[:-1], unit[1:]), -1.0, 1.0)
    valid = (lengths[:-1] > 0.0) & (lengths[1:] > 0.0)
    turning[1:-1] = np.where(valid, np.degrees(np.arccos(cosine)), 0.0)
    return turning


class CurveIndex(NamedTuple):
    """The target curves prepared once for :func:`nearest_curves`: each one's kind, points and bounding box."""

    kinds: np.ndarray  # (K,) str
    points: list  # of (P, 3) float64
    boxes: np.ndarray  # (K, 2, 3) float64 low and high corners


def curve_index(curves_found) -> CurveIndex:
    """:class:`CurveIndex` of ``curves_found`` (``feature_lines.target_curves``' tuples; curves of fewer than two
    points get an empty box and are never nearest)."""
    points = [np.asarray(curve[1], dtype=np.float64).reshape(-1, 3) for curve in curves_found]
    boxes = np.array(
        [
            [p.min(axis=0), p.max(axis=0)] if p.shape[0] >= 2 else [np.full(3, np.inf), np.full(3, -np.inf)]
            for p in points
        ]
    ).reshape(-1, 2, 3)
    return CurveIndex(np.array([curve[0] for curve in curves_found], dtype=object), points, boxes)


def nearest_curves(points, curves, kind: str, max_distance: float) -> np.ndarray:
    """(P,) int64: for each of ``points`` ((P, 3)), the index in ``curves`` (a :class:`CurveIndex`, or
    ``feature_lines.target_curves``' tuples) of the nearest curve a line of ``kind`` may follow, when within
    ``max_distance``; else -1."""
    index = curves if hasattr(curves, "boxes") else curve_index(curves)  # (a CurveIndex of any import of this module)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    best = np.full(points.shape[0], np.inf)
    found = np.full(points.shape[0], -1, dtype=np.int64)
    if points.shape[0] == 0 or index.boxes.shape[0] == 0:
        return found
    allowed = CURVE_KINDS.get(kind)
    low, high = points.min(axis=0) - max_distance, points.max(axis=0) + max_distance
    near = np.all((index.boxes[:, 0] <= high) & (index.boxes[:, 1] >= low), axis=1)
    if allowed is not None:
        near &= np.isin(index.kinds, allowed)
    for curve in np.flatnonzero(near):
        curve_low, curve_high = index.boxes[curve, 0] - max_distance, index.boxes[curve, 1] + max_distance
        inside = np.all((points >= curve_low) & (points <= curve_high), axis=1)
        if not inside.any():
            continue
        distance = np.full(points.shape[0], np.inf)
        distance[inside] = _distance_to_polyline(points[inside], index.points[curve])
        closer = (distance < best) & (distance <= max_distance)
        best[closer], found[closer] = distance[closer], curve
    return found


def _distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """(P,): the distance of each of ``points`` to the polyline ((K, 3), K >= 2)."""
    starts, direction = polyline[:-1], np.diff(polyline, axis=0)
    squared = np.maximum(np.einsum("ij,ij->i", direction, direction), 1e-300)
    nearest = np.full(points.shape[0], np.inf)
    for begin in range(0, starts.shape[0], 256):  # blocks of segments: memory stays (P, 256)
        block = slice(begin, begin + 256)
        offset = points[:, None, :] - starts[None, block]
        t = np.clip(np.einsum("psk,sk->ps", offset, direction[block]) / squared[block], 0.0, 1.0)
        gap = offset - t[..., None] * direction[None, block]
        nearest = np.minimum(nearest, np.sqrt(np.einsum("psk,psk->ps", gap, gap)).min(axis=1))
    return nearest


def pieces(vertices, closed: bool, kind: str, rest, current, curves_found, max_distance: float, left_out) -> list:
    """The pieces (each (C,) int64 vertex indices, in the line's order, ``C >= MIN_PIECE``) of the line through
    ``vertices`` ((L,), ``closed`` when it loops): cut where it turns by more than :data:`SPLIT_DEGREES` on the rest
    shape (``rest``, (N, 3)), where its vertices' nearest curve of its kind (:func:`nearest_curves`, at their
    places under the fit ``current``) changes, and at vertices without a curve within :data:`PIECE_REACH` of
    ``max_distance`` or in
    ``left_out`` (a set: vertices other constraints hold, corners where lines meet), which no piece takes;
    ``curves_found`` may be their :class:`CurveIndex` (built once for many lines).
    Empty when the line stays one piece: it was tried whole."""
    vertices = np.asarray(vertices, dtype=np.int64).reshape(-1)
    if vertices.size < MIN_PIECE:
        return []
    rest = np.asarray(rest, dtype=np.float64)
    ring = np.concatenate([vertices[-1:], vertices, vertices[:1]]) if closed else vertices
    turning = turning_degrees(rest[ring])
    turning = turning[1:-1] if closed else turning
    labels = nearest_curves(
        np.asarray(current, dtype=np.float64)[vertices], curves_found, kind, PIECE_REACH * max_distance
    )
    usable = (labels >= 0) & (turning <= SPLIT_DEGREES)
    usable &= ~np.isin(vertices, np.fromiter(left_out, dtype=np.int64, count=len(left_out)))
    changed = np.concatenate([[True], labels[1:] != labels[:-1]])
    begins = usable & (changed | np.concatenate([[True], ~usable[:-1]]))  # a run begins after a cut
    if closed and usable.all() and not changed[1:].any():
        return []
    found = []
    for start in np.flatnonzero(begins):
        end = start + 1
        while end < vertices.size and usable[end] and not begins[end]:
            end += 1
        found.append(vertices[start:end])
    if closed and len(found) > 1 and usable[0] and usable[-1] and labels[0] == labels[-1]:
        found[0] = np.concatenate([found.pop(), found[0]])  # the run across the loop's first vertex is one
    found = [piece for piece in found if piece.size >= MIN_PIECE]
    if len(found) == 1 and found[0].size == vertices.size:
        return []
    return found
