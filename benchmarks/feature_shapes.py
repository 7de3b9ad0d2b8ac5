"""A machined L-shaped part with known blend centre-lines, and the measures of detected feature curves against
them (coverage, offset, fragments). Used by ``benchmarks/feature_curves.py`` and the feature tests.

The part (metres): the profile is an L in the xy plane (arms 0.40 along x and 0.30 along y, 0.10 thick) whose
six vertical edges are filleted with radius ``radius`` (five convex blends: ridges; the inner corner's concave
fillet: a valley), extruded 0.20 along z; the two end caps are flat with sharp edges (the "part's edges" where
the blends end). Side walls are a grid of about ``spacing``; each cap is a star of rings round a point that
sees the whole profile. The kernel's own test (``rust_core/kernel/tests/features.rs``) builds the same part.
"""

import numpy as np

ARM_X, ARM_Y, THICKNESS, DEPTH = 0.40, 0.30, 0.10, 0.20
"""The L part's size (metres): x arm length, y arm length, arm thickness, extrusion depth."""


def _corners():
    """The L profile's six corners (counter-clockwise) and whether each is convex."""
    corners = np.array(
        [(0.0, 0.0), (ARM_X, 0.0), (ARM_X, THICKNESS), (THICKNESS, THICKNESS), (THICKNESS, ARM_Y), (0.0, ARM_Y)]
    )
    convex = np.array([True, True, True, False, True, True])
    return corners, convex


def _fillet(corner, previous, following, radius):
    """The fillet of ``corner`` between its edges to ``previous`` and ``following``: (centre, start, end)."""
    into = (previous - corner) / np.linalg.norm(previous - corner)
    out = (following - corner) / np.linalg.norm(following - corner)
    # A 90 degree corner: the fillet's centre is `radius` along both edges' inward directions.
    centre = corner + (into + out) * radius
    return centre, corner + into * radius, corner + out * radius


def l_profile(radius: float, spacing: float) -> np.ndarray:
    """(P, 2) the filleted L profile, counter-clockwise, points about ``spacing`` apart."""
    corners, _ = _corners()
    count = len(corners)
    points = []
    for index in range(count):
        corner = corners[index]
        previous, following = corners[index - 1], corners[(index + 1) % count]
        centre, start, end = _fillet(corner, previous, following, radius)
        a0 = np.arctan2(*(start - centre)[::-1])
        a1 = np.arctan2(*(end - centre)[::-1])
        sweep = (a1 - a0 + np.pi) % (2 * np.pi) - np.pi
        steps = max(2, int(np.ceil(abs(sweep) * radius / spacing)))
        angles = a0 + sweep * np.arange(steps) / steps
        points.extend(centre + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1))
        # The straight edge from this fillet's end to the next fillet's start.
        next_corner = corners[(index + 1) % count]
        _, next_start, _ = _fillet(next_corner, corner, corners[(index + 2) % count], radius)
        length = np.linalg.norm(next_start - end)
        steps = max(1, int(np.ceil(length / spacing)))
        points.extend(end + (next_start - end) * (np.arange(steps)[:, None] / steps))
    return np.array(points)


def l_part(radius: float = 0.04, spacing: float = 0.0065):
    """The closed L part: (V, 3) float32 vertices, (T, 3) uint32 triangles winding outwards."""
    profile = l_profile(radius, spacing)
    count = len(profile)
    rows = max(2, int(round(DEPTH / spacing)))
    z = DEPTH * np.arange(rows + 1) / rows
    wall = np.concatenate([np.column_stack([profile, np.full(count, height)]) for height in z])
    triangles = []
    for row in range(rows):
        a = row * count + np.arange(count)
        b = row * count + (np.arange(count) + 1) % count
        c, d = a + count, b + count
        triangles += [np.stack([a, b, d], 1), np.stack([a, d, c], 1)]
    vertices = [wall]
    # Caps: rings shrinking towards a point that sees all of the profile (inside the arms' common square).
    centre = np.array([THICKNESS / 2, THICKNESS / 2])
    reach = np.linalg.norm(profile - centre, axis=1).max()
    ring_count = max(2, int(np.ceil(reach / spacing)))
    offset = wall.shape[0]
    for cap, height, outer_row in ((0, 0.0, 0), (1, DEPTH, rows)):
        outer = outer_row * count + np.arange(count)
        fractions = 1.0 - np.arange(1, ring_count) / ring_count
        rings = [np.column_stack([centre + (profile - centre) * f, np.full(count, height)]) for f in fractions]
        inner_points = np.concatenate(rings + [np.array([[*centre, height]])])
        vertices.append(inner_points)
        ring_index = [outer] + [offset + k * count + np.arange(count) for k in range(ring_count - 1)]
        apex = offset + (ring_count - 1) * count
        for k in range(ring_count - 1):
            a, b = ring_index[k], np.roll(ring_index[k], -1)
            c, d = ring_index[k + 1], np.roll(ring_index[k + 1], -1)
            quads = [np.stack([a, c, d], 1), np.stack([a, d, b], 1)]
            if cap == 1:
                quads = [q[:, ::-1] for q in quads]
            triangles += quads
        last = ring_index[-1]
        fan = np.stack([last, np.full(count, apex), np.roll(last, -1)], 1)
        triangles.append(fan if cap == 0 else fan[:, ::-1])
        offset += inner_points.shape[0]
    vertices = np.concatenate(vertices)
    triangles = np.concatenate(triangles)
    return np.ascontiguousarray(vertices, dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.uint32)


def l_part_centre_lines(radius: float = 0.04):
    """The six blend centre-lines: (6, 2, 3) segment ends (z from 0 to the depth) and (6,) kinds
    (``'RIDGE'`` for the five convex blends, ``'VALLEY'`` for the inner fillet)."""
    corners, convex = _corners()
    count = len(corners)
    lines, kinds = [], []
    for index in range(count):
        centre, start, end = _fillet(corners[index], corners[index - 1], corners[(index + 1) % count], radius)
        middle = (start + end) / 2 - centre
        point = centre + middle / np.linalg.norm(middle) * radius
        lines.append([(*point, 0.0), (*point, DEPTH)])
        kinds.append("RIDGE" if convex[index] else "VALLEY")
    return np.array(lines), kinds


def segment_distances(points, segments):
    """(P, S) distance of each point to each segment ((S, 2, 3) ends)."""
    points = np.asarray(points, dtype=np.float64)
    start, end = segments[:, 0], segments[:, 1]
    direction = end - start
    t = np.einsum("psk,sk->ps", points[:, None, :] - start[None], direction) / (direction**2).sum(1)
    closest = start[None] + np.clip(t, 0.0, 1.0)[..., None] * direction[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2)


def resample(points, closed: bool, step: float) -> np.ndarray:
    """Points along a polyline about ``step`` apart (its vertices and points between them)."""
    points = np.asarray(points, dtype=np.float64)
    if closed:
        points = np.concatenate([points, points[:1]])
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        pieces = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, pieces + 1)[:, None] / pieces))
    return np.concatenate(out)


def l_part_sharp_edges(radius: float = 0.04, spacing: float = 0.002) -> np.ndarray:
    """(P, 3) points about ``spacing`` apart along the caps' sharp edges (the profile at z = 0 and at the depth):
    real creases too, the limit of a blend whose radius goes to 0."""
    profile = l_profile(radius, spacing)
    return np.concatenate([np.column_stack([profile, np.full(len(profile), z)]) for z in (0.0, DEPTH)])


def _nearest_distances(points, cloud, chunk: int = 2048) -> np.ndarray:
    """(P,) distance of each point to the nearest point of ``cloud``."""
    points = np.asarray(points, dtype=np.float64)
    result = np.empty(points.shape[0])
    for start in range(0, points.shape[0], chunk):
        block = points[start : start + chunk]
        result[start : start + chunk] = np.linalg.norm(block[:, None, :] - cloud[None], axis=2).min(1)
    return result


def curve_measures(curves, segments, kinds, tolerance: float, sharp_edges=None, step: float = 0.002) -> dict:
    """Coverage of each known centre-line by the curves of its kind (the fraction of the line, sampled every
    ``step``, within ``tolerance`` of such a curve), the offset (mean distance of the points of the curves that
    follow a centre-line, i.e. whose median point is within ``tolerance`` of one of their kind, to it), and the
    curve counts: ``curves_on_lines`` follow a centre-line, ``curves_on_edges`` follow a sharp edge (points
    ``sharp_edges``, when given), ``other_curves`` are the rest."""
    coverage, offsets, on_lines, on_edges, others = [], [], 0, 0, 0
    for segment, kind in zip(segments, kinds, strict=True):
        samples = resample(segment, False, step)
        near = np.zeros(len(samples), dtype=bool)
        for curve in curves:
            if curve.kind != kind:
                continue
            dense = resample(curve.points, curve.closed, step)
            near |= _nearest_distances(samples, dense) <= tolerance
        coverage.append(float(near.mean()))
    for curve in curves:
        distances = segment_distances(curve.points, segments)
        same_kind = np.array([kind == curve.kind for kind in kinds])
        distances[:, ~same_kind] = np.inf
        line = int(np.argmin(np.median(distances, axis=0)))
        if np.median(distances[:, line]) <= tolerance:
            on_lines += 1
            offsets.append(distances[:, line])
        elif sharp_edges is not None and np.median(_nearest_distances(curve.points, sharp_edges)) <= tolerance:
            on_edges += 1
        else:
            others += 1
    offset = float(np.concatenate(offsets).mean()) if offsets else float("nan")
    return {
        "coverage": coverage,
        "offset": offset,
        "curves_on_lines": on_lines,
        "curves_on_edges": on_edges,
        "other_curves": others,
    }


def end_reach(curves, segments, kinds, tolerance: float) -> list:
    """Per centre-line, how the curves following it (of its kind, median point within ``tolerance`` of it) end
    near its two ends (the caps): ``(gap_start, gap_end, drift_start, drift_end)``, the gaps measured along the
    line (from each end of the line to the farthest point of those curves projected onto it; 0: they reach
    it) and the drifts across it (the distance to the line of the curve point nearest each end). ``inf`` when
    no curve follows the line."""
    result = []
    for segment, kind in zip(segments, kinds, strict=True):
        start, end = segment
        axis = end - start
        length = float(np.linalg.norm(axis))
        points = [
            np.asarray(curve.points, dtype=np.float64)
            for curve in curves
            if curve.kind == kind and np.median(segment_distances(curve.points, segment[None])[:, 0]) <= tolerance
        ]
        if not points:
            result.append((float("inf"),) * 4)
            continue
        points = np.concatenate(points)
        along = (points - start) @ axis / length
        across = segment_distances(points, segment[None])[:, 0]
        first, last = int(np.argmin(along)), int(np.argmax(along))
        result.append(
            (
                max(0.0, float(along[first])),
                max(0.0, length - float(along[last])),
                float(across[first]),
                float(across[last]),
            )
        )
    return result
