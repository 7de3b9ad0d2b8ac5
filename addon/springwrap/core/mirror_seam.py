"""Where a layout meets its mirror plane (no ``bpy``): the seam of a surfaced half, and a layout that is no half.

A half surfaced alone has an **open border** where its midline is. A wrap without Hold on Plane moves that
border off the plane (on a body, up to about two of its edge lengths, to either side), so a seam found only
by distance (``mirroring.plan``'s weld distance) misses most of it and the mirror leaves a crack. Here the
seam is also found as what it is: the open border vertices that **face** the plane (the layout runs away
from the plane on the surfaced side behind them) and lie within :data:`BORDER_REACH` of their own edge
lengths of it, wherever the wrap left them. Other open borders (a neck opening, a wrist) run across the
plane or face away from it and are not taken.

The **surfaced side** is the side with more vertices clearly off the plane. A layout with vertices on the
other side farther than :data:`OTHER_SIDE_REACH` of their edge lengths (beyond the seam) already covers both
sides: mirroring would lay a copy over it, and it is refused.
"""

import numpy as np

from .errors import LayoutError

BORDER_REACH = 2.5
"""An open-border vertex facing the plane is on the seam within this many of its mean edge lengths of it."""
BORDER_FACING = 0.25
"""An open-border vertex faces the plane when the cosine between the plane's normal (toward the surfaced side) and
the direction from it to its neighbours off the border is at least this."""
OTHER_SIDE_REACH = 2.0
"""A vertex beyond the seam on the other side farther than this many of its edge lengths: the layout covers both."""
RESETTLE_RINGS = 2
"""Rings of the surfaced half around seam vertices brought back onto the plane that the mirror's wrap re-settles."""


def vertex_edge_lengths(positions: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(N,) float64 mean length of each vertex's edges; vertices on no edge get the overall mean."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    count = positions.shape[0]
    if edges.shape[0] == 0:
        return np.zeros(count)
    lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    totals = np.bincount(edges.ravel(), weights=np.repeat(lengths, 2), minlength=count)
    degrees = np.bincount(edges.ravel(), minlength=count)
    mean = float(lengths.mean())
    return np.where(degrees > 0, totals / np.maximum(degrees, 1), mean)


def face_edges(corners: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """(C, 2) int64 the edges of faces given corner by corner (each corner to the next in its face)."""
    corners, sizes = np.asarray(corners, dtype=np.int64), np.asarray(sizes, dtype=np.int64)
    if corners.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    starts = np.repeat(np.concatenate([[0], np.cumsum(sizes)[:-1]]), sizes)
    following = np.arange(corners.size) + 1
    following = np.where(following == starts + np.repeat(sizes, sizes), starts, following)
    return np.stack([corners, corners[following]], axis=1)


def border_edges(face_edges: np.ndarray) -> np.ndarray:
    """(B, 2) the edges used by exactly one face (the open borders), from every face's edges (:func:`face_edges`)."""
    face_edges = np.sort(np.asarray(face_edges, dtype=np.int64).reshape(-1, 2), axis=1)
    keys, counts = np.unique(face_edges[:, 0] * (1 << 32) + face_edges[:, 1], return_counts=True)
    single = keys[counts == 1]
    return np.stack([single >> 32, single & ((1 << 32) - 1)], axis=1)


def border_on_plane(
    positions: np.ndarray, open_edges: np.ndarray, edge_lengths: np.ndarray, distances: np.ndarray, weld: float
) -> np.ndarray:
    """(K,) the open-border vertices within ``weld`` of their mean edge length of a plane (``distances`` from it),
    when they are at least half of the open border and at least three (a half's midline); else empty."""
    border = np.unique(np.asarray(open_edges, dtype=np.int64))
    on_plane = border[np.abs(distances[border]) <= weld * edge_lengths[border]]
    if on_plane.size < 3 or 2 * on_plane.size < border.size:
        return np.zeros(0, dtype=np.int64)
    return on_plane


def surfaced_side(distances: np.ndarray, weld: np.ndarray) -> float:
    """+1.0 when at least as many vertices lie clearly on the normal's side of the plane as on the other, else -1.0."""
    return 1.0 if int((distances > weld).sum()) >= int((distances < -weld).sum()) else -1.0


def facing_cosines(positions: np.ndarray, edges: np.ndarray, border: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(N,) for each vertex, the cosine between ``direction`` and the sum of its edges to vertices off the open
    border (where the mesh lies from a border vertex), or of all its edges when none leads off the border (a
    corner); 0 for a vertex on no edge."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    inward = np.zeros_like(positions)
    everywhere = np.zeros_like(positions)
    for start, end in ((0, 1), (1, 0)):
        vectors = positions[edges[:, end]] - positions[edges[:, start]]
        off_border = ~border[edges[:, end]]
        np.add.at(inward, edges[off_border, start], vectors[off_border])
        np.add.at(everywhere, edges[:, start], vectors)
    inward = np.where((inward == 0.0).all(axis=1, keepdims=True), everywhere, inward)
    lengths = np.linalg.norm(inward, axis=1)
    return np.divide(inward @ direction, lengths, out=np.zeros(lengths.shape), where=lengths > 0.0)


def border_seam(
    positions: np.ndarray,
    edges: np.ndarray,
    open_edges: np.ndarray,
    distances: np.ndarray,
    edge_lengths: np.ndarray,
    normal: np.ndarray,
    side: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(seam, left out): the open-border vertices facing the plane within :data:`BORDER_REACH` of it, and those
    facing it next to them along the border but farther (the border drifted too far: a crack if mirrored)."""
    count = np.asarray(positions).reshape(-1, 3).shape[0]
    border = np.zeros(count, dtype=bool)
    border[np.asarray(open_edges, dtype=np.int64).ravel()] = True
    facing = border & (facing_cosines(positions, edges, border, side * np.asarray(normal)) >= BORDER_FACING)
    reach = np.abs(distances) / np.maximum(edge_lengths, np.finfo(np.float64).tiny)
    seam = facing & (reach <= BORDER_REACH)
    neighbours = np.zeros(count, dtype=bool)
    for start, end in ((0, 1), (1, 0)):
        neighbours[open_edges[seam[open_edges[:, start]], end]] = True
    return seam, neighbours & facing & ~seam & (reach <= 2.0 * BORDER_REACH)


def check_one_side(
    distances: np.ndarray, edge_lengths: np.ndarray, seam: np.ndarray, side: float, layout_name: str
) -> None:
    """Refuse a layout with vertices beyond the seam on the other side farther than :data:`OTHER_SIDE_REACH` of
    their edge lengths: it covers both sides of the plane already."""
    across = -side * distances
    beyond = ~seam & (across > OTHER_SIDE_REACH * edge_lengths)
    if beyond.any():
        raise LayoutError(
            f"{layout_name} already covers both sides of the mirror plane: {int(beyond.sum())} vertices lie on "
            f"the other side, up to {float(across[beyond].max()):.4g} from it, so their mirror would be laid over "
            "the other half. Delete the other half (keep one side and its midline) and mirror that, or choose the "
            "axis or the Mirror Object of the plane along the layout's open side"
        )


def check_drifted_border(left_out: np.ndarray, distances: np.ndarray, layout_name: str, plane_hint: str) -> None:
    """Refuse when part of the open border at the plane drifted too far from it to be welded (a crack)."""
    if left_out.any():
        raise LayoutError(
            f"The open border of {layout_name} at the mirror plane drifted too far from it to be welded: "
            f"{int(left_out.sum())} of its vertices lie up to {float(np.abs(distances[left_out]).max()):.4g} from "
            f"the plane (more than {BORDER_REACH:g} of their edge lengths). Wrap the half with Hold on Plane "
            f"{plane_hint} (its midline then stays on the plane), or move those vertices onto the plane, then mirror"
        )


def resettled(edges: np.ndarray, moved: np.ndarray, rings: int = RESETTLE_RINGS) -> np.ndarray:
    """(N,) bool: the vertices within ``rings`` edges of a ``moved`` one (those included)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    reached = np.asarray(moved, dtype=bool).copy()
    for _ring in range(rings):
        grown = reached.copy()
        grown[edges[reached[edges[:, 0]], 1]] = True
        grown[edges[reached[edges[:, 1]], 0]] = True
        reached = grown
    return reached


def midline_plane(world_positions, open_edges, edges, planes, weld_fraction: float):
    """``(axis, plane, vertices)`` of the first of ``planes`` (``(axis, mirroring.Plane)`` pairs: the layout's or its
    Mirror Object's X, Y and Z planes) that the layout's open border (``open_edges``, (B, 2): edges of one face)
    lies on (:func:`border_on_plane`: a half's midline), ``vertices`` those border vertices; None when it lies on
    none of them, or when the layout lies in that plane altogether (a flat sheet)."""
    positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    open_edges = np.asarray(open_edges, dtype=np.int64).reshape(-1, 2)
    if open_edges.size == 0:
        return None
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    border = np.zeros(positions.shape[0], dtype=bool)
    border[open_edges.ravel()] = True
    edge_lengths = vertex_edge_lengths(positions, edges[border[edges].any(axis=1)])  # needed on the border only
    typical = float(np.median(edge_lengths[border]))
    for axis, plane in planes:
        distances = (positions - plane.point) @ plane.normal
        if np.mean(np.abs(distances) <= weld_fraction * typical) > 0.5:
            continue  # the layout lies in this plane: its border is no midline
        vertices = border_on_plane(positions, open_edges, edge_lengths, distances, weld_fraction)
        if vertices.size:
            return axis, plane, vertices
    return None
