"""Openings: a closed slit of the layout (lips that meet, a closed eye) paired with the rim of the opening it has
on the target (an open mouth), on arrays (numpy + kernel, no ``bpy``).

A layout feature line is a **slit** when it is a closed loop whose two halves, between the two vertices farthest
apart on the rest shape (its corners), lie against each other: the gap between them is below :data:`SLIT_RATIO`
of the corners' distance (closed lips: the upper lip's edge and the lower lip's). On the target the same place may
be open: the surface turns inward there, into a cavity. A closed loop of the layout has no open partner among the
target's ridges and hole borders (a voxel remesh has no border, the rim of an open mouth is no crest the layout's
closed loop is near), so it is found directly: looking at the slit under the current fit from the front (the
side its surroundings face), rays are cast in columns across it; where a column's rays run deeper than the
surface beside them by more than :data:`DEPTH_JUMP` of the mouth's width, the target is open; the rim on each side
is where the rays stop grazing the lip and fall in (the largest step in depth between finer rays). The two halves of the slit are paired
with the two rims (the half nearer each, under the current fit), from corner to corner of the opening (the
outermost open columns): two curve constraints, the first holding the corners, with the confidence the share of
columns that found the opening.
"""

from typing import NamedTuple

import numpy as np

from . import curves, smooth_map
from .edge_paths import cumulative_lengths
from .parts import fan_triangles

SLIT_RATIO = 0.12
"""A closed loop is a slit when the median gap between its halves is below this share of its corners' distance."""
DEPTH_JUMP = 0.75
"""A ray falls into the opening when it runs deeper than the shallowest of its column by more than this share of
the slit's width (its corners' distance)."""
COLUMNS = 24
"""Columns of rays across the slit, spread over its width between :data:`COLUMN_MARGIN` of it from each corner."""
COLUMN_MARGIN = 0.06
"""The columns keep this share of the slit's width from its corners (where the opening closes)."""
RIM_ACCURACY = 0.15
"""How closely a rim found by rays marks where a slit's half belongs, in slit widths (the rays graze the rounded
lip a little inside its edge): a half whose every vertex is already within it of its rim is not paired."""
ROWS = 48
"""Rays in each column, spread over :data:`REACH` of the slit's width each side of it."""
REACH = 0.6
"""How far each side of the slit (in its widths) the columns look for the rims."""
RIM_DEPTH = 0.05
"""A rim lies within this share of the slit's width behind the front of the lip beside it."""
RIM_RAYS = 33
"""Rays locating a rim between the last ray of a column that grazes the lip and the first that falls in."""
MIN_OPEN_COLUMNS = 0.4
"""The least share of the columns inside the slit's corners that must find the opening for a pairing."""
MIN_OPENING = 0.1
"""The opening must be wider (between its rims, in the middle columns) than this share of the slit's width over
the slit's own gap under the current fit: a slit already as open as its target is not paired."""


class Slit(NamedTuple):
    """A closed loop of the layout split at its corners into two halves."""

    loop: np.ndarray  # (C,) int64 the loop's vertices, starting at one corner
    corner: int  # index in ``loop`` of the other corner
    gap: float  # median gap between the halves on the rest shape, in corner distances


class OpeningPair(NamedTuple):
    """A slit paired with the rims of its opening on the target."""

    slit: Slit
    constraints: list  # curves.CurveConstraint (FEATURE_LINE), one per half paired
    confidence: float


TOUCHING = 1.25
"""Of the slits round one opening (lips are several loops deep), those whose gap is within this factor of the
smallest touch; the frontmost of them (the lips' edge where they meet, not a loop inside the mouth) is paired."""


def _polyline_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """(P,) distance of each point to the polyline (segments between its consecutive points)."""
    starts, ends = polyline[:-1], polyline[1:]
    direction = ends - starts
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(np.einsum("psk,sk->ps", points[:, None, :] - starts[None], direction) / squared, 0.0, 1.0)
    closest = starts[None] + t[..., None] * direction[None]
    return np.linalg.norm(closest - points[:, None, :], axis=2).min(axis=1)


def closed_loops(face_corners, face_sizes) -> list:
    """(C,) int64 vertices of each closed edge loop of the layout's quads: chains that go straight on through
    vertices of four edges (across the edge opposite the one they came by: the one of the four that shares no quad
    with it) until they close. Each loop once, from the first edge (in the quads' order) of two quads it has."""
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    quads = corners[starts[sizes == 4][:, None] + np.arange(4)[None, :]] if (sizes == 4).any() else np.zeros((0, 4))
    quads = np.asarray(quads, dtype=np.int64)
    if quads.size == 0:
        return []
    pairs = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    span = int(quads.max()) + 1
    keys, first, edge_of = np.unique(pairs[:, 0] * span + pairs[:, 1], return_index=True, return_inverse=True)
    edge_of = edge_of.reshape(-1)
    low, high = keys // span, keys % span
    edges = np.stack([low, high], axis=1)
    # Each edge's quads (as many slots as the edge with most), -1 where it has fewer.
    faces = np.repeat(np.arange(quads.shape[0]), 4)
    order = np.argsort(edge_of, kind="stable")
    uses = np.bincount(edge_of, minlength=edges.shape[0])
    slot = np.arange(order.size) - np.repeat(np.cumsum(uses) - uses, uses)
    edge_faces = np.full((edges.shape[0], int(uses.max())), -1, dtype=np.int64)
    edge_faces[edge_of[order], slot] = faces[order]
    # The vertices of four edges, their edges; for each edge in, the one edge out that shares no quad with it.
    ends = np.concatenate([low, high])
    by_vertex = np.argsort(ends, kind="stable")
    valence = np.bincount(ends)
    four = np.flatnonzero(valence == 4)
    incident = (by_vertex % edges.shape[0])[(np.cumsum(valence) - valence)[four][:, None] + np.arange(4)[None, :]]
    around = edge_faces[incident]  # (M, 4, K)
    shared = ((around[:, :, None, :, None] == around[:, None, :, None, :]) & (around[:, :, None, :, None] >= 0)).any(
        axis=(3, 4)
    )
    apart = ~shared & ~np.eye(4, dtype=bool)[None]
    single = apart.sum(axis=2) == 1
    out = np.argmax(apart, axis=2)
    # Directed edge 2e runs low -> high, 2e + 1 high -> low; following[d]: the one straight on from d, or -1.
    following = np.full(2 * edges.shape[0], -1, dtype=np.int64)
    vertex = np.repeat(four, 4).reshape(-1, 4)
    edge_in, edge_out = incident, np.take_along_axis(incident, out, axis=1)
    coming = 2 * edge_in + (vertex != high[edge_in])
    going = 2 * edge_out + (vertex == high[edge_out])
    following[coming[single]] = going[single]
    head = np.stack([high, low], axis=1).reshape(-1)
    following, head = following.tolist(), head.tolist()
    visited = np.zeros(edges.shape[0], dtype=bool)
    most = int(np.count_nonzero(valence))
    loops = []
    for edge in np.argsort(first, kind="stable").tolist():
        if visited[edge] or uses[edge] != 2:
            continue
        visited[edge] = True
        path, directed = [int(low[edge]), int(high[edge])], 2 * edge
        while True:
            onward = following[directed]
            if onward < 0 or len(path) > most:
                break
            if head[onward] == path[0]:
                visited[onward >> 1] = True
                loops.append(np.array(path, dtype=np.int64))
                break
            if visited[onward >> 1]:
                break
            visited[onward >> 1] = True
            path.append(head[onward])
            directed = onward
    return loops


def find_slit(loop, rest) -> Slit | None:
    """The loop (``loop``: its vertices in order, not repeating the first) as a :class:`Slit` on the rest shape
    (``rest``, (N, 3)), or None when its halves do not lie against each other."""
    loop = np.asarray(loop, dtype=np.int64).reshape(-1)
    if loop.size < 6:
        return None
    points = np.asarray(rest, dtype=np.float64)[loop]
    distances = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    first, second = np.unravel_index(int(np.argmax(distances)), distances.shape)
    width = float(distances[first, second])
    if not width > 0.0:
        return None
    loop = np.roll(loop, -int(first))
    corner = (int(second) - int(first)) % loop.size
    if corner < 2 or loop.size - corner < 2:
        return None
    points = np.asarray(rest, dtype=np.float64)[loop]
    one, other = points[: corner + 1], np.concatenate([points[corner:], points[:1]])
    gaps = np.concatenate([_polyline_distance(one[1:-1], other), _polyline_distance(other[1:-1], one)])
    gap = float(np.median(gaps)) / width
    return Slit(loop, corner, gap) if gap < SLIT_RATIO else None


class Frame(NamedTuple):
    """A slit's frame under the current fit: its corners, unit directions across it (corner a to b), up (across
    its halves) and front (the side its surroundings face), and its width (the corners' distance)."""

    a: np.ndarray
    b: np.ndarray
    across: np.ndarray
    up: np.ndarray
    front: np.ndarray
    width: float


def _rotation(rest: np.ndarray, current: np.ndarray) -> np.ndarray:
    """The best rotation (3, 3) taking the centred ``rest`` points onto the centred ``current`` ones (Kabsch)."""
    cross = (rest - rest.mean(axis=0)).T @ (current - current.mean(axis=0))
    u, _s, vt = np.linalg.svd(cross)
    flip = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(vt.T @ u.T))) or 1.0])
    return vt.T @ flip @ u.T


def slit_frame(slit: Slit, rest, current, facing) -> Frame:
    """The slit's :class:`Frame`: its directions are those of the closed slit on the rest shape (across: corner to
    corner; front: ``facing``, the summed normals of the surface round it, made perpendicular to across; up:
    perpendicular to both) turned by the rotation that best takes the layout round it (within
    its width) from the rest shape to the current fit."""
    rest = np.asarray(rest, dtype=np.float64)
    current = np.asarray(current, dtype=np.float64)
    points = rest[slit.loop]
    a_rest, b_rest = points[0], points[slit.corner]
    width_rest = float(np.linalg.norm(b_rest - a_rest))
    across = (b_rest - a_rest) / width_rest
    front = np.asarray(facing, dtype=np.float64) - across * float(np.asarray(facing, dtype=np.float64) @ across)
    front /= max(float(np.linalg.norm(front)), 1e-300)
    up = np.cross(front, across)
    around = np.linalg.norm(rest - points.mean(axis=0), axis=1) < width_rest
    turn = _rotation(rest[around], current[around]) if around.sum() >= 3 else np.eye(3)
    a, b = current[slit.loop[0]], current[slit.loop[slit.corner]]
    return Frame(a, b, turn @ across, turn @ up, turn @ front, float(np.linalg.norm(b - a)))


def facing(rest, triangles, centre, radius: float) -> np.ndarray:
    """The area-weighted sum of the normals of ``triangles`` ((T, 3) of ``rest``) within ``radius`` of ``centre``:
    the side a slit's surroundings face (a closed pocket behind the slit adds its mouth's area, the same way)."""
    corners = np.asarray(rest, dtype=np.float64)[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    near = np.linalg.norm(corners.mean(axis=1) - np.asarray(centre, dtype=np.float64), axis=1) < radius
    return normals[near].sum(axis=0)


def _depths(mesh, origins: np.ndarray, front: np.ndarray, reach: float):
    """(depths, hit points) of rays from ``origins`` (world) against ``front``: inf and NaN where nothing is hit
    within ``reach``; ``mesh`` a ``core.target.CentredMesh``."""
    directions = np.repeat(-front[None, :], origins.shape[0], axis=0)
    hits = mesh.ray_cast(origins, directions, max_distance=float(reach))
    depths = np.asarray(hits.distances, dtype=np.float64)
    return np.where(np.isfinite(depths), depths, np.inf), np.asarray(hits.positions, dtype=np.float64)


def _rim(mesh, frame: Frame, base: np.ndarray, grazing: float, falling: float) -> np.ndarray:
    """The rim between a grazing ray (at ``grazing`` along ``up`` from ``base``) and one falling in (``falling``):
    of :data:`RIM_RAYS` rays between them, up to the first step in depth of at least half the largest (where the
    rays fall in), the hit point of the last that lies within :data:`RIM_DEPTH` of the shallowest (where the lip
    starts to curl in, not a point down its inner side)."""
    stand, reach = frame.width, 3.0 * frame.width
    heights = np.linspace(grazing, falling, RIM_RAYS)
    origins = base[None, :] + heights[:, None] * frame.up[None, :] + stand * frame.front[None, :]
    depths, hits = _depths(mesh, origins, frame.front, reach)
    steps = np.diff(np.where(np.isfinite(depths), depths, 2.0 * reach))
    fall = int(np.argmax(steps >= 0.5 * steps.max()))
    # Where the lip starts to curl in: the last ray before the fall within RIM_DEPTH of the shallowest.
    touching = np.flatnonzero(depths[: fall + 1] <= depths[: fall + 1].min() + RIM_DEPTH * frame.width)
    return hits[int(touching[-1])]


def _runs(flags: np.ndarray) -> list:
    """(first, last) of each run of set flags."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    changes = np.flatnonzero(np.diff(padded))
    return list(zip(changes[::2].tolist(), (changes[1::2] - 1).tolist()))


def opening_rims(mesh, slit: Slit, frame: Frame, current):
    """(fractions (K,), rim on the ``up`` side (K, 3), rim on the other side (K, 3)) of the target's opening at the
    slit (``mesh`` a ``core.target.CentredMesh``; ``current`` (N, 3) world positions now), in the columns across
    it (:data:`COLUMNS`, at fractions of the way from corner a to corner b) that find one."""
    current = np.asarray(current, dtype=np.float64)
    stand, reach = frame.width, 3.0 * frame.width
    rows = np.linspace(-REACH, REACH, ROWS) * frame.width
    line = current[slit.loop]
    along = (line - frame.a) @ frame.across / frame.width
    fractions, upper, lower = [], [], []
    for fraction in np.linspace(COLUMN_MARGIN, 1.0 - COLUMN_MARGIN, COLUMNS):
        base = frame.a + fraction * (frame.b - frame.a)
        # The slit's own height in this column: its two vertices nearest it, between its halves.
        middle = float(np.mean((line[np.argsort(np.abs(along - fraction))[:2]] - base) @ frame.up))
        origins = base[None, :] + rows[:, None] * frame.up[None, :] + stand * frame.front[None, :]
        depths, _points = _depths(mesh, origins, frame.front, reach)
        shallow = float(np.min(depths))
        if not np.isfinite(shallow):
            continue
        limit = shallow + DEPTH_JUMP * frame.width
        runs = _runs(depths > limit)
        if not runs:
            continue
        centre = int(np.argmin(np.abs(rows - middle)))
        low, high = min(runs, key=lambda run: max(run[0] - centre, centre - run[1], 0))
        if low == 0 or high == ROWS - 1:
            continue  # the opening runs out of the column: no rim on one side
        fractions.append(float(fraction))
        # From two rays before the first falling in: the last grazing one may already be on a wall going in.
        lower.append(_rim(mesh, frame, base, rows[max(low - 2, 0)], rows[low]))
        upper.append(_rim(mesh, frame, base, rows[min(high + 2, ROWS - 1)], rows[high]))
    return np.array(fractions), np.array(upper).reshape(-1, 3), np.array(lower).reshape(-1, 3)


def _trimmed(points: np.ndarray, begin: float, finish: float) -> np.ndarray:
    """The piece of the polyline from arc-length fraction ``begin`` to ``finish``."""
    cumulative = cumulative_lengths(points)
    total = cumulative[-1]
    if not total > 0.0:
        return points.copy()
    fractions = cumulative / total
    ends = np.stack([np.interp([begin, finish], fractions, points[:, axis]) for axis in range(3)], axis=1)
    inside = (fractions > begin) & (fractions < finish)
    return np.concatenate([ends[:1], points[inside], ends[1:]])


def pair_slit(mesh, slit: Slit, rest, current, facing_direction, mapping=None) -> OpeningPair | None:
    """The slit's halves paired with the rims of the target's opening there (see the module's docstring), or None
    when the target is not open there (too few columns open, or no wider than the slit is already). A half already
    within :data:`RIM_ACCURACY` of its rim is left out. ``mapping`` (``smooth_map.SmoothMap`` from the rest shape
    to the target): each vertex goes along its rim where the map takes its rest point (``smooth_map.placements``),
    instead of where the fit spaces it."""
    current = np.asarray(current, dtype=np.float64)
    frame = slit_frame(slit, rest, current, facing_direction)
    fractions, upper, lower = opening_rims(mesh, slit, frame, current)
    share = fractions.size / COLUMNS
    if share < MIN_OPEN_COLUMNS:
        return None
    middle = int(np.argmin(np.abs(fractions - 0.5)))
    one = slit.loop[: slit.corner + 1]
    other = np.concatenate([slit.loop[slit.corner :], slit.loop[:1]])
    gap = abs(float((current[one].mean(axis=0) - current[other].mean(axis=0)) @ frame.up))
    if float((upper[middle] - lower[middle]) @ frame.up) - gap < MIN_OPENING * frame.width:
        return None
    # Each half goes to the rim on its side, from corner a to corner b (the corners where the fit has them).
    one_is_upper = float((current[one] @ frame.up).mean()) >= float((current[other] @ frame.up).mean())
    upper_line = np.concatenate([[frame.a], upper, [frame.b]])
    lower_line = np.concatenate([[frame.a], lower, [frame.b]])
    one_line, other_line = (upper_line, lower_line) if one_is_upper else (lower_line, upper_line)
    across = np.concatenate([[0.0], fractions, [1.0]])
    ends = np.asarray(rest, dtype=np.float64)[slit.loop[[0, slit.corner]]]

    def placed(chain, line, backwards=False):
        if mapping is None:
            return ()
        return rim_placements(mapping, np.asarray(rest, dtype=np.float64)[chain], ends, line, across, backwards)

    constraints = []
    if _farther_than(current[one], one_line, RIM_ACCURACY * frame.width, placed(one, one_line)):
        constraints.append(
            curves.make_constraint(
                one, one_line, curves.FEATURE_LINE, confidence=share, fractions=placed(one, one_line)
            )
        )
    # The other half runs from corner b round to corner a: without the corners if the first half holds them.
    if _farther_than(current[other], other_line, RIM_ACCURACY * frame.width):
        chain, points, placement = other, other_line[::-1], placed(other, other_line, True)
        if constraints:
            chain, placement = other[1:-1], placement[1:-1]
            if mapping is None:
                lengths = cumulative_lengths(current[other])
                points = _trimmed(points, lengths[1] / lengths[-1], lengths[-2] / lengths[-1])
        constraints.append(
            curves.make_constraint(chain, points, curves.FEATURE_LINE, confidence=share, fractions=placement)
        )
    return OpeningPair(slit, constraints, float(share)) if constraints else None


def rim_placements(mapping, chain_rest, corners_rest, line, across, backwards=False) -> np.ndarray:
    """(C,) float64: where along a rim (``line``, (P, 3) from corner a to corner b, each point ``across`` (P,)
    of the way from a to b) each vertex of a slit's half goes, as a fraction of the rim's length (from b when
    ``backwards``: the half runs from b to a): the vertex's rest point (``chain_rest``) taken through the map
    (``smooth_map.SmoothMap``) is that share of the way across between where the map takes the corners
    (``corners_rest``, (2, 3)), and goes to the rim's point as far across. Across an opening, not to the rim's
    nearest point: a closed lip maps into the middle of the open mouth, nearer the rim's ends than its middle."""
    mapped = smooth_map.apply(mapping, chain_rest)
    a, b = smooth_map.apply(mapping, corners_rest)
    axis = b - a
    share = (mapped - a) @ axis / max(float(axis @ axis), 1e-300)
    cumulative = cumulative_lengths(np.asarray(line, dtype=np.float64))
    fractions = np.interp(share, across, cumulative / max(cumulative[-1], 1e-300))
    fractions = 1.0 - fractions if backwards else fractions
    return np.clip(np.maximum.accumulate(fractions), 0.0, 1.0)


def _farther_than(chain_positions: np.ndarray, line: np.ndarray, distance: float, fractions=()) -> bool:
    """Whether a vertex of the chain lies farther than ``distance`` from where the line would pull it (at
    ``fractions`` of its length, or as the chain is spaced)."""
    pulled = curves.arc_length_points(chain_positions, line, fractions)
    return bool(np.linalg.norm(pulled - chain_positions, axis=1).max() > distance)


def layout_slits(rest, face_corners, face_sizes) -> list:
    """``(slit, facing)`` per opening of the layout (its closed slits, :func:`find_slit`, grouped by the opening
    they are round: centres within half a width of each other), the frontmost of the touching ones
    (:data:`TOUCHING`) with the direction its surroundings face on the rest shape (:func:`facing`)."""
    rest = np.asarray(rest, dtype=np.float64)
    slits = [slit for slit in (find_slit(loop, rest) for loop in closed_loops(face_corners, face_sizes)) if slit]
    if not slits:
        return []
    triangles = fan_triangles(face_corners, face_sizes, np.ones(np.asarray(face_sizes).size, dtype=bool))
    centres = np.array([rest[slit.loop].mean(axis=0) for slit in slits])
    widths = np.array([np.linalg.norm(rest[slit.loop[0]] - rest[slit.loop[slit.corner]]) for slit in slits])
    chosen, taken = [], np.zeros(len(slits), dtype=bool)
    for first in np.argsort([slit.gap for slit in slits]).tolist():
        if taken[first]:
            continue
        group = np.flatnonzero(~taken & (np.linalg.norm(centres - centres[first], axis=1) < 0.5 * widths[first]))
        taken[group] = True
        direction = facing(rest, triangles, centres[first], widths[first])
        touching = [index for index in group.tolist() if slits[index].gap <= TOUCHING * slits[first].gap]
        front = max(touching, key=lambda index: float(centres[index] @ direction))
        chosen.append((slits[front], direction))
    return chosen


def report_text(pairs) -> str:
    """``"paired 1 opening (2 halves, confidence 0.92)"``: what :func:`pair_slit` paired, as reports say it."""
    halves = sum(len(pair.constraints) for pair in pairs)
    confidences = ", ".join(f"{pair.confidence:.2f}" for pair in pairs)
    return (
        f"paired {len(pairs)} opening{'' if len(pairs) == 1 else 's'} ({halves} slit "
        f"{'half' if halves == 1 else 'halves'} onto its rim, confidence {confidences})"
    )
