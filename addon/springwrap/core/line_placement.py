"""Where along its feature each vertex of a paired line goes (numpy, no ``bpy``).

A paired line's stretch of target curve, and each vertex's place along it: between two corners matched on the
target, the curve between them shared out by the rest shape's arc length (:func:`between_junctions`); elsewhere
the stretch and places the smooth map through the anchors and matched corners gives (:func:`mapped_stretch`,
``smooth_map.placements``) where that map reaches the feature (:func:`map_reaches`). The map is affine between its
points (a thin-plate spline) unless a quadratic one lands the paired lines closer to their features
(:func:`choose_map`): how far a map takes a line's rest points from its feature is evidence its points do not give.
"""

import numpy as np

from . import smooth_map
from .edge_paths import cumulative_lengths, length_fractions


def parameter(points: np.ndarray, cumulative: np.ndarray, point: np.ndarray) -> tuple[float, float]:
    """``(arc-length parameter, distance)`` of the point of the polyline ``points`` nearest to ``point``."""
    starts, direction = points[:-1], np.diff(points, axis=0)
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(((point[None, :] - starts) * direction).sum(axis=1) / squared, 0.0, 1.0)
    distances = ((starts + t[:, None] * direction - point[None, :]) ** 2).sum(axis=1)
    segment = int(np.argmin(distances))
    along = cumulative[segment] + t[segment] * (cumulative[segment + 1] - cumulative[segment])
    return float(along), float(np.sqrt(distances[segment]))


def piece(points: np.ndarray, cumulative: np.ndarray, begin: float, finish: float) -> np.ndarray:
    """The stretch of the open polyline ``points`` from arc parameter ``begin`` to ``finish`` (reversed when
    ``finish`` comes first)."""
    low, high = min(begin, finish), max(begin, finish)
    inside = (cumulative > low) & (cumulative < high)
    ends = np.stack([np.interp([low, high], cumulative, points[:, axis]) for axis in range(3)], axis=1)
    piece = np.concatenate([ends[:1], points[inside], ends[1:]])
    return piece if begin <= finish else piece[::-1]


def between_junctions(line_rest, chain_rows, curve_points, start_point, end_point) -> np.ndarray | None:
    """The target stretch of a chain on a line that runs between two matched junctions, or None.

    ``line_rest``: (L, 3) the whole line on the layout's rest shape, junction to junction; ``chain_rows``: the
    rows of the line its chain takes (the junctions themselves left out, or a line trimmed at the curve's end);
    ``curve_points``: (P, 3) the open target curve it pairs with; ``start_point``/``end_point``: the target
    junctions of the line's first and last vertex. The curve between the two junctions is shared out in
    proportion to the rest shape's arc length, so that the corners, not the fit's sliding, fix where along the
    crease each vertex lies; the chain's stretch is its part of it. None when the junctions project to one point
    of the curve, the curve between them is not about as long as the line (:data:`MIN_LENGTH_RATIO`) or a
    junction lies off the curve (:data:`JUNCTION_TOLERANCE`: the curve stops short of that corner)."""
    curve_points = np.asarray(curve_points, dtype=np.float64).reshape(-1, 3)
    cumulative = cumulative_lengths(curve_points)
    begin, off_start = parameter(curve_points, cumulative, np.asarray(start_point, dtype=np.float64))
    finish, off_end = parameter(curve_points, cumulative, np.asarray(end_point, dtype=np.float64))
    span = abs(finish - begin)
    line_length = cumulative_lengths(np.asarray(line_rest, dtype=np.float64))[-1]
    if not (span > 0.0 and line_length > 0.0 and MIN_LENGTH_RATIO <= span / line_length <= 1.0 / MIN_LENGTH_RATIO):
        return None
    if max(off_start, off_end) > JUNCTION_TOLERANCE * line_length:
        return None  # a junction off the curve: the curve ends before that corner (another crease takes over)
    fractions = length_fractions(np.asarray(line_rest, dtype=np.float64))
    stretch = piece(curve_points, cumulative, begin, finish)
    along = cumulative_lengths(stretch)
    first, last = fractions[chain_rows[0]] * along[-1], fractions[chain_rows[-1]] * along[-1]
    if not last > first:
        return None
    return piece(stretch, along, first, last)


def mapped_stretch(mapping, chain_rest, curve_points, stretch) -> np.ndarray:
    """The stretch of the open curve ``curve_points`` from where ``mapping`` (``smooth_map.SmoothMap``) takes the
    chain's first rest point (``chain_rest``, (C, 3)) to where it takes the last, both projected onto the curve;
    ``stretch`` (the one under the current fit, in the chain's direction) when those two are not about as far apart
    along the curve (:data:`MIN_LENGTH_RATIO`) or come in the other order."""
    curve_points = np.asarray(curve_points, dtype=np.float64).reshape(-1, 3)
    stretch = np.asarray(stretch, dtype=np.float64).reshape(-1, 3)
    cumulative = cumulative_lengths(curve_points)
    ends = smooth_map.apply(mapping, np.asarray(chain_rest, dtype=np.float64)[[0, -1]])
    begin, finish = (parameter(curve_points, cumulative, end)[0] for end in ends)
    first, last = (parameter(curve_points, cumulative, end)[0] for end in stretch[[0, -1]])
    length = cumulative_lengths(stretch)[-1]
    span = (finish - begin) * np.sign(last - first)
    if not MIN_LENGTH_RATIO * length <= span <= length / MIN_LENGTH_RATIO:
        return stretch
    return piece(curve_points, cumulative, begin, finish)


JUNCTION_TOLERANCE = 0.01
"""How far a matched target junction may lie from the curve a line pairs with, as a fraction of the line's
rest length: farther, the curve does not run to that corner."""
MIN_LENGTH_RATIO = 0.5
"""The shortest stretch of curve between two matched junctions a line may follow, as a fraction of its rest
length (and the longest, its inverse)."""


MIN_MAP_POINTS = 12
"""The fewest matched points (anchors and corners) through which the smooth map places the vertices of a line that
does not run between two matched corners (and a slit's halves): through fewer it is too coarse to say where along
a feature a vertex lies (8 anchors on a whole part), and such lines go as the fit spaces them."""


MAP_REACH = 0.4
"""How close (mean, as a share of the maximum distance) the smooth map must take a chain's rest points to the
feature it pairs with for it to place the chain along it: the map's distance across the feature is a sample of its
error, and a map farther off (few anchors, far from them) would place the chain worse than the fit spaces it."""


def map_reaches(mapping, chain_rest, curve_points, max_distance: float) -> bool:
    """Whether ``mapping`` takes ``chain_rest`` ((C, 3)) within :data:`MAP_REACH` maximum distances (mean) of the
    polyline ``curve_points``: the map through its points alone (a correction, :func:`corrected`, bends it onto
    the lines, and its miss would no longer say how far off it is)."""
    count = np.asarray(chain_rest).reshape(-1, 3).shape[0]
    plain = mapping._replace(bumps=None, bump_weights=None)
    return bool(count and miss(plain, chain_rest, curve_points) <= MAP_REACH * max_distance * count)


def past_ends(mapping, chain_rest, curve_points, reach: float) -> tuple[int, int]:
    """``(leading, trailing)``: how many of the chain's first and last vertices (``chain_rest``, (C, 3)) ``mapping``
    takes past an end of the open polyline ``curve_points`` (its nearest point on it that end) by more than
    ``reach`` (along the curve's direction at that end): the feature stops before them (a crease a scan lost near
    a corner), and the map would pin them to its end."""
    chain_rest = np.asarray(chain_rest, dtype=np.float64).reshape(-1, 3)
    curve_points = np.asarray(curve_points, dtype=np.float64).reshape(-1, 3)
    if chain_rest.shape[0] == 0 or curve_points.shape[0] < 2:
        return 0, 0
    mapped = smooth_map.apply(mapping, chain_rest)
    cumulative = cumulative_lengths(curve_points)
    past = np.zeros(mapped.shape[0])
    for row, point in enumerate(mapped):
        along, _distance = parameter(curve_points, cumulative, point)
        end, inner = (0, 1) if along <= 0.0 else (-1, -2) if along >= cumulative[-1] else (None, None)
        outward = curve_points[end] - curve_points[inner] if end is not None else np.zeros(3)
        length = float(np.linalg.norm(outward))
        if length > 0.0:  # its nearest point on the curve is that end
            past[row] = (point - curve_points[end]) @ outward / length
    beyond = past > reach
    if beyond.all():
        return int(beyond.size), 0
    return int(np.argmin(beyond)), int(np.argmin(beyond[::-1]))


def placement_maps(rest, vertices, locations, junctions=None) -> list:
    """``[affine, quadratic]`` (:func:`smooth_map.fit`, degrees 1 and 2; the quadratic left out when the points do
    not fix one) from the layout's rest shape (``rest``, (N, 3) world) to the target through the anchored
    ``vertices`` ((K,)) and their target ``locations`` ((K, 3) world) and the matched ``junctions`` (``{layout
    vertex: target point}``); empty without any point. An anchored corner goes where its matched corner is: the
    anchor (a point on the surface, inside a rounded corner) says which corner, the corner (where the target's
    flanks meet) where the sharp point the layout's corner stands for is."""
    vertices = np.asarray(vertices, dtype=np.int64).reshape(-1)
    locations = np.asarray(locations, dtype=np.float64).reshape(-1, 3)
    if junctions:  # first: a source given twice keeps its first target
        vertices = np.concatenate([np.fromiter(junctions, dtype=np.int64, count=len(junctions)), vertices])
        locations = np.concatenate([np.array(list(junctions.values()), dtype=np.float64), locations])
    if vertices.size == 0:
        return []
    sources = np.asarray(rest, dtype=np.float64)[vertices]
    maps = [smooth_map.fit(sources, locations), smooth_map.fit(sources, locations, degree=2)]
    return [mapping for mapping in maps if mapping is not None]


def miss(mapping, chain_rest, curve_points) -> float:
    """The sum over ``chain_rest`` ((C, 3)) of how far ``mapping`` takes each point from the polyline
    ``curve_points``."""
    curve_points = np.asarray(curve_points, dtype=np.float64).reshape(-1, 3)
    cumulative = cumulative_lengths(curve_points)
    return float(sum(parameter(curve_points, cumulative, point)[1] for point in smooth_map.apply(mapping, chain_rest)))


def choose_map(maps: list, chains: list):
    """``(map, affine miss, chosen miss)``: of ``maps`` (:func:`placement_maps`: the affine one first), the one that
    takes ``chains`` (``(chain rest points (C, 3), curve points (P, 3))`` of the paired lines) nearest their curves
    in all (:func:`miss`), the affine one on a tie (both on the features, to rounding); None (and zeros) without
    maps."""
    if not maps:
        return None, 0.0, 0.0
    misses = [sum(miss(mapping, chain, curve) for chain, curve in chains) for mapping in maps]
    size = sum(
        len(chain) * float(np.ptp(np.asarray(curve).reshape(-1, 3), axis=0).max(initial=0.0)) for chain, curve in chains
    )
    best = int(np.argmin(misses))
    if misses[0] - misses[best] <= 1e-9 * size:
        best = 0  # no nearer, to rounding
    return maps[best], misses[0], misses[best]


BUMP_WIDTH = 0.35
"""The width of the Gaussian bumps that correct the chosen map (:func:`corrected`), as a share of the layout's
size: a design change's smooth variation, wider than a crease's stretch between two corners."""
BUMP_COUNT = 80
"""The most bumps (their centres spread over the layout's rest shape, farthest first)."""
BUMP_RIDGE = 0.01
"""The penalty on the bumps' weights, per paired vertex (squared lengths, as the misses are): it keeps the
correction where the lines' misses agree."""
MAP_POINT_WEIGHT = 10.0
"""How much more than a paired vertex's miss each of the map's own points (anchors, matched corners) weighs in the
correction: they stay where the map takes them."""


def corrected(mapping, chains: list, rest):
    """``mapping`` (``smooth_map.SmoothMap``) with a smooth correction (Gaussian bumps, ``SmoothMap.bumps``) that
    takes the paired lines' rest points (``chains``, as for :func:`choose_map`) onto their curves across them,
    keeping the map's own points: a line's miss across its feature is evidence of the map's error there, and where
    lines run in other directions it tells where along each of them its vertices go. ``rest``: (N, 3) the layout's
    rest shape (where the bumps sit). The map itself when no chain is paired."""
    chains = [
        (np.asarray(c, dtype=np.float64).reshape(-1, 3), np.asarray(p, dtype=np.float64).reshape(-1, 3))
        for c, p in chains
    ]
    chains = [(c, p) for c, p in chains if c.shape[0] and p.shape[0] >= 2]
    rest = np.asarray(rest, dtype=np.float64).reshape(-1, 3)
    if mapping is None or not chains or rest.shape[0] == 0:
        return mapping
    points = np.concatenate([c for c, _p in chains])
    mapped = smooth_map.apply(mapping, points)
    nearest, tangents = [], []
    at = 0
    for chain, curve in chains:
        here = _nearest_on(mapped[at : at + chain.shape[0]], curve)
        nearest.append(here[0])
        tangents.append(here[1])
        at += chain.shape[0]
    across = np.eye(3)[None] - np.einsum("ni,nj->nij", np.concatenate(tangents), np.concatenate(tangents))
    misses = np.einsum("nij,nj->ni", across, np.concatenate(nearest) - mapped)
    width = BUMP_WIDTH * float(np.ptp(rest, axis=0).max())
    if not width > 0.0:
        return mapping
    centres = rest[_farthest(rest, min(BUMP_COUNT, rest.shape[0]))]
    values, fixed = smooth_map.bumps(points, centres, width), smooth_map.bumps(mapping.centres, centres, width)
    count = centres.shape[0]
    rows = [np.concatenate([values * across[:, axis, other, None] for other in range(3)], axis=1) for axis in range(3)]
    normal = sum(row.T @ row for row in rows) + BUMP_RIDGE * points.shape[0] * np.eye(3 * count)
    for axis in range(3):
        block = slice(axis * count, (axis + 1) * count)
        normal[block, block] += MAP_POINT_WEIGHT**2 * fixed.T @ fixed
    right = sum(row.T @ misses[:, axis] for axis, row in enumerate(rows))
    weights = np.linalg.solve(normal, right).reshape(3, count).T
    return mapping._replace(bumps=centres, bump_weights=weights, bump_width=width)


def _nearest_on(points: np.ndarray, polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nearest (P, 3), unit tangents (P, 3)): each of ``points``' nearest point on ``polyline`` ((K, 3), K >= 2)
    and the direction of the segment it lies on."""
    segment, t = smooth_map.nearest_segments(points, polyline)
    direction = np.diff(polyline, axis=0)[segment]
    length = np.maximum(np.linalg.norm(direction, axis=1), 1e-300)
    return polyline[segment] + t[:, None] * direction, direction / length[:, None]


def _farthest(points: np.ndarray, count: int) -> np.ndarray:
    """(count,) int64 indices of ``points`` ((N, 3)) spread by farthest-point sampling from the first."""
    chosen = [0]
    distance = np.linalg.norm(points - points[0], axis=1)
    for _pick in range(count - 1):
        chosen.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.asarray(chosen, dtype=np.int64)
