"""The target's sharp creases: edges of its own whose flanks are flat, not a chamfer a voxel remesh cut (numpy, no
``bpy``).

A part exported sharp keeps each crease as a row of edges between two flat faces; a voxel remesh or a scan rounds
it into a band of several rows (``rounded_creases`` finds those) or cuts it into a chamfer of two parallel rows.
:func:`sharp_edges` keeps only the first kind: ``feature_lines`` pairs the layout's creases with them as exact
features.
"""

import numpy as np

from . import rounded_creases

CLEAN_SHARE = 0.8
"""The share of a target crease's edges that must have flat flanks (:func:`sharp_edges`) for it to be a sharp
crease."""


def sharp_edges(positions, triangles, crease_degrees: float) -> np.ndarray:
    """(K, 2) uint32: the target's sharp edges, those whose two triangles' normals differ by more than
    ``crease_degrees`` while the triangles' other edges bend less than a third of that (flat flanks) or are sharp
    themselves (a corner), and that have no parallel twin beside them: a crease of a part exported sharp. On a
    rounded crease (a scan's) the bend is spread over several rows of edges, none of which has flat flanks, or
    cut into a chamfer of two parallel rows (:func:`_twinned`)."""
    positions = np.asarray(positions, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if crease_degrees <= 0.0 or triangles.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.uint32)
    count = triangles.shape[0]
    keys, slot, angle, _normals, _areas = rounded_creases.edge_dihedrals(positions, triangles)
    sharp = angle > crease_degrees
    flank_ok = (angle < crease_degrees / 3.0) | sharp  # per edge: flat, or a sharp edge meeting it
    face_edges = slot.reshape(3, count).T  # each triangle's three edges
    # A triangle has flat flanks for one of its edges when its two other edges are fine.
    fine = flank_ok[face_edges]
    clean_face_edge = np.stack(
        [fine[:, [1, 2]].all(axis=1), fine[:, [2, 0]].all(axis=1), fine[:, [0, 1]].all(axis=1)], 1
    )
    clean = np.ones(keys.shape[0], dtype=bool)
    np.logical_and.at(clean, face_edges.ravel(), clean_face_edge.ravel())
    found = np.flatnonzero(sharp & clean)
    found = found[~_twinned(positions[keys[found, 0]], positions[keys[found, 1]])]
    return np.ascontiguousarray(keys[found], dtype=np.uint32)


def _twinned(starts: np.ndarray, ends: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """(S,) bool: the segments with a parallel one beside them (offset by more than a quarter of their length,
    within twice their length): the two edges of a chamfer, as a voxel remesh cuts a crease, not a sharp crease,
    whose edges only continue each other."""
    middles = (starts + ends) / 2.0
    directions = ends - starts
    lengths = np.maximum(np.linalg.norm(directions, axis=1), 1e-300)
    units = directions / lengths[:, None]
    twinned = np.zeros(starts.shape[0], dtype=bool)
    for begin in range(0, starts.shape[0], chunk):
        here = slice(begin, begin + chunk)
        offsets = middles[None, :, :] - middles[here, None, :]
        along = np.einsum("ijk,ik->ij", offsets, units[here])
        across = np.linalg.norm(offsets - along[..., None] * units[here, None, :], axis=2)
        parallel = np.abs(units[here] @ units.T) > 0.9
        near = np.linalg.norm(offsets, axis=2) < 2.0 * lengths[here, None]
        twinned[here] = np.any(parallel & near & (across > 0.25 * lengths[here, None]), axis=1)
    return twinned
