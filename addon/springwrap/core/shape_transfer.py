"""Shape keys carried over a change of the layout's shape: deformation transfer by per-vertex frames (numpy, no bpy).

A key's offset at a vertex (key minus the key it is relative to) is expressed in the vertex's local frame
on the rest shape (the basis before the operation) and re-expressed in its frame on the new basis, times
the ratio of the two local scales: a smile made on the template is a smile on the new shape, turned
with the surface and grown with it.

- **Frame**: the normal is the area-weighted sum of the incident faces' normals (Newell's polygon
  normal, so quads and n-gons count by their area). The tangent is fixed by the one-ring itself: the
  in-plane rotation between the rest and the new frame is the 2D Procrustes angle that best maps the
  rest one-ring edges (projected into the rest tangent plane) onto the new ones, so no edge is
  privileged and the result does not depend on which tangent each frame started from.
- **Scale**: the square root of the ratio of the one-ring areas (the incident faces), which is how
  Sumner & Popović's deformation gradient scales a triangle's normal; the ratio of mean incident edge
  lengths where an area is degenerate.
- **Fallbacks** (never NaN): a vertex on no face, or whose area-weighted normal vanishes on either shape
  (degenerate or cancelling faces), turns by the smallest rotation taking its first incident edge's rest
  direction to the new one, scaled by the edge-length ratio; a vertex with no usable edge either is
  only moved along (its offset kept). A vertex whose whole neighbourhood (itself, the corners of its
  faces, its edge neighbours) did not move keeps its offsets bit for bit, and a zero offset stays
  exactly zero everywhere.

Why frames and not Sumner & Popović's per-triangle gradients solved by least squares: the solve
spreads every key over the whole mesh (untouched vertices of a key would drift), needs a sparse
solver (Blender's Python has no scipy), and gives the same rotation and scale on a smooth surface.
"""

from typing import NamedTuple

import numpy as np

from . import input_policy
from .errors import LayoutError

AREA_EPSILON = 1e-12
"""A one-ring area (or area-weighted normal) below this fraction of its squared mean edge length is degenerate."""


class TransferMaps(NamedTuple):
    """Per-vertex linear maps from rest offsets to new offsets."""

    matrices: np.ndarray  # (N, 3, 3) float64: new offset = matrices[i] @ rest offset
    moved: np.ndarray  # (N,) bool: the vertex's neighbourhood moved (others keep their offsets bit for bit)
    fallback: np.ndarray  # (N,) bool: no face frame on one of the shapes (edge rotation or none)


def _face_corner_arrays(face_corners, face_sizes):
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    face_of_corner = np.repeat(np.arange(sizes.shape[0]), sizes)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64) if sizes.size else np.zeros(0, np.int64)
    position_in_face = np.arange(corners.shape[0]) - starts[face_of_corner]
    last = position_in_face + 1 == sizes[face_of_corner]
    next_corner = np.where(last, starts[face_of_corner], np.arange(corners.shape[0]) + 1)
    return corners, face_of_corner, next_corner, starts


def _sum_by(index: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Row sums of ``values`` ((M,) or (M, 3)) grouped by ``index`` into ``count`` rows."""
    if values.ndim == 1:
        return np.bincount(index, weights=values, minlength=count)[:count]
    return np.stack([np.bincount(index, weights=values[:, axis], minlength=count)[:count] for axis in range(3)], 1)


def _one_ring(positions, face_arrays, face_count):
    """(N, 3) area-weighted normal sums and (N,) one-ring areas of ``positions``."""
    corners, face_of_corner, next_corner, starts = face_arrays
    count = positions.shape[0]
    if corners.size == 0:
        return np.zeros((count, 3)), np.zeros(count)
    # Newell: half the sum of p_i x p_next over a face is its area vector (area times unit normal); taken
    # relative to the face's first corner, so that a layout far from the origin loses nothing.
    origin = positions[corners[starts[face_of_corner]]]
    crosses = np.cross(positions[corners] - origin, positions[corners[next_corner]] - origin)
    area_vectors = 0.5 * _sum_by(face_of_corner, crosses, face_count)
    areas = np.linalg.norm(area_vectors, axis=1)
    return _sum_by(corners, area_vectors[face_of_corner], count), _sum_by(corners, areas[face_of_corner], count)


def _tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing each unit normal to a right-handed frame (Duff et al. 2017)."""
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    tangents = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    bitangents = np.stack([b, sign + y * y * a, -y], axis=1)
    return tangents, bitangents


def _unit(vectors: np.ndarray, valid: np.ndarray) -> np.ndarray:
    lengths = np.linalg.norm(vectors, axis=1)
    safe = np.where(valid & (lengths > 0.0), lengths, 1.0)
    return np.where(valid[:, None], vectors / safe[:, None], 0.0)


def _smallest_rotations(sources: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(N, 3, 3) smallest rotations taking unit ``sources`` to unit ``targets`` (a half turn when opposite)."""
    axis = np.cross(sources, targets)
    cosine = np.clip(np.einsum("ij,ij->i", sources, targets), -1.0, 1.0)
    skew = np.zeros((sources.shape[0], 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    opposite = cosine < -1.0 + 1e-9
    factor = np.where(opposite, 0.0, 1.0 / np.where(opposite, 1.0, 1.0 + cosine))
    rotations = np.eye(3) + skew + factor[:, None, None] * (skew @ skew)
    if opposite.any():
        perpendicular, _ = _tangent_basis(sources[opposite])
        rotations[opposite] = 2.0 * np.einsum("ni,nj->nij", perpendicular, perpendicular) - np.eye(3)
    return rotations


def transfer_maps(rest, deformed, face_corners, face_sizes, edges) -> TransferMaps:
    """The per-vertex maps taking offsets on ``rest`` ((N, 3)) to offsets on ``deformed`` (the same topology:
    ``face_corners`` / ``face_sizes`` as the kernel's layout structure, ``edges`` (E, 2))."""
    rest = np.asarray(rest, dtype=np.float64).reshape(-1, 3)
    deformed = np.asarray(deformed, dtype=np.float64).reshape(-1, 3)
    count = rest.shape[0]
    if deformed.shape[0] != count:
        raise LayoutError(f"Shape keys: {count} rest positions but {deformed.shape[0]} new ones")
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    face_arrays = _face_corner_arrays(face_corners, face_sizes)
    corners, face_of_corner = face_arrays[0], face_arrays[1]
    face_count = int(np.asarray(face_sizes).size)

    # Who moved: a vertex, a corner of one of its faces or an edge neighbour.
    changed = np.any(rest != deformed, axis=1)
    moved = changed.copy()
    if corners.size:
        face_changed = _sum_by(face_of_corner, changed[corners].astype(np.float64), face_count) > 0
        moved |= _sum_by(corners, face_changed[face_of_corner].astype(np.float64), count) > 0
    if edges.size:
        moved |= _sum_by(edges[:, 0], changed[edges[:, 1]].astype(np.float64), count) > 0
        moved |= _sum_by(edges[:, 1], changed[edges[:, 0]].astype(np.float64), count) > 0

    # Mean incident edge length per vertex on both shapes (the reference for degeneracy, the fallback scale).
    degree = _sum_by(edges.reshape(-1), np.ones(edges.size), count) if edges.size else np.zeros(count)
    ends = np.concatenate([edges, edges[:, ::-1]]) if edges.size else np.zeros((0, 2), np.int64)

    def mean_edge(points):
        if not ends.size:
            return np.zeros(count)
        lengths = np.linalg.norm(points[ends[:, 1]] - points[ends[:, 0]], axis=1)
        return _sum_by(ends[:, 0], lengths, count) / np.maximum(degree, 1.0)

    rest_edge, deformed_edge = mean_edge(rest), mean_edge(deformed)
    rest_normal, rest_area = _one_ring(rest, face_arrays, face_count)
    deformed_normal, deformed_area = _one_ring(deformed, face_arrays, face_count)
    rest_floor = AREA_EPSILON * rest_edge**2
    deformed_floor = AREA_EPSILON * deformed_edge**2
    framed = (
        (np.linalg.norm(rest_normal, axis=1) > rest_floor)
        & (np.linalg.norm(deformed_normal, axis=1) > deformed_floor)
        & (rest_edge > 0.0)
        & (deformed_edge > 0.0)
    )
    rest_n = _unit(rest_normal, framed)
    deformed_n = _unit(deformed_normal, framed)
    rest_n[~framed] = (0.0, 0.0, 1.0)
    deformed_n[~framed] = (0.0, 0.0, 1.0)
    rest_t, rest_b = _tangent_basis(rest_n)
    deformed_t, deformed_b = _tangent_basis(deformed_n)

    # The in-plane turn: the 2D Procrustes angle from the rest one-ring edges to the new ones.
    cross_sum = np.zeros(count)
    dot_sum = np.zeros(count)
    if ends.size:
        home = ends[:, 0]
        rest_edges = rest[ends[:, 1]] - rest[home]
        deformed_edges = deformed[ends[:, 1]] - deformed[home]
        rx = np.einsum("ij,ij->i", rest_edges, rest_t[home])
        ry = np.einsum("ij,ij->i", rest_edges, rest_b[home])
        dx = np.einsum("ij,ij->i", deformed_edges, deformed_t[home])
        dy = np.einsum("ij,ij->i", deformed_edges, deformed_b[home])
        cross_sum = _sum_by(home, rx * dy - ry * dx, count)
        dot_sum = _sum_by(home, rx * dx + ry * dy, count)
    angle = np.where((cross_sum != 0.0) | (dot_sum != 0.0), np.arctan2(cross_sum, dot_sum), 0.0)
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    turned_t = cos * deformed_t + sin * deformed_b
    turned_b = cos * deformed_b - sin * deformed_t
    rest_frame = np.stack([rest_t, rest_b, rest_n], axis=2)  # columns
    deformed_frame = np.stack([turned_t, turned_b, deformed_n], axis=2)
    rotations = deformed_frame @ np.transpose(rest_frame, (0, 2, 1))

    area_ok = (rest_area > rest_floor) & (deformed_area > deformed_floor)
    edge_ok = (rest_edge > 0.0) & (deformed_edge > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        area_scale = np.sqrt(deformed_area / np.where(area_ok, rest_area, 1.0))
        edge_scale = deformed_edge / np.where(edge_ok, rest_edge, 1.0)
    scales = np.where(area_ok & framed, area_scale, np.where(edge_ok, edge_scale, 1.0))

    # No face frame: the first incident edge's smallest rotation, or nothing.
    fallback = ~framed
    if fallback.any():
        rotations[fallback] = np.eye(3)
        first = np.full(count, -1, dtype=np.int64)
        if ends.size:
            order = np.argsort(ends[:, 0], kind="stable")
            homes = ends[order, 0]
            starts = np.flatnonzero(np.r_[True, homes[1:] != homes[:-1]])
            first[homes[starts]] = ends[order[starts], 1]
        vertices = np.flatnonzero(fallback & (first >= 0))
        if vertices.size:
            source = rest[first[vertices]] - rest[vertices]
            target = deformed[first[vertices]] - deformed[vertices]
            usable = (np.linalg.norm(source, axis=1) > 0.0) & (np.linalg.norm(target, axis=1) > 0.0)
            vertices, source, target = vertices[usable], source[usable], target[usable]
            if vertices.size:
                rotations[vertices] = _smallest_rotations(
                    _unit(source, np.ones(len(source), bool)), _unit(target, np.ones(len(target), bool))
                )
    matrices = scales[:, None, None] * rotations
    bad = ~np.all(np.isfinite(matrices), axis=(1, 2))
    matrices[bad] = np.eye(3)
    return TransferMaps(matrices, moved, fallback)


def transfer_offsets(maps: TransferMaps, offsets) -> np.ndarray:
    """(N, 3) float64 offsets on the new shape of (N, 3) ``offsets`` on the rest shape; unmoved vertices keep
    theirs exactly, a zero offset stays zero."""
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    result = offsets.copy()
    moved = maps.moved
    result[moved] = np.einsum("nij,nj->ni", maps.matrices[moved], offsets[moved])
    result[np.all(offsets == 0.0, axis=1)] = 0.0  # not -0.0 from a turned zero: the key adds nothing, bit for bit
    return result


class ShapeKeys(NamedTuple):
    """A layout's shape keys as arrays (Blender's order: the reference key is usually first)."""

    names: tuple  # (K,) key names, for messages
    positions: np.ndarray  # (K, N, 3) float32 local positions of every key
    relative: np.ndarray  # (K,) int64: the index of the key each key is relative to
    reference: int  # the index of the reference key (the basis)


def check_keys(keys: ShapeKeys, layout_name: str) -> None:
    """Raise :class:`LayoutError` naming the first key and vertex with a coordinate the add-on's input policy
    refuses on a vertex (``core.input_policy``): NaN or infinite, or beyond its absolute limit (an infinity
    typed into a field is stored as 3.4e38)."""
    finite = np.isfinite(keys.positions).all(axis=2)
    if not finite.all():
        key, vertex = (int(value) for value in np.argwhere(~finite)[0])
        raise LayoutError(
            f"Layout '{layout_name}': shape key '{keys.names[key]}' has a NaN or infinite coordinate at vertex "
            f"{vertex}: fix or remove that key (its offsets cannot be carried over)"
        )
    far = np.abs(keys.positions).max(axis=2) > input_policy.ABSOLUTE_LIMIT
    if far.any():
        key, vertex = (int(value) for value in np.argwhere(far)[0])
        raise LayoutError(
            f"Layout '{layout_name}': shape key '{keys.names[key]}' has a coordinate beyond "
            f"{input_policy.ABSOLUTE_LIMIT:g} at vertex {vertex} (an infinity typed into a Blender field is stored "
            "as 3.4e38): fix or remove that key (its offsets cannot be carried over)"
        )


def key_order(keys: ShapeKeys) -> list[tuple[int, int]]:
    """(key, the key its offsets are taken from) for every key but the reference, each after the key it needs.

    A key relative to itself, to a key out of range or in a cycle of relative keys is taken relative to the
    reference key (Blender shows such a key relative to nothing; its shape is kept against the basis).
    """
    count = len(keys.names)
    parents = {}
    for key in range(count):
        if key == keys.reference:
            continue
        parent = int(keys.relative[key])
        parents[key] = parent if 0 <= parent < count and parent != key else keys.reference
    order, placed = [], {keys.reference}
    for key in range(count):
        chain, current = [], key
        while current not in placed and current not in chain:
            chain.append(current)
            current = parents[current]
        if current in chain:  # a cycle: break it at the reference
            parents[current] = keys.reference
            chain = chain[: chain.index(current) + 1]
        for item in reversed(chain):
            order.append((item, parents[item]))
            placed.add(item)
    return order


def carry_keys(keys: ShapeKeys, new_basis, face_corners, face_sizes, edges) -> np.ndarray:
    """(K, N, 3) float32 key positions after the basis became ``new_basis`` ((N, 3) local).

    The reference key becomes ``new_basis``; every other key becomes the new position of the key it is
    relative to plus its own offset from that key, carried by :func:`transfer_maps` from the old basis
    to the new.
    """
    rest = keys.positions[keys.reference].astype(np.float64)
    new_basis = np.asarray(new_basis, dtype=np.float32).reshape(rest.shape).astype(np.float64)
    maps = transfer_maps(rest, new_basis, face_corners, face_sizes, edges)
    carried = np.empty(keys.positions.shape, dtype=np.float64)
    carried[keys.reference] = new_basis
    for key, parent in key_order(keys):
        offsets = keys.positions[key].astype(np.float64) - keys.positions[parent].astype(np.float64)
        carried[key] = carried[parent] + transfer_offsets(maps, offsets)
    return carried.astype(np.float32)


def follow_keys(keys: ShapeKeys, new_basis) -> np.ndarray:
    """(K, N, 3) float32 key positions moved along with the basis, offsets unchanged: a live wrap's frames
    (cheap; the finished wrap carries the keys with :func:`carry_keys` from the keys as they were)."""
    rest = keys.positions[keys.reference].astype(np.float64)
    shift = np.asarray(new_basis, dtype=np.float64).reshape(rest.shape) - rest
    moved = keys.positions.astype(np.float64) + shift[None]
    moved[keys.reference] = np.asarray(new_basis, dtype=np.float64).reshape(rest.shape)
    return moved.astype(np.float32)
