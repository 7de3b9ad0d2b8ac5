"""Creases of a re-tessellated part, found from the planes of its flanks (numpy + kernel, no ``bpy``).

A voxel remesh or a scan of a machined part rounds each sharp crease into a narrow band of a few rows of
triangles whose dihedral angles are smaller than the crease's and whose rows stair-step: no single edge is the
crease. The crease is still there as the line where the planes of its two flanks meet. Each vertex gathers the
planes of the flat triangles (those that bend less than :data:`FLAT_SHARE` of the crease angle from each of
their neighbours) within :data:`RINGS` rings of it, as a quadric (dual contouring's least-squares corner): where
these planes have two directions of normal and meet on one line (:data:`MAX_MISFIT`), the point nearest the vertex on the line where they meet is the
crease's sharp corner, known to within a small part of a triangle however the band is tessellated; where they
have three, their meeting point is a corner of the part, where creases meet. The corner points of the band's
vertices are thinned to about one per mean edge, chained along the crease's direction, extended to the part's
corners they run into (those the planes show, or where the lines of two or more chain ends meet) and taken to the nearest point of the surface: the rounded crease's crest, where a sharp
crease of the part as designed lands on the rounded surface.
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

FLAT_SHARE = 1.0 / 6.0
"""A triangle is a flank's (its plane counts) when it bends less than this share of the crease angle from each
of its neighbours: on a voxel remesh a flat face's triangles bend a few degrees at its steps, those of a rounded
crease's band tens of degrees."""
RINGS = 3
"""The rings of vertices around each vertex whose flat triangles' planes it gathers: enough to reach past a
band of a couple of rows to both flanks, few enough not to reach the next crease."""
MIN_FLAT_AREA = 0.75
"""Rounded creases are looked for only on a mesh at least this share of whose area is in flat triangles (see
:data:`FLAT_SHARE`): a machined part's faces (0.85 on a part voxel-remeshed at 1/200 of its diagonal). On a
curved, organic shape (0.63 on a body voxel-remeshed at 4 mm) the planes of its scattered flat triangles meet
at small scale everywhere (the nose, the lips, the fingers) and no line there is a crease."""
MAX_MISFIT = 0.1
"""The largest root-mean-square distance (mean edges) of a vertex's flank planes from their crease line: two
flat flanks meet on one line, the facets of a coarsely tessellated curved surface do not."""
CORNER_SHARE = 0.01
"""The share of the planes' weight in their third direction of normal above which a vertex sees a corner of
the part (three flanks) rather than a crease."""
BAND_EDGES = 1.5
"""How far (mean edges) a vertex may lie from its crease's corner line to place a point of it."""
LINK_EDGES = 2.5
"""The farthest (mean edges) two thinned crease points are linked into one chain."""
LINK_COSINE = 0.9
"""Two crease points are linked only along the crease: the cosine between the crease's direction and the
step from one to the other is at least this."""
JOIN_EDGES = 5.0
"""The widest gap (mean edges) across which two chain ends that continue each other are joined: where a crease's
bend dips below the crease angle for a few rows (a crease about as sharp as the angle) it is still one line."""
JOIN_COSINE = 0.8
"""Two chain ends across a gap are joined only when the step from one to the other leaves each at a cosine of
at least this (the ends themselves leaving in opposite directions, :data:`LINK_COSINE`)."""
CORNER_EDGES = 5.0
"""How far (mean edges) beyond a chain's end a corner of the part may lie for the chain to be extended to it."""
MIN_POINTS = 4
"""Chains of fewer thinned points are dropped (a few stray planes, not a crease)."""


class RoundedCreases(NamedTuple):
    """What :func:`rounded_creases` found."""

    curves: list  # of (kind RIDGE or VALLEY, (P, 3) float32 points on the surface, closed)
    junctions: np.ndarray  # (J, 3) float64: the corners where two or more of them end, on the surface
    mean_edge: float = 0.0  # the mesh's mean edge length
    corners: np.ndarray | None = None  # (J, 3) float64: those corners where their flanks' planes meet (off the surface)


def edge_dihedrals(positions, triangles):
    """``(keys, slot, angle, normals, areas)``: the mesh's edges ((E, 2) int64 sorted vertex pairs), each
    triangle side's edge (``slot``, (3T,): sides 01, 12, 20 of every triangle in turn), the angle (degrees)
    between the normals of each edge's two triangles (0 for an edge of one triangle or of more than two), and
    the triangles' unit normals and areas."""
    positions = np.asarray(positions, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = positions[triangles]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    areas = np.linalg.norm(cross, axis=1) / 2.0
    normals = cross / np.maximum(2.0 * areas, 1e-300)[:, None]
    count = triangles.shape[0]
    sides = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    codes = sides[:, 0] * max(positions.shape[0], 1) + sides[:, 1]
    unique, slot = np.unique(codes, return_inverse=True)
    slot = slot.reshape(-1)
    keys = np.stack([unique // max(positions.shape[0], 1), unique % max(positions.shape[0], 1)], axis=1)
    faces = np.tile(np.arange(count), 3)
    order = np.argsort(slot, kind="stable")
    uses = np.bincount(slot, minlength=keys.shape[0])
    starts = np.concatenate([[0], np.cumsum(uses)[:-1]]).astype(np.int64)
    angle = np.zeros(keys.shape[0])
    inner = uses == 2
    first, second = faces[order[starts[inner]]], faces[order[starts[inner] + 1]]
    angle[inner] = np.degrees(np.arccos(np.clip(np.sum(normals[first] * normals[second], axis=1), -1.0, 1.0)))
    return keys, slot, angle, normals, areas


def _sum_columns(index: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """(count, C): the rows of ``values`` ((K, C)) summed by ``index`` ((K,))."""
    return np.stack([np.bincount(index, values[:, column], minlength=count) for column in range(values.shape[1])], 1)


def flank_quadrics(
    positions, triangles, crease_degrees: float, rings: int = RINGS, min_flat_area: float = MIN_FLAT_AREA
):
    """(N, 19) per vertex: the flat triangles' planes within ``rings`` rings, area-weighted, summed as
    ``A = Σ w n nᵀ`` (9 columns), ``b = Σ w (n·c) n`` (3), the first moment ``Σ w n`` (3), ``Σ w (n·c)²`` (1)
    and ``Σ w c`` (3), ``c`` a triangle's centroid (None when less than ``min_flat_area`` of the mesh's area is in
    flat triangles: not a machined part); and the mesh's mean edge length."""
    positions = np.asarray(positions, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    keys, slot, angle, normals, areas = edge_dihedrals(positions, triangles)
    count = triangles.shape[0]
    bend = np.zeros(count)
    np.maximum.at(bend, np.tile(np.arange(count), 3), angle[slot])
    weights = areas * (bend < FLAT_SHARE * crease_degrees)
    lengths = np.linalg.norm(positions[keys[:, 0]] - positions[keys[:, 1]], axis=1)
    mean_edge = float(lengths.mean()) if lengths.size else 0.0
    if not weights.sum() >= min_flat_area * areas.sum() or not areas.sum() > 0.0:
        return None, mean_edge
    offsets = np.einsum("ij,ij->i", normals, positions[triangles].mean(axis=1))
    per_face = np.concatenate(
        [
            (weights[:, None, None] * normals[:, :, None] * normals[:, None, :]).reshape(-1, 9),
            (weights * offsets)[:, None] * normals,
            weights[:, None] * normals,
            (weights * offsets**2)[:, None],
            weights[:, None] * positions[triangles].mean(axis=1),
        ],
        axis=1,
    )
    vertex_count = positions.shape[0]
    summed = sum(_sum_columns(triangles[:, corner], per_face, vertex_count) for corner in range(3))
    for _ring in range(rings - 1):
        summed = (
            summed
            + _sum_columns(keys[:, 0], summed[keys[:, 1]], vertex_count)
            + _sum_columns(keys[:, 1], summed[keys[:, 0]], vertex_count)
        )
    return summed, mean_edge


def corner_points(positions, quadrics, crease_degrees: float, mean_edge: float):
    """``(crease, corner)`` from :func:`flank_quadrics`: ``crease`` a tuple ``(points, directions, convex)`` of
    the sharp corner on the crease line of each vertex whose planes have two directions of normal meeting at
    more than ``crease_degrees`` on one line (:data:`MAX_MISFIT`) and whose line passes within
    :data:`BAND_EDGES` of it; ``corner`` (K, 3) the meeting points of the vertices whose planes have three
    directions, within :data:`CORNER_EDGES`."""
    positions = np.asarray(positions, dtype=np.float64)
    matrices = quadrics[:, :9].reshape(-1, 3, 3)
    values, vectors = np.linalg.eigh(matrices)  # ascending
    total = np.maximum(values.sum(axis=1), 1e-300)
    share = values / total[:, None]
    residual = quadrics[:, 9:12] - np.einsum("nij,nj->ni", matrices, positions)
    solvable = values > 1e-9 * total[:, None]  # a direction without planes moves nothing
    steps = np.einsum("nji,nj->ni", vectors, residual) / np.where(solvable, values, 1.0) * solvable
    moment = quadrics[:, 12:15]
    # Two clusters of normals with weights w1, w2 at angle t: the in-plane eigenvalues' product is
    # w1 w2 sin² t and (total² - |moment|²) / 2 is w1 w2 (1 - cos t).
    spread = np.maximum((total**2 - np.sum(moment**2, axis=1)) / 2.0, 1e-300)
    cosine = np.clip(values[:, 1] * values[:, 2] / spread - 1.0, -1.0, 1.0)
    minimum = 0.5 * np.sin(np.radians(crease_degrees) / 2.0) ** 2
    two = (share[:, 1] > minimum) & (share[:, 0] < CORNER_SHARE) & (np.degrees(np.arccos(cosine)) > crease_degrees)
    line = positions + vectors[:, :, 1] * steps[:, 1:2] + vectors[:, :, 2] * steps[:, 2:3]
    two &= np.linalg.norm(line - positions, axis=1) < BAND_EDGES * mean_edge
    centre = quadrics[:, 16:19] / total[:, None]  # the flanks' centroid: behind a convex crease's line
    convex = np.einsum("ij,ij->i", line - centre, moment) > 0.0
    energy = (
        quadrics[:, 15]
        - 2.0 * np.einsum("ij,ij->i", quadrics[:, 9:12], line)
        + np.einsum("ni,nij,nj->n", line, matrices, line)
    )
    two &= np.sqrt(np.maximum(energy, 0.0) / total) < MAX_MISFIT * mean_edge
    three = share[:, 0] >= CORNER_SHARE
    meeting = line + vectors[:, :, 0] * steps[:, 0:1]
    three &= np.linalg.norm(meeting - positions, axis=1) < CORNER_EDGES * mean_edge
    return (line[two], vectors[two, :, 0], convex[two]), meeting[three]


def _thin(points, directions, convex, cell: float):
    """The crease points averaged per grid cell of side ``cell`` (ridges and valleys apart): ``(points,
    directions (unit, the principal one of the cell's), convex)``."""
    cells = np.floor(points / cell).astype(np.int64)
    codes = np.concatenate([cells, convex[:, None].astype(np.int64)], axis=1)
    _unique, group = np.unique(codes, axis=0, return_inverse=True)
    group = group.reshape(-1)
    count = int(group.max()) + 1
    sizes = np.bincount(group, minlength=count).astype(np.float64)
    averaged = _sum_columns(group, points, count) / sizes[:, None]
    outer = _sum_columns(group, (directions[:, :, None] * directions[:, None, :]).reshape(-1, 9), count)
    principal = np.linalg.eigh(outer.reshape(-1, 3, 3))[1][:, :, 2]
    kinds = np.zeros(count, dtype=bool)
    kinds[group] = convex
    return averaged, principal, kinds


def _links(points, directions, convex, reach: float) -> np.ndarray:
    """(M, 2) int64 the nearest point ahead and behind each point (-1: none) along its direction, within
    ``reach``, of its kind."""
    links = np.full((points.shape[0], 2), -1, dtype=np.int64)
    for begin in range(0, points.shape[0], 512):
        here = slice(begin, begin + 512)
        steps = points[None, :, :] - points[here, None, :]
        distance = np.linalg.norm(steps, axis=2)
        along = np.einsum("ijk,ik->ij", steps, directions[here])
        usable = (
            (distance > 0.0)
            & (distance <= reach)
            & (np.abs(along) >= LINK_COSINE * distance)
            & (convex[None, :] == convex[here, None])
        )
        for column, side in ((0, along > 0.0), (1, along < 0.0)):
            masked = np.where(usable & side, distance, np.inf)
            nearest = masked.argmin(axis=1)
            found = np.isfinite(masked[np.arange(nearest.size), nearest])
            links[here, column] = np.where(found, nearest, -1)
    return links


def _chains(links: np.ndarray) -> list:
    """The chains (lists of point indices, closed ones flagged) of the links both ends chose."""
    neighbours = [set() for _ in range(links.shape[0])]
    for point, chosen in enumerate(links.tolist()):
        for other in chosen:
            if other >= 0 and point in links[other].tolist():
                neighbours[point].add(other)
    seen, chains = np.zeros(links.shape[0], dtype=bool), []
    starts = [point for point in range(links.shape[0]) if len(neighbours[point]) < 2]
    for start in starts + list(range(links.shape[0])):  # open chains from their ends first, then loops
        if seen[start]:
            continue
        chain, previous, here = [start], -1, start
        seen[start] = True
        while True:
            ahead = [other for other in neighbours[here] if other != previous and not seen[other]]
            if not ahead:
                break
            previous, here = here, ahead[0]
            seen[here] = True
            chain.append(here)
        chains.append((chain, len(chain) > 2 and chain[0] in neighbours[chain[-1]]))
    return chains


def _outward(line: np.ndarray, end: int) -> np.ndarray:
    """The unit direction in which the open chain ``line`` leaves at its start (``end`` 0) or end (1)."""
    tip, before = (line[0], line[min(2, line.shape[0] - 1)]) if end == 0 else (line[-1], line[max(-3, -line.shape[0])])
    step = tip - before
    return step / max(float(np.linalg.norm(step)), 1e-300)


def _join(chains: list, reach: float) -> list:
    """``chains`` ((points, convex, closed) each) with the ends that continue each other joined, nearest first:
    of one kind, within ``reach``, leaving in opposite directions (:data:`LINK_COSINE`) and, unless they
    overlap, facing each other across the gap; a chain whose two ends do so is closed."""
    chains = list(chains)
    while True:
        ends = [(index, end) for index, (line, _c, closed) in enumerate(chains) if not closed for end in (0, 1)]
        if len(ends) < 2:
            return chains
        tips = np.array([chains[index][0][0 if end == 0 else -1] for index, end in ends])
        outward = np.array([_outward(chains[index][0], end) for index, end in ends])
        kinds = np.array([chains[index][1] for index, _end in ends])
        owners = np.array([index for index, _end in ends])
        steps = tips[None, :, :] - tips[:, None, :]
        distance = np.linalg.norm(steps, axis=2)
        facing = np.einsum("ijk,ik->ij", steps, outward) >= JOIN_COSINE * distance
        facing &= facing.T
        joinable = (
            (distance <= reach)
            & (kinds[:, None] == kinds[None, :])
            & (outward @ outward.T <= -LINK_COSINE)
            & (facing | (distance <= 0.5 * reach / JOIN_EDGES))
        )
        small = np.array([chains[index][0].shape[0] < 2 * MIN_POINTS for index in owners])
        joinable &= (owners[:, None] != owners[None, :]) | ~small[:, None]
        np.fill_diagonal(joinable, False)
        if not joinable.any():
            return chains
        first, second = np.unravel_index(np.argmin(np.where(joinable, distance, np.inf)), distance.shape)
        (one, one_end), (other, other_end) = ends[first], ends[second]
        line = chains[one][0] if one_end == 1 else chains[one][0][::-1]
        if one == other:
            chains[one] = (line, chains[one][1], True)
            continue
        after = chains[other][0] if other_end == 0 else chains[other][0][::-1]
        joined = (np.concatenate([line, after]), chains[one][1], False)
        chains = [chain for index, chain in enumerate(chains) if index not in (one, other)] + [joined]


def _extend(points: np.ndarray, corners: np.ndarray, reach: float) -> tuple[np.ndarray, list]:
    """The open chain ``points`` with the corner of ``corners`` ((K, 3)) ahead of each end within ``reach``
    appended there, and the corners' indices used (-1: none) at its start and end."""
    used = []
    for end in (0, 1):
        tip, outward = points[0] if end == 0 else points[-1], _outward(points, end)
        steps = corners - tip
        distance = np.linalg.norm(steps, axis=1)
        ahead = (distance <= reach) & (steps @ outward >= 0.5 * distance)
        choice = int(np.argmin(np.where(ahead, distance, np.inf))) if ahead.any() else -1
        used.append(choice)
        if choice >= 0:
            points = (
                np.concatenate([corners[choice][None], points])
                if end == 0
                else np.concatenate([points, corners[choice][None]])
            )
    return points, used


def _meeting_point(tips: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The point nearest (least squares) to the lines through ``tips`` along ``directions`` ((K, 3) each)."""
    across = np.eye(3)[None, :, :] - directions[:, :, None] * directions[:, None, :]
    return np.linalg.lstsq(across.sum(axis=0), np.einsum("kij,kj->i", across, tips), rcond=None)[0]


def _ends_met(traced: list, free: list, reach: float) -> tuple[list, list]:
    """``traced`` ((kind, points, closed) each) with the ends ``free`` flags (``[start, end]`` per chain: not
    closed, not extended to a corner yet) that meet another's across a corner no planes found (within ``reach`` of each other, running across each other: ``|cos|`` below
    :data:`LINK_COSINE`) extended to where their lines meet, if that lies ahead of each within ``reach``; and
    the meeting points."""
    ends = [(index, end) for index, flags in enumerate(free) for end in (0, 1) if flags[end]]
    if len(ends) < 2:
        return traced, []
    tips = np.array([traced[index][1][0 if end == 0 else -1] for index, end in ends], dtype=np.float64)
    outward = np.array([_outward(np.asarray(traced[index][1], dtype=np.float64), end) for index, end in ends])
    distance = np.linalg.norm(tips[:, None, :] - tips[None, :, :], axis=2)
    meets = (distance <= reach) & (np.abs(outward @ outward.T) < LINK_COSINE)
    group = np.arange(len(ends))
    for first, second in zip(*np.nonzero(np.triu(meets, 1))):
        group[group == group[second]] = group[first]
    traced, corners = [list(item) for item in traced], []
    for label in np.unique(group):
        members = np.flatnonzero(group == label)
        if members.size < 2:
            continue
        corner = _meeting_point(tips[members], outward[members])
        steps = corner - tips[members]
        if not np.all((np.linalg.norm(steps, axis=1) <= reach) & (np.einsum("ij,ij->i", steps, outward[members]) > 0)):
            continue
        corners.append(corner)
        for member in members.tolist():
            index, end = ends[member]
            line = np.asarray(traced[index][1], dtype=np.float64)
            traced[index][1] = np.concatenate([corner[None], line] if end == 0 else [line, corner[None]])
    return [tuple(item) for item in traced], corners


def _merge(points: np.ndarray, reach: float) -> np.ndarray:
    """The points averaged where they lie within ``reach`` of one another (greedily, nearest to the first)."""
    merged, left = [], np.ones(points.shape[0], dtype=bool)
    for index in range(points.shape[0]):
        if not left[index]:
            continue
        near = left & (np.linalg.norm(points - points[index], axis=1) <= reach)
        merged.append(points[near].mean(axis=0))
        left &= ~near
    return np.array(merged, dtype=np.float64).reshape(-1, 3)


def rounded_creases(positions, triangles, crease_degrees: float) -> RoundedCreases:
    """The creases of a mesh whose sharp creases a re-tessellation rounded (see the module docs): each chain of
    crease points on the surface, kind RIDGE (convex) or VALLEY, and the corners where two or more end. Empty
    for a crease angle of 0, a mesh without triangles or one mostly curved (:data:`MIN_FLAT_AREA`: an organic
    shape, or noise everywhere)."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    empty = RoundedCreases([], np.zeros((0, 3)))
    if not crease_degrees > 0.0 or triangles.shape[0] == 0:
        return empty
    quadrics, mean_edge = flank_quadrics(positions, triangles, crease_degrees)
    if quadrics is None or not mean_edge > 0.0:
        return RoundedCreases([], np.zeros((0, 3)), mean_edge)
    (points, directions, convex), meeting = corner_points(positions, quadrics, crease_degrees, mean_edge)
    if points.shape[0] < MIN_POINTS:
        return RoundedCreases([], np.zeros((0, 3)), mean_edge)
    points, directions, convex = _thin(points, directions, convex, mean_edge)
    corners = _merge(meeting, 2.0 * mean_edge)
    traced, ends, free = [], [], []
    chained = [
        (points[chain], bool(convex[chain].mean() >= 0.5), closed)
        for chain, closed in _chains(_links(points, directions, convex, LINK_EDGES * mean_edge))
    ]
    for line, ridge, closed in _join(chained, JOIN_EDGES * mean_edge):
        if line.shape[0] < MIN_POINTS:
            continue
        used = [-1, -1]
        if not closed and corners.shape[0]:
            line, used = _extend(line, corners, CORNER_EDGES * mean_edge)
            ends += [index for index in used if index >= 0]
        traced.append(("RIDGE" if ridge else "VALLEY", line, closed))
        free.append([not closed and used[0] < 0, not closed and used[1] < 0])
    traced, met = _ends_met(traced, free, CORNER_EDGES * mean_edge)
    if not traced:
        return RoundedCreases([], np.zeros((0, 3)), mean_edge)
    surface = springwrap_kernel.TargetMesh(
        np.ascontiguousarray(positions, dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.uint32)
    )
    everything = np.concatenate([line for _kind, line, _closed in traced])
    landed = surface.closest_points(np.ascontiguousarray(everything, dtype=np.float32)).positions
    landed = np.asarray(landed, dtype=np.float32)
    found, at = [], 0
    for kind, line, closed in traced:
        found.append((kind, np.ascontiguousarray(landed[at : at + line.shape[0]]), closed))
        at += line.shape[0]
    used, uses = np.unique(np.asarray(ends, dtype=np.int64), return_counts=True)
    shared = np.concatenate([corners[used[uses >= 2]], np.asarray(met, dtype=np.float64).reshape(-1, 3)])
    junctions = np.zeros((0, 3))
    if shared.shape[0]:
        junctions = np.asarray(
            surface.closest_points(np.ascontiguousarray(shared, dtype=np.float32)).positions, dtype=np.float64
        )
    return RoundedCreases(found, junctions, mean_edge, np.asarray(shared, dtype=np.float64).reshape(-1, 3))


ON_CREST_EDGES = 0.1
"""A target crease of its own sharp edges that runs along a rounded crease (:func:`rounded_creases`) is that crease
only when it lies this close (mean target edges, median over its vertices) to the rounded crease's line:
farther, it is a row of edges beside the crest, and the rounded crease is paired instead."""


def on_lines(points, polylines, distance: float) -> bool:
    """Whether the median distance of ``points`` from the nearest segment of ``polylines`` is within
    ``distance``."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    segments = [np.asarray(line, dtype=np.float64) for line in polylines if len(line) >= 2]
    if not segments or points.shape[0] == 0:
        return False
    starts = np.concatenate([line[:-1] for line in segments])
    steps = np.concatenate([np.diff(line, axis=0) for line in segments])
    squared = np.maximum(np.sum(steps**2, axis=1), 1e-300)
    nearest = np.empty(points.shape[0])
    for begin in range(0, points.shape[0], 256):
        block = points[begin : begin + 256, None, :]
        t = np.clip(np.sum((block - starts) * steps, axis=2) / squared, 0.0, 1.0)
        nearest[begin : begin + 256] = np.sqrt(
            np.min(np.sum((block - starts - t[..., None] * steps) ** 2, axis=2), axis=1)
        )
    return bool(np.median(nearest) <= distance)


CORNER_RINGS = 2
"""The rings of faces round a layout's corner vertex whose planes say where its corner is: its flanks, not the
next crease (a layout's faces are far larger than a scan's triangles)."""
OFF_CORNER = 0.08
"""A layout's corner vertex lies off its corner when its distance from its flanks' planes (root mean square) is
more than this share of a mean edge: a retopology that put the vertex beside the corner (a sharp corner's vertex
lies on its planes to a few hundredths of an edge)."""
CORNER_FIT = 0.05
"""The largest root-mean-square distance (mean edges) of the flanks' planes from their meeting point for it to be
taken: three flat flanks meet at one point, the facets of curved ones do not."""
WIDE_SHARE, WIDE_OFF = 0.03, 0.05
"""A corner vertex whose :data:`CORNER_RINGS` rings show two flanks (its third flank bent near it) looks one ring
farther, where the third flank must carry this share of the planes' weight (three times :data:`CORNER_SHARE`: the
wider ring takes in more of the flanks' curvature) and the vertex lie off them by more than this (mean edges; a
corner's vertex lies on them to 0.01-0.04 edges on fandisk's QuadriFlow layout)."""
CORNER_REACH = 0.5
"""The farthest (mean edges) a layout's corner vertex is taken to where its flanks meet."""


def sharp_corners(positions, face_corners, face_sizes, vertices, crease_degrees: float) -> np.ndarray:
    """(K, 3) float64: for each of ``vertices`` ((K,), corners where a layout's creases meet) of the polygon mesh
    (``positions`` (N, 3), ``face_corners`` flat, ``face_sizes``), the point where the planes of its flat flanks
    within :data:`CORNER_RINGS` rings (or one more, :data:`WIDE_SHARE`) meet when it lies off them (:data:`OFF_CORNER`)
    and they meet well at one point (:data:`CORNER_FIT`, three directions of normal) within :data:`CORNER_REACH`; else the vertex itself.
    What a retopology's corner vertex beside the part's corner stands for: the corner."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    vertices = np.asarray(vertices, dtype=np.int64).reshape(-1)
    found = positions[vertices].copy()
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    if vertices.size == 0 or sizes.size == 0 or not crease_degrees > 0.0:
        return found
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    fan = [
        np.stack([corners[starts[sizes > k]], corners[starts[sizes > k] + k - 1], corners[starts[sizes > k] + k]], 1)
        for k in range(2, int(sizes.max()))
    ]
    triangles = np.concatenate(fan) if fan else np.zeros((0, 3), dtype=np.int64)
    with np.errstate(invalid="ignore"):  # a lost (not finite) vertex: its faces' quadrics are skipped below
        narrow, mean_edge = flank_quadrics(positions, triangles, crease_degrees, CORNER_RINGS, min_flat_area=0.0)
        wide = flank_quadrics(positions, triangles, crease_degrees, CORNER_RINGS + 1, min_flat_area=0.0)[0]
    if narrow is None or not mean_edge > 0.0:
        return found
    for row, vertex in enumerate(vertices.tolist()):
        for quadrics, share, limit in ((narrow, CORNER_SHARE, OFF_CORNER), (wide, WIDE_SHARE, WIDE_OFF)):
            matrix, offset, squares = quadrics[vertex, :9].reshape(3, 3), quadrics[vertex, 9:12], quadrics[vertex, 15]
            values = np.linalg.eigvalsh(matrix) if np.all(np.isfinite(quadrics[vertex])) else np.zeros(3)
            total, off_corner = values.sum(), limit
            if total > 0.0 and values[0] >= share * total:
                break  # three flanks
        else:
            continue  # fewer than three flanks, or a face of a lost vertex (not finite) among them
        meeting = np.linalg.solve(matrix, offset)
        point = positions[vertex]
        off, fit = (
            np.sqrt(max(squares - 2.0 * offset @ p + p @ matrix @ p, 0.0) / total) / mean_edge for p in (point, meeting)
        )
        if off > off_corner and fit <= CORNER_FIT and np.linalg.norm(meeting - point) <= CORNER_REACH * mean_edge:
            found[row] = meeting
    return found
