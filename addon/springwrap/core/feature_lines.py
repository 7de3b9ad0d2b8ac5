"""The layout's feature lines paired with the target's feature curves, on arrays (numpy + kernel, no ``bpy``).

A feature line is a chain of layout edges that should land on a feature of the target: edges the artist marked
(sharp or seam edges, a vertex group, a boolean edge attribute), creases of the layout's rest shape (dihedral
angle) and open borders (the rim of a hole). The kernel finds and chains them
(``springwrap_kernel.layout_feature_lines``) and pairs each with a target ridge, valley or hole border that is
close under the current fit, parallel, of its kind and about as long (``springwrap_kernel.pair_feature_lines``);
each pair becomes a curve constraint whose target is that stretch of curve, with the pair's confidence. Lines
without a partner stay free and are listed.
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import curves, line_pieces, line_placement, rounded_creases, sharp_creases, smooth_map
from .errors import LayoutError

FREE_REASONS = {
    "NONE_NEARBY": "no target feature of its kind nearby",
    "NOT_PARALLEL": "the nearby features run across it",
    "LENGTH_DIFFERS": "the nearby features are much shorter or longer",
    "LOW_CONFIDENCE": "below the minimum confidence",
    "TAKEN": "a more confident line follows that feature",
    "CONSTRAINED": "its vertices already follow another curve constraint",
    "WITHIN_ACCURACY": "it already lies within the accuracy of its feature",
}
"""Why a feature line stays free (the kernel's reasons, and one of the add-on's), as said in reports."""

DISTANCE_EDGES = 1.0
"""The automatic maximum distance between a line and its curve, in median layout edge lengths."""


class FeatureLine(NamedTuple):
    """A layout feature line as the kernel found it."""

    kind: str  # RIDGE, VALLEY, BORDER or ANY (what it may pair with)
    source: str  # MARKED, CREASE or BORDER
    vertices: np.ndarray  # (C,) int64 in order; a closed line does not repeat its first vertex
    closed: bool
    dihedral: float  # mean signed dihedral angle, degrees (convex positive)


class Pairing(NamedTuple):
    """What :func:`pair_lines` found: the new constraints and the lines left free."""

    constraints: list  # of curves.CurveConstraint (source FEATURE_LINE, with a confidence)
    free: list  # of (FeatureLine, FREE_REASONS key)
    between_junctions: int = 0  # how many constraints run between two matched junctions
    pieces: int = 0  # how many constraints hold a piece of a line no curve took whole
    cut_lines: int = 0  # how many lines were paired in pieces
    mapping: object = None  # the smooth map that placed the lines (line_placement.choose_map, corrected), or None


def marked_edges(edges, flags) -> np.ndarray:
    """(K, 2) uint32: the rows of ``edges`` ((E, 2) vertex pairs) whose flag ((E,) bool) is set."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    return np.ascontiguousarray(edges[np.asarray(flags, dtype=bool).reshape(-1)], dtype=np.uint32)


def group_edges(edges, member, group_name: str) -> np.ndarray:
    """(K, 2) uint32: the edges both of whose vertices are in the vertex group (``member``: (N,) bool).

    Raises :class:`LayoutError` when no edge lies in the group (an empty group, or scattered vertices)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    member = np.asarray(member, dtype=bool)
    inside = member[edges[:, 0]] & member[edges[:, 1]] if edges.size else np.zeros(0, dtype=bool)
    if not inside.any():
        raise LayoutError(
            f"Vertex group '{group_name}' holds no edge ({int(member.sum())} vertices, none joined by an edge): "
            "assign the vertices of whole edge chains to it"
        )
    return marked_edges(edges, inside)


def find_lines(positions, face_corners, face_sizes, marked, crease_degrees: float, borders: bool) -> list:
    """The layout's feature lines (:class:`FeatureLine`) at ``positions`` ((N, 3) world rest shape).

    Raises the kernel's ``InvalidArgumentError`` for a marked line that crosses itself."""
    found = springwrap_kernel.layout_feature_lines(
        np.ascontiguousarray(positions, dtype=np.float32),
        np.ascontiguousarray(face_corners, dtype=np.uint32),
        np.ascontiguousarray(face_sizes, dtype=np.uint32),
        marked=np.ascontiguousarray(marked, dtype=np.uint32).reshape(-1, 2),
        crease_degrees=float(crease_degrees),
        borders=bool(borders),
    )
    return [
        FeatureLine(kind, source, np.asarray(vertices, dtype=np.int64), bool(closed), float(dihedral))
        for kind, source, vertices, closed, dihedral in found
    ]


RIDGE_ACCURACY_SCALES = 0.1
"""How far a ridge or valley traced from curvatures may lie from the feature it marks, in feature scales: the
crest of a rounded crease is located only to within the fit's reach (a line already that close to it stays
free)."""


def zigzag(points, closed: bool) -> float:
    """The median distance of a polyline's inner points from the line through their two neighbours: about 0
    along a crease of straight or gently bending edges however unevenly they are split (a few corners do not
    count), about half a triangle's size along a staircase of edges on a rounded crease (a scan's): how far the
    polyline may lie from the crease it marks."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if closed:
        points = np.concatenate([points[-1:], points, points[:1]])
    if points.shape[0] < 3:
        return 0.0
    before, here, after = points[:-2], points[1:-1], points[2:]
    chord = after - before
    length = np.maximum(np.linalg.norm(chord, axis=1), 1e-30)
    return float(np.median(np.linalg.norm(np.cross(here - before, chord), axis=1) / length))


def _along(points, creases, distance: float, share: float = 0.5) -> bool:
    """Whether more than ``share`` of ``points`` lie within ``distance`` of one of ``creases`` (lists of (P, 3)
    points, or their points in one (N, 3) array)."""
    if len(creases) == 0 or distance <= 0.0:
        return False
    crease_points = np.asarray(creases if isinstance(creases, np.ndarray) else np.concatenate(creases))
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if points.shape[0] == 0:
        return False
    low, high = points.min(axis=0) - distance, points.max(axis=0) + distance
    crease_points = crease_points[np.all((crease_points >= low) & (crease_points <= high), axis=1)]
    crease_points = crease_points.astype(np.float64)
    near = np.zeros(points.shape[0], dtype=bool)
    for begin in range(0, crease_points.shape[0], 4096):
        block = crease_points[begin : begin + 4096]
        squared = np.sum((points[:, None, :] - block[None, :, :]) ** 2, axis=2)
        near |= squared.min(axis=1) <= distance * distance
    return bool(near.mean() >= share)


COVERED_SHARE = 0.8
"""A rounded crease is left out for the target's sharp creases only when they run along this share of it: a
short sharp piece on a long rounded crease leaves the whole crease to pair with."""


def target_features(feature_curves, target_positions, triangles, crease_degrees: float = 0.0, scale: float = 0.0):
    """``(curves, junctions)``: :func:`target_curves`' curves, and (J, 3) float64 the target's crease junctions,
    the points where two or more of its sharp or rounded creases end (a corner where creases meet): a rounded
    corner's where its flanks' planes meet, off the surface by its rounding, as the layout's sharp corner is (the
    smooth map through the corners then takes the creases beside it onto their crests, not pulled along them
    toward the rounding's middle)."""
    target_positions = np.ascontiguousarray(target_positions, dtype=np.float32)
    triangles = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
    chains = springwrap_kernel.layout_feature_lines(
        target_positions,
        triangles.reshape(-1),
        np.full(triangles.shape[0], 3, dtype=np.uint32),
        crease_degrees=float(crease_degrees),
        borders=True,
    )
    clean = sharp_creases.sharp_edges(target_positions, triangles, crease_degrees).astype(np.int64)
    clean_keys = set((clean[:, 0] * target_positions.shape[0] + clean[:, 1]).tolist())
    rounded = rounded_creases.rounded_creases(target_positions, triangles, crease_degrees)
    crests = [points for _kind, points, _closed in rounded.curves]
    found, creases, borders, ends = [], [], [], []
    for kind, source, vertices, closed, _dihedral in chains:
        points = np.ascontiguousarray(target_positions[vertices])
        if source == "CREASE":
            ring = np.concatenate([vertices, vertices[:1]]) if closed else np.asarray(vertices)
            pairs = np.sort(np.stack([ring[:-1], ring[1:]], axis=1).astype(np.int64), axis=1)
            keys = (pairs[:, 0] * target_positions.shape[0] + pairs[:, 1]).tolist()
            if np.mean([key in clean_keys for key in keys]) < sharp_creases.CLEAN_SHARE:
                continue  # a rounded crease's row of edges (a scan's), not a sharp one
            beside = not rounded_creases.on_lines(points, crests, rounded_creases.ON_CREST_EDGES * rounded.mean_edge)
            if beside and _along(points, crests, 2.0 * rounded.mean_edge, COVERED_SHARE):
                continue  # a straight row of edges beside a rounded crease's crest (a voxel remesh's chamfer)
            creases.append(points)
            found.append((kind, points, bool(closed), zigzag(points, bool(closed))))
            if not closed:
                ends += [int(vertices[0]), int(vertices[-1])]
        else:
            borders.append(("BORDER", points, bool(closed), 0.0))
    sharp_lines = list(creases)
    for kind, points, closed in rounded.curves:
        if not _along(points, sharp_lines, 2.0 * rounded.mean_edge, COVERED_SHARE):
            creases.append(points)
            found.append((kind, points, closed, zigzag(points, closed)))
    crease_points = np.concatenate(creases) if creases else np.zeros((0, 3))
    for curve in feature_curves:
        points = np.ascontiguousarray(curve.points, dtype=np.float32)
        if not _along(points, crease_points, scale):
            found.append((curve.kind, points, bool(curve.closed), RIDGE_ACCURACY_SCALES * scale))
    corners, uses = np.unique(np.asarray(ends, dtype=np.int64), return_counts=True)
    junctions = target_positions[corners[uses >= 2]].astype(np.float64)
    corners = rounded.junctions if rounded.corners is None else rounded.corners
    if corners.shape[0]:
        apart = np.linalg.norm(corners[:, None, :] - junctions[None, :, :], axis=2).min(axis=1, initial=np.inf)
        junctions = np.concatenate([junctions, corners[apart > scale]])
    return found + borders, junctions


def target_curves(feature_curves, target_positions, triangles, crease_degrees: float = 0.0, scale: float = 0.0):
    """(kind, (P, 3) float32 points, closed, accuracy) per target feature: each sharp crease of the target's own
    edges (``sharp_creases.sharp_edges`` at ``crease_degrees``; 0: none), kind RIDGE (convex) or VALLEY,
    its accuracy :func:`zigzag`; each crease a re-tessellation rounded (``rounded_creases``: where the planes of
    its flanks meet, on the surface) that does not run along a sharp one, accuracy :func:`zigzag`; each ridge and valley of ``feature_curves`` (the kernel's ``FeatureCurve``,
    detected at ``scale``) that does not run along such a crease, accuracy :data:`RIDGE_ACCURACY_SCALES` scales;
    then each open border of the target's triangles (a hole's rim), accuracy 0."""
    return target_features(feature_curves, target_positions, triangles, crease_degrees, scale)[0]


# ---------------------------------------------------------------- junctions


def line_junctions(lines) -> np.ndarray:
    """(J,) int64: the layout vertices where two or more open feature lines end (a corner where creases meet)."""
    ends = [int(end) for line in lines if not line.closed for end in (line.vertices[0], line.vertices[-1])]
    vertices, uses = np.unique(np.asarray(ends, dtype=np.int64), return_counts=True)
    return vertices[uses >= 2]


def match_junctions(vertices, current, junction_points, max_distance: float) -> dict:
    """``{layout vertex: (3,) target point}``: each layout junction (``vertices``, at ``current`` (N, 3) world
    positions) whose nearest target junction (``junction_points``, (J, 3)) lies within ``max_distance`` and has
    it as its own nearest layout junction (mutual nearest: two corners close together are not swapped)."""
    vertices = np.asarray(vertices, dtype=np.int64).reshape(-1)
    junction_points = np.asarray(junction_points, dtype=np.float64).reshape(-1, 3)
    if vertices.size == 0 or junction_points.shape[0] == 0:
        return {}
    here = np.asarray(current, dtype=np.float64)[vertices]
    distance = np.linalg.norm(here[:, None, :] - junction_points[None, :, :], axis=2)
    nearest, back = distance.argmin(axis=1), distance.argmin(axis=0)
    return {
        int(vertex): junction_points[nearest[row]].copy()
        for row, vertex in enumerate(vertices.tolist())
        if distance[row, nearest[row]] <= max_distance and back[nearest[row]] == row
    }


def cornered_rest(rest, face_corners, face_sizes, corners, crease_degrees: float) -> np.ndarray:
    """A copy of the layout's rest shape (``rest``, (N, 3)) with each of ``corners`` (layout vertices where its
    creases meet) moved to where its flanks' planes meet when a retopology put it beside that point
    (``rounded_creases.sharp_corners``): the smooth map and the share-out between matched corners then start from
    the part's corner, as the target's corners are."""
    moved = np.array(rest, dtype=np.float64).reshape(-1, 3)
    corners = np.asarray(list(corners), dtype=np.int64).reshape(-1)
    if corners.size:
        moved[corners] = rounded_creases.sharp_corners(moved, face_corners, face_sizes, corners, crease_degrees)
    return moved


def pair_lines(
    lines,
    current,
    curves_found,
    anchored,
    existing,
    max_distance: float,
    rest=None,
    junctions=None,
    maps=(),
    **settings,
) -> Pairing:
    """Pair ``lines`` with ``curves_found`` (:func:`target_curves`) under the current fit (``current``, (N, 3)
    world positions). A paired line whose vertices (``anchored`` ones excepted) already follow one of
    ``existing`` constraints, or a more confident pair of this call (lines that cross), stays free.
    ``junctions``: ``{layout vertex: target point}`` (:func:`match_junctions`) with ``rest`` ((N, 3) world rest
    shape): a paired line between two matched junctions follows its curve between them, shared out by the rest
    shape's arc length (``line_placement.between_junctions``), instead of the stretch under the current fit.
    ``maps`` (``line_placement.placement_maps``, with ``rest``): the one that takes the paired lines nearest their
    features (``line_placement.choose_map``), corrected by their misses across (``line_placement.corrected``,
    ``Pairing.mapping``), places each vertex of an open line where it
    takes its rest point, projected onto the line's stretch (``smooth_map.placements``), instead of where the fit
    spaces it (a line not between matched corners only when the map runs through
    ``line_placement.MIN_MAP_POINTS`` points or more; a line the chosen map misses,
    ``line_placement.map_reaches``, by another of ``maps`` that reaches it, or as spaced; the vertices it takes past
    the feature's end, ``line_placement.past_ends``, left to the fit). The free lines are then
    tried again in parts (:func:`_pair_again`: pieces of a line no curve takes whole, a line within a crest's
    accuracy placed along it): a pair made so counts in ``Pairing.pieces``, and such a line is free only when
    none of its parts pairs.
    ``settings``: ``max_angle`` (degrees), ``min_confidence``."""
    held = curves.constrained_vertices(existing, anchored)
    outcomes = _kernel_pairs(lines, current, curves_found, max_distance, settings)
    mapping = chosen = None
    if rest is not None and maps:
        chains = [
            (
                np.asarray(rest, dtype=np.float64)[np.asarray(outcome.chain, dtype=np.int64)],
                curves_found[outcome.curve][1],
            )
            for outcome in outcomes
            if outcome.curve is not None
        ]
        chosen = line_placement.choose_map(list(maps), chains)[0]
        mapping = line_placement.corrected(chosen, chains, rest)
    mappings = [] if mapping is None else [mapping] + [other for other in maps if other is not chosen]
    accepted, free, between = {}, [], 0
    for index in sorted(range(len(lines)), key=lambda index: -(outcomes[index].confidence or 0.0)):
        made = _accept(
            lines[index], outcomes[index], held, anchored, curves_found, max_distance, rest, junctions, mappings
        )
        if isinstance(made, str):
            free.append((index, lines[index], made))
            continue
        held |= made.held
        accepted[index] = made
        between += made.between
    constraints = [accepted[index].constraint for index in sorted(accepted)]
    again = _pair_again(
        lines, free, current, curves_found, anchored, held, constraints, max_distance, rest, mappings, settings
    )
    free = [item for item in free if item[0] not in again[1]]
    free_pairs = [(line, reason) for _index, line, reason in sorted(free, key=lambda item: item[0])]
    return Pairing(constraints + again[0], free_pairs, between, len(again[0]), len(again[1]), mapping)


def _pair_again(
    lines, free, current, curves_found, anchored, held, constraints, max_distance, rest, mappings, settings
):
    """``(constraints, indices of the lines they come from)``: the free lines tried again in parts (see
    :func:`pair_lines`): each one no curve takes whole cut into pieces (``line_pieces.pieces``); each one already
    within its curve's accuracy across (a rounded crease's crest, located no better than the fit) whole, and so each
    piece that is, when the
    map places it along a curve located to within :data:`PLACING_ACCURACY` max distances: the curve then says
    where along the feature its vertices go, which the fit does not. A part that would follow a stretch another
    pair follows stays free."""
    if rest is None:
        return [], set()
    left_out = held | set(line_junctions(lines).tolist())
    prepared = line_pieces.curve_index(curves_found)
    parts, exact_parts = [], []
    for index, line, reason in free:
        if reason in line_pieces.RETRIED:
            for piece in line_pieces.pieces(
                line.vertices, line.closed, line.kind, rest, current, prepared, max_distance, left_out
            ):
                parts.append((index, FeatureLine(line.kind, line.source, piece, False, line.dihedral)))
        elif reason == "WITHIN_ACCURACY" and mappings and not line.closed:
            inner = line.vertices[~np.isin(line.vertices, np.fromiter(left_out, dtype=np.int64, count=len(left_out)))]
            if (
                inner.size >= line_pieces.MIN_PIECE
                and inner.size == np.ptp(np.flatnonzero(np.isin(line.vertices, inner))) + 1
            ):
                exact_parts.append((index, FeatureLine(line.kind, line.source, inner, False, line.dihedral)))
    exact = [  # the curves located well enough to say where along them a line goes, taken as exact
        (*curve[:3], 0.0, *curve[4:])
        for curve in curves_found
        if len(curve) < 4 or curve[3] <= PLACING_ACCURACY * max_distance
    ]
    made_list, sources, taken = [], set(), [item.points for item in constraints]
    for group, found, mapped_only in ((parts, curves_found, False), (exact_parts, exact, True)):
        if not group:
            continue
        outcomes = _kernel_pairs([line for _index, line in group], current, found, max_distance, settings)
        for order in sorted(range(len(group)), key=lambda order: -(outcomes[order].confidence or 0.0)):
            if mappings and not mapped_only and outcomes[order].reason == "WITHIN_ACCURACY":
                exact_parts.append(group[order])  # a piece already within its crest's accuracy: placed along it
            made = _accept(group[order][1], outcomes[order], held, anchored, found, max_distance, rest, None, mappings)
            if (
                isinstance(made, str)
                or (mapped_only and made.constraint.fractions.size == 0)
                or _overlaps(made.constraint.points, taken, max_distance)
            ):
                continue
            held |= made.held
            made_list.append(made.constraint)
            taken.append(made.constraint.points)
            sources.add(group[order][0])
    return made_list, sources


class _Made(NamedTuple):
    constraint: object  # curves.CurveConstraint
    between: bool  # it runs between two matched junctions
    held: set  # the vertices it holds (anchored ones left out)


def _kernel_pairs(lines, current, curves_found, max_distance: float, settings: dict) -> list:
    """The kernel's pairing of ``lines`` (its ``LinePairing`` per line)."""
    return springwrap_kernel.pair_feature_lines(
        np.ascontiguousarray(current, dtype=np.float32),
        [(np.ascontiguousarray(line.vertices, dtype=np.uint32), line.closed, line.kind) for line in lines],
        curves_found,
        max_distance=float(max_distance),
        **settings,
    )


def _accept(line, outcome, held: set, anchored, curves_found, max_distance, rest, junctions, mappings):
    """The constraint (:class:`_Made`) for ``line`` from the kernel's ``outcome``, or the reason (a
    :data:`FREE_REASONS` key) it stays free (``held``: the vertices other pairs hold; ``mappings``: the smooth maps
    that may place it, the chosen one first). See :func:`pair_lines`."""
    if outcome.curve is None:
        return outcome.reason
    chain = np.asarray(outcome.chain, dtype=np.int64)
    if any(vertex in held and not anchored[vertex] for vertex in chain.tolist()):
        return "CONSTRAINED"
    target = None
    _kind, curve_points, curve_closed = curves_found[outcome.curve][:3]
    ends = (int(line.vertices[0]), int(line.vertices[-1]))
    if junctions and rest is not None and not line.closed and not curve_closed and all(e in junctions for e in ends):
        first = int(np.flatnonzero(line.vertices == chain[0])[0])
        rows = np.arange(first, first + chain.size)
        if rows[-1] < line.vertices.size and np.array_equal(line.vertices[rows], chain):
            target = line_placement.between_junctions(
                np.asarray(rest, dtype=np.float64)[line.vertices], rows, curve_points, *(junctions[e] for e in ends)
            )
    points = np.asarray(outcome.target if target is None else target, dtype=np.float64).reshape(-1, 3)
    fractions, reach = (), line_placement.MAP_REACH * max_distance
    chain_rest = None if rest is None else np.asarray(rest, dtype=np.float64)[chain]
    mapping = next(  # the chosen map, or another candidate where it misses the feature and that one reaches it
        (
            candidate
            for candidate in mappings
            if (target is not None or candidate.centres.shape[0] >= line_placement.MIN_MAP_POINTS)
            and line_placement.map_reaches(candidate, chain_rest, curve_points, max_distance)
        ),
        None,
    )
    if mapping is not None and not line.closed and not curves.is_closed(points):
        if target is None and not curve_closed:
            leading, trailing = line_placement.past_ends(mapping, chain_rest, curve_points, reach)
            if chain.size - leading - trailing >= 2:  # the vertices past the feature's ends left to the fit
                chain, chain_rest = chain[leading : chain.size - trailing], chain_rest[leading : chain.size - trailing]
            points = line_placement.mapped_stretch(mapping, chain_rest, curve_points, points)
        fractions = smooth_map.placements(mapping, chain_rest, points)
    constraint = curves.make_constraint(
        chain, points, curves.FEATURE_LINE, confidence=float(outcome.confidence), fractions=fractions
    )
    return _Made(constraint, target is not None, {vertex for vertex in chain.tolist() if not anchored[vertex]})


PLACING_ACCURACY = 0.1
"""A line already within its curve's accuracy is tried again (placed along the curve by the map) only on a curve
located to within this share of the max distance: a crease's crest, not a ridge traced from curvatures (whose
accuracy is a tenth of the feature scale, and would pull the line across to where it is not)."""
OVERLAP_SHARE = 0.5
"""A piece whose stretch of curve lies along a stretch already taken for more than this share of its points stays
free (two layout lines on one feature)."""


def _overlaps(points, taken: list, max_distance: float) -> bool:
    """Whether more than :data:`OVERLAP_SHARE` of ``points`` ((P, 3), a piece's stretch) lie within a quarter of
    ``max_distance`` of one of the ``taken`` stretches."""
    return _along(points, taken, 0.25 * max_distance, OVERLAP_SHARE)


def automatic_distance(median_edge: float) -> float:
    """The maximum line-to-curve distance used when none is given: :data:`DISTANCE_EDGES` median edge lengths."""
    if not median_edge > 0.0:
        raise LayoutError("The layout has no edge of non-zero length: give the maximum distance")
    return DISTANCE_EDGES * median_edge


def line_label(line: FeatureLine) -> str:
    """``"crease (ridge) 12-13-...-40, 9 vertices"``: a line as a report names it."""
    source = {"MARKED": "marked line", "CREASE": "crease", "BORDER": "border"}[line.source]
    ends = (
        f"{int(line.vertices[0])}…{int(line.vertices[-1])}" if not line.closed else f"loop at {int(line.vertices[0])}"
    )
    return f"{source} ({line.kind.lower()}) {ends}, {line.vertices.size} vertices"


def pairing_report(line_count: int, pairing: Pairing, listed: int = 5) -> tuple[str, str]:
    """``(report level, text)``: how many lines were paired (with their confidences), and the free ones listed
    (the first ``listed``) with why."""
    paired = len(pairing.constraints)
    if line_count == 0:
        return "WARNING", (
            "The layout has no feature lines: mark edges sharp (or give a vertex group or edge attribute), "
            "or lower the crease angle"
        )
    lines_paired = paired - pairing.pieces + pairing.cut_lines
    text = f"Paired {lines_paired} of {line_count} feature line{'' if line_count == 1 else 's'}"
    if paired:
        confidences = [constraint.confidence for constraint in pairing.constraints]
        text += f" (confidence {min(confidences):.2f} to {max(confidences):.2f})"
    if pairing.pieces:
        text += f", {pairing.cut_lines} of them in {pairing.pieces} pieces where no feature takes them whole"
    if pairing.free:
        reasons = {}
        for _line, reason in pairing.free:
            reasons[reason] = reasons.get(reason, 0) + 1
        text += f"; {len(pairing.free)} free: " + ", ".join(
            f"{count} {FREE_REASONS[reason]}" for reason, count in reasons.items()
        )
        shown = "; ".join(f"{line_label(line)}: {FREE_REASONS[reason]}" for line, reason in pairing.free[:listed])
        more = len(pairing.free) - listed
        text += f" [{shown}{f'; {more} more' if more > 0 else ''}]"
    return ("INFO" if paired else "WARNING"), text
