"""Curve constraints on arrays (paper section 2.4): numpy, no ``bpy``.

A curve constraint pairs a chain of layout edges (its vertices in order) with a target curve, a
world-space polyline in the same direction: a Blender curve object, or a chain of target mesh
edges. The wrap hands them to the kernel, which matches each chain vertex to the polyline point
at the same fraction of arc length.

The functions here order selected edges into a chain, find target edge chains that follow a
layout chain's course (``edge_paths``), orient polylines by the
whole chain, pair layout curves automatically, and check and flatten constraints for the kernel;
``blender.curves`` reads and writes them, ``operators.curves`` only call and report. Every function
returns new arrays and leaves its inputs untouched.
"""

from typing import Any, NamedTuple

import numpy as np

from .edge_paths import chain_course, cumulative_lengths, edge_graph, following_path, length_fractions, nearest_vertex
from .errors import LayoutError

CURVE_OBJECT = "CURVE_OBJECT"
"""Source of a constraint whose target is a Blender curve object."""
TARGET_EDGES = "TARGET_EDGES"
"""Source of a constraint whose target is a chain of target mesh edges."""
FEATURE_LINE = "FEATURE_LINE"
"""Source of a constraint pairing a layout feature line with a stretch of a target feature (the polyline kept)."""

SKIP_REASONS = {
    "closed": "the layout curve is closed",
    "unanchored": "an end of the layout curve has no anchor",
    "ambiguous": "both ends anchor to the same target vertex",
    "constrained": "its vertices are already constrained by another pairing",
    "unreachable": "no target edge chain joins the two anchor targets",
}
"""Why ``auto_pairs`` skips a layout curve (key -> sentence for the report)."""


class CurveConstraint(NamedTuple):
    """One curve constraint: a layout chain and its target polyline (world space, same direction)."""

    layout_vertices: np.ndarray  # (C,) int64 layout vertices in order along the chain
    points: np.ndarray  # (P, 3) float64 world-space target polyline, its start at the chain's start
    source_kind: str  # CURVE_OBJECT or TARGET_EDGES
    target_vertices: np.ndarray  # (P,) int64 target vertices of a TARGET_EDGES polyline, empty otherwise
    curve_object: Any = None  # the curve object of a CURVE_OBJECT constraint (opaque here)
    confidence: float = 0.0  # how sure the pairing of a FEATURE_LINE constraint was (0 to 1)
    fractions: np.ndarray = np.zeros(0)  # (C,) where each chain vertex goes along the polyline; empty: as spaced


class AutoOutcome(NamedTuple):
    """What ``auto_pairs`` found: the new constraints and how many curves were skipped, by reason."""

    constraints: list  # of CurveConstraint
    skipped: dict  # SKIP_REASONS key -> count


def make_constraint(
    layout_vertices, points, source_kind, target_vertices=(), curve_object=None, confidence=0.0, fractions=()
) -> CurveConstraint:
    """A :class:`CurveConstraint` with the right dtypes and shapes. ``fractions``: where along ``points`` each
    chain vertex goes (fractions of its length, one per vertex), or empty: at the fraction of the chain's own length
    the vertex has when the wrap starts."""
    if source_kind not in (CURVE_OBJECT, TARGET_EDGES, FEATURE_LINE):
        raise ValueError(f"unknown curve constraint source {source_kind!r}")
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1).copy()
    if fractions.size and fractions.size != np.asarray(layout_vertices).size:
        raise ValueError(f"{fractions.size} fractions for a chain of {np.asarray(layout_vertices).size} vertices")
    return CurveConstraint(
        layout_vertices=np.asarray(layout_vertices, dtype=np.int64).reshape(-1).copy(),
        points=np.asarray(points, dtype=np.float64).reshape(-1, 3).copy(),
        source_kind=source_kind,
        target_vertices=np.asarray(target_vertices, dtype=np.int64).reshape(-1).copy(),
        curve_object=curve_object,
        confidence=float(confidence),
        fractions=fractions,
    )


# ---------------------------------------------------------------- orientation

CLOSED_TOLERANCE = 1e-5
"""A polyline whose last point is within this fraction of its length of its first is closed (a loop)."""


def is_closed(points) -> bool:
    """Whether the polyline ``points`` (P, 3) ends where it starts (a loop: a closed feature curve)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if points.shape[0] < 4:  # a loop needs three distinct points
        return False
    length = cumulative_lengths(points)[-1]
    return bool(length > 0.0 and np.linalg.norm(points[-1] - points[0]) <= CLOSED_TOLERANCE * length)


def matching_error(chain_positions, points) -> float:
    """Mean distance between the chain's vertices and the points of the polyline the wrap pulls them
    to (the same fraction of arc length: :func:`arc_length_points`)."""
    chain_positions = np.asarray(chain_positions, dtype=np.float64).reshape(-1, 3)
    return float(np.linalg.norm(arc_length_points(chain_positions, points) - chain_positions, axis=1).mean())


def _loop_parameter(loop: np.ndarray, cumulative: np.ndarray, point: np.ndarray) -> float:
    """Arc-length parameter of the point of the closed polyline ``loop`` nearest to ``point``."""
    starts, direction = loop[:-1], np.diff(loop, axis=0)
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(((point[None, :] - starts) * direction).sum(axis=1) / squared, 0.0, 1.0)
    distances = ((starts + t[:, None] * direction - point[None, :]) ** 2).sum(axis=1)
    segment = int(np.argmin(distances))
    return float(cumulative[segment] + t[segment] * (cumulative[segment + 1] - cumulative[segment]))


def _loop_arc(loop: np.ndarray, cumulative: np.ndarray, begin: float, length: float) -> np.ndarray:
    """The piece of the closed polyline ``loop`` from parameter ``begin`` on, ``length`` long (at most once round)."""
    total = cumulative[-1]
    twice = np.concatenate([loop[:-1], loop])
    twice_cumulative = np.concatenate([cumulative[:-1], cumulative + total])
    finish = begin + length
    margin = 1e-9 * total
    inside = (twice_cumulative > begin + margin) & (twice_cumulative < finish - margin)
    ends = np.stack([np.interp([begin, finish], twice_cumulative, twice[:, axis]) for axis in range(3)], axis=1)
    return np.concatenate([ends[:1], twice[inside], ends[1:]])


def _candidates(points: np.ndarray, chain_positions: np.ndarray) -> list:
    """The polylines a chain may follow along ``points``: both directions of an open polyline; for a
    closed one, in each direction, the piece from the point nearest the chain's first vertex to the
    point nearest its last, and the whole loop from the first (a chain whose ends meet)."""
    if not is_closed(points):
        return [points, points[::-1]]
    found = []
    for loop in (points, points[::-1]):
        cumulative = cumulative_lengths(loop)
        total = cumulative[-1]
        begin = _loop_parameter(loop, cumulative, chain_positions[0])
        finish = _loop_parameter(loop, cumulative, chain_positions[-1])
        piece = (finish - begin) % total
        if piece > 1e-6 * total:
            found.append(_loop_arc(loop, cumulative, begin, piece))
        found.append(_loop_arc(loop, cumulative, begin, total))
    return found


def orient_to_chain(points, chain_positions) -> np.ndarray:
    """The target polyline ``points`` (P, 3) as a chain (``chain_positions``, (C, 3) in order) should
    follow it: the way round — and, for a closed polyline (:func:`is_closed`), the piece of it —
    along which the chain's vertices lie nearest to the points the wrap pulls them to
    (:func:`matching_error`: the whole chain decides, not its first vertex alone; an opened ring's
    two ends are next to each other). Ties keep the polyline as it is.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    chain_positions = np.asarray(chain_positions, dtype=np.float64).reshape(-1, 3)
    if points.shape[0] < 2 or chain_positions.shape[0] < 1:
        return points.copy()
    candidates = _candidates(points, chain_positions)
    errors = [matching_error(chain_positions, candidate) for candidate in candidates]
    return np.array(candidates[int(np.argmin(errors))], dtype=np.float64)


# ---------------------------------------------------------------- pairing


def constrained_vertices(constraints, anchored: np.ndarray | None = None) -> set:
    """The layout vertices some constraint holds, anchored vertices excepted (they may be shared)."""
    held = set()
    for constraint in constraints:
        for vertex in constraint.layout_vertices.tolist():
            if anchored is None or not (0 <= vertex < anchored.shape[0] and anchored[vertex]):
                held.add(vertex)
    return held


def check_free(chain, constraints, anchored: np.ndarray | None = None) -> None:
    """Raise :class:`LayoutError` when a vertex of ``chain`` (not anchored) is held by one of ``constraints``."""
    held = constrained_vertices(constraints, anchored)
    for vertex in np.asarray(chain).tolist():
        if vertex in held and not (anchored is not None and 0 <= vertex < anchored.shape[0] and anchored[vertex]):
            raise LayoutError(
                f"Layout vertex {vertex} already belongs to another curve constraint: a vertex may follow one "
                "target curve only (remove that constraint first)"
            )


def target_edge_constraint(
    chain, chain_positions, start_point, end_point, target_positions, target_edges
) -> CurveConstraint:
    """A TARGET_EDGES constraint: ``chain`` paired with a target edge path between the target
    vertices nearest to ``start_point`` (the chain's first vertex's end) and ``end_point`` that
    follows the chain's course (``chain_positions``, (C, 3) world; :func:`following_path`).

    Raises :class:`LayoutError` when both ends find the same target vertex (ambiguous) or no path.
    """
    start = nearest_vertex(target_positions, start_point)
    end = nearest_vertex(target_positions, end_point)
    if start == end:
        raise LayoutError(f"Both ends of the chain are nearest to target vertex {start}: the target curve is ambiguous")
    graph = edge_graph(target_positions, target_edges)
    course = chain_course(chain_positions, start_point, end_point)
    path = following_path(target_positions, graph, course, start, end)
    points = np.asarray(target_positions, dtype=np.float64).reshape(-1, 3)[path]
    return make_constraint(chain, points, TARGET_EDGES, path)


def auto_pairs(
    layout_curves,
    anchor_vertices,
    anchor_locations,
    existing,
    target_positions,
    target_edges,
    layout_positions,
) -> AutoOutcome:
    """Pair every layout curve whose two ends carry anchors with the target edge path between them
    that follows the curve's course (:func:`following_path`).

    ``layout_curves``: (kind, vertices in order, closed) per curve (the kernel's
    ``LayoutStructure.curves()``); ``anchor_vertices`` (K,) and ``anchor_locations`` (K, 3) the
    anchors' vertices and world-space targets; ``existing`` the constraints already there;
    ``layout_positions`` (V, 3) the layout's world positions. A curve is skipped (and counted
    under a :data:`SKIP_REASONS` key) when it is closed, an end has no anchor, both anchors find
    the same target vertex, a vertex (not anchored) is already constrained, or no target path
    joins them.
    """
    layout_positions = np.asarray(layout_positions, dtype=np.float64).reshape(-1, 3)
    vertex_count = layout_positions.shape[0]
    anchor_vertices = np.asarray(anchor_vertices, dtype=np.int64).reshape(-1)
    anchor_locations = np.asarray(anchor_locations, dtype=np.float64).reshape(-1, 3)
    location_of = {int(vertex): anchor_locations[row] for row, vertex in enumerate(anchor_vertices.tolist())}
    anchored = np.zeros(vertex_count, dtype=bool)
    valid = anchor_vertices[(anchor_vertices >= 0) & (anchor_vertices < vertex_count)]
    anchored[valid] = True
    skipped = {key: 0 for key in SKIP_REASONS}
    found = []
    graph = None
    for _kind, vertices, closed in layout_curves:
        chain = np.asarray(vertices, dtype=np.int64).reshape(-1)
        if closed or chain.size < 2 or chain[0] == chain[-1]:
            skipped["closed"] += 1
            continue
        first, last = int(chain[0]), int(chain[-1])
        if first not in location_of or last not in location_of:
            skipped["unanchored"] += 1
            continue
        try:
            check_free(chain, list(existing) + found, anchored)
        except LayoutError:
            skipped["constrained"] += 1
            continue
        start = nearest_vertex(target_positions, location_of[first])
        end = nearest_vertex(target_positions, location_of[last])
        if start == end:
            skipped["ambiguous"] += 1
            continue
        if graph is None:
            graph = edge_graph(target_positions, target_edges)
        course = chain_course(layout_positions[chain], location_of[first], location_of[last])
        try:
            path = following_path(target_positions, graph, course, start, end)
        except LayoutError:
            skipped["unreachable"] += 1
            continue
        points = np.asarray(target_positions, dtype=np.float64).reshape(-1, 3)[path]
        found.append(make_constraint(chain, points, TARGET_EDGES, path))
    return AutoOutcome(found, skipped)


SKIP_ADVICE = {
    "closed": "a closed curve (a loop) is paired only in part: mark a seam along the part to follow, or select "
    "that edge chain and add it by hand (+)",
    "unanchored": "anchor both ends of each curve to pair (an anchor on each end vertex)",
    "ambiguous": "move one of the two anchors so that they find different target vertices",
    "constrained": "remove the constraint already on those vertices first",
    "unreachable": "the target has no chain of edges between those anchors: pair the curve with a curve object "
    "instead (select the chain, Curve Object, +)",
}
"""What to do about the commonest reason when nothing was paired."""


def auto_pairs_report(curve_count: int, outcome: AutoOutcome) -> tuple[str, str]:
    """``(report level, text)`` of ``auto_pairs`` on a layout with ``curve_count`` curves: what was paired, what
    was skipped and why, and when nothing was paired, the reason and what to do (a WARNING)."""
    paired = len(outcome.constraints)
    text = f"Paired {paired} layout curve{'' if paired == 1 else 's'} with target edge chains"
    if curve_count == 0:
        return "WARNING", (
            f"{text}: the layout has no curve to pair (no open border, no edge marked as seam, no loose edge "
            "chain; a closed body has none). Mark Seam along the edges to follow and anchor both ends, or select "
            "an edge chain and add a constraint by hand (+)"
        )
    skipped = skip_report(outcome.skipped)
    if paired:
        return "INFO", f"{text}; {skipped}" if skipped else text
    commonest = max(outcome.skipped, key=outcome.skipped.get)
    return "WARNING", f"{text} of its {curve_count}: {skipped}. {SKIP_ADVICE[commonest].capitalize()}"


def skip_report(skipped: dict) -> str:
    """``"2 skipped: 1 the layout curve is closed, 1 ..."``, or ``""`` when nothing was skipped."""
    parts = [f"{count} {SKIP_REASONS[key]}" for key, count in skipped.items() if count]
    if not parts:
        return ""
    return f"{sum(skipped.values())} skipped: " + ", ".join(parts)


# ---------------------------------------------------------------- the wrap


def kernel_arrays(constraints, vertex_count: int, anchored: np.ndarray | None = None, origin=None):
    """The kernel's flat arrays ``(curve_vertices, curve_vertex_counts, curve_points, curve_point_counts,
    curve_fractions)`` (the fractions NaN for a chain without), the points relative to ``origin`` (the kernel's
    frame, see ``wrap_inputs.WrapInputs``).

    Raises :class:`LayoutError` naming the constraint when a chain has fewer than two vertices or
    a vertex the layout does not have, a polyline fewer than two points or a non-finite one, or a
    (non-anchored) vertex belongs to two constraints. Returns None when there are no constraints.
    """
    constraints = list(constraints)
    if not constraints:
        return None
    held: dict[int, int] = {}
    for number, constraint in enumerate(constraints):
        chain, points = constraint.layout_vertices, constraint.points
        label = f"Curve constraint {number}"
        if chain.size < 2:
            raise LayoutError(f"{label} has {chain.size} layout vertices: a chain needs at least two")
        bad = chain[(chain < 0) | (chain >= vertex_count)]
        if bad.size:
            raise LayoutError(
                f"{label} uses vertex {int(bad[0])}, which the layout no longer has (it has {vertex_count}): remove it"
            )
        if points.shape[0] < 2:
            raise LayoutError(f"{label} has a target curve of {points.shape[0]} points: it needs at least two")
        if not np.all(np.isfinite(points)):
            raise LayoutError(f"{label} has a NaN or infinite target point")
        fractions = constraint.fractions
        if fractions.size and (fractions.size != chain.size or not np.all((fractions >= 0.0) & (fractions <= 1.0))):
            raise LayoutError(f"{label} has placements that are not one per vertex from 0 to 1: pair it again")
        for vertex in chain.tolist():
            if anchored is not None and anchored[vertex]:
                continue
            if vertex in held:
                raise LayoutError(
                    f"Layout vertex {vertex} belongs to curve constraints {held[vertex]} and {number}: remove one"
                )
            held[vertex] = number
    placed = [c.fractions if c.fractions.size else np.full(c.layout_vertices.size, np.nan) for c in constraints]
    return (
        np.ascontiguousarray(np.concatenate([c.layout_vertices for c in constraints]), dtype=np.uint32),
        np.asarray([c.layout_vertices.size for c in constraints], dtype=np.uint32),
        np.ascontiguousarray(
            np.concatenate([c.points for c in constraints]) - (0.0 if origin is None else np.asarray(origin)),
            dtype=np.float32,
        ),
        np.asarray([c.points.shape[0] for c in constraints], dtype=np.uint32),
        np.ascontiguousarray(np.concatenate(placed), dtype=np.float32),
    )


# ---------------------------------------------------------------- drawing


def arc_length_points(chain_positions, points, fractions=()) -> np.ndarray:
    """(C, 3): for each chain vertex, the polyline point at the same fraction of arc length (or at its
    ``fractions`` entry, when given: one per vertex)."""
    chain_positions = np.asarray(chain_positions, dtype=np.float64).reshape(-1, 3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if points.shape[0] == 0:
        return np.full_like(chain_positions, np.nan)
    if points.shape[0] == 1:
        return np.repeat(points, chain_positions.shape[0], axis=0)
    point_lengths = cumulative_lengths(points)
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1)
    wanted = (fractions if fractions.size else length_fractions(chain_positions)) * point_lengths[-1]
    return np.stack([np.interp(wanted, point_lengths, points[:, axis]) for axis in range(3)], axis=1)


def dashed_segments(starts, ends, dash_count: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Each line ``starts[i] -> ends[i]`` cut into ``dash_count`` dashes (every other piece of 2·n-1).

    Returns float32 (L·n, 3) dash starts and ends; lines with a non-finite end are left out.
    """
    starts = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
    ends = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
    finite = np.all(np.isfinite(starts), axis=1) & np.all(np.isfinite(ends), axis=1)
    starts, ends = starts[finite], ends[finite]
    pieces = 2 * dash_count - 1
    first = np.arange(0, pieces, 2, dtype=np.float64) / pieces
    second = first + 1.0 / pieces
    direction = ends - starts
    dash_starts = starts[:, None, :] + first[None, :, None] * direction[:, None, :]
    dash_ends = starts[:, None, :] + second[None, :, None] * direction[:, None, :]
    return dash_starts.reshape(-1, 3).astype(np.float32), dash_ends.reshape(-1, 3).astype(np.float32)


def parse_indices(text: str) -> np.ndarray:
    """The vertex indices stored as text (``"0 1 2"``), as int64; raises :class:`LayoutError` when malformed."""
    try:
        return np.asarray([int(part) for part in text.split()], dtype=np.int64)
    except ValueError as error:
        raise LayoutError(f"Malformed vertex index list {text[:40]!r}") from error


def format_indices(indices) -> str:
    """Vertex indices as the text :func:`parse_indices` reads."""
    return " ".join(str(int(index)) for index in np.asarray(indices).reshape(-1).tolist())
