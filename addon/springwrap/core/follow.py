"""Follow, without Blender: which layout vertices a change of the target concerns, and the wrap's inputs that
re-settle only those (the others held where they are). No ``bpy``.

A vertex is concerned when its distance to the target's surface changed (measured from where it is, before
and after the change), or when it is a face-point whose point on the surface moved; the region re-settled is
those vertices grown by a few rings of layout edges, so the layout eases into the change. Every other vertex
is held by an anchor where it is (a face anchor on its face when it is a face-point) and written back exactly
as it was.
"""

import numpy as np

from . import layout_state, transforms
from .wrap_inputs import WrapInputs

CHANGE_FRACTION = 1e-5
"""A distance that changed by less than this fraction of the target's bounding-box diagonal did not change
(the float32 frame the target is held in moves points by about 1e-7 of it)."""

RINGS = 2
"""Rings of layout edges the changed vertices are grown by."""


def changed_vertices(before: np.ndarray, after: np.ndarray, moved: np.ndarray, tolerance: float) -> np.ndarray:
    """(N,) bool: vertices whose surface distance changed (``before`` → ``after``, NaN: unknown, taken as
    changed) or whose face-point moved (``moved``: how far, 0 for space-points) by more than ``tolerance``."""
    before, after = np.asarray(before, dtype=np.float64), np.asarray(after, dtype=np.float64)
    difference = np.abs(after - before)
    return ~(difference <= tolerance) | (np.asarray(moved, dtype=np.float64) > tolerance)


def grow(mask: np.ndarray, edges: np.ndarray, rings: int = RINGS) -> np.ndarray:
    """``mask`` grown by ``rings`` rings of ``edges`` ((E, 2) vertex pairs)."""
    grown = np.asarray(mask, dtype=bool).copy()
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    for _ring in range(int(rings)):
        touched = grown[edges[:, 0]] | grown[edges[:, 1]]
        if not touched.any():
            break
        grown[edges[touched].reshape(-1)] = True
    return grown


def held(inputs: WrapInputs, region: np.ndarray) -> WrapInputs:
    """``inputs`` with every vertex outside ``region`` held where it starts (the layout's own anchors kept):
    a face anchor on its face for a face-point, a space anchor at its position for a space-point; and the
    springs resting in the layout's shape as it is."""
    region = np.asarray(region, dtype=bool)
    anchored = np.zeros(region.shape[0], dtype=bool)
    anchored[inputs.anchor_vertices.astype(np.int64)] = True
    vertices = np.flatnonzero(~region & ~anchored)
    on_face = inputs.states[vertices] == layout_state.FACE_POINT
    triangles = np.where(on_face, inputs.triangles[vertices], layout_state.NO_FACE).astype(np.int32)
    barycentrics = np.where(on_face[:, None], inputs.barycentrics[vertices], 0.0)
    return inputs._replace(
        anchor_vertices=np.ascontiguousarray(np.concatenate([inputs.anchor_vertices, vertices]), dtype=np.uint32),
        anchor_triangles=np.ascontiguousarray(np.concatenate([inputs.anchor_triangles, triangles]), dtype=np.int32),
        anchor_barycentrics=transforms.as_float32_points(np.concatenate([inputs.anchor_barycentrics, barycentrics])),
        anchor_positions=transforms.as_float32_points(
            np.concatenate([inputs.anchor_positions, inputs.positions[vertices]])
        ),
        rest_positions=inputs.positions,
    )


def merged(settled: np.ndarray, before: np.ndarray, region: np.ndarray) -> np.ndarray:
    """The settled positions inside ``region`` and the positions as they were (bit for bit) outside it."""
    result = np.array(before, dtype=np.float32, copy=True)
    region = np.asarray(region, dtype=bool)
    result[region] = np.asarray(settled, dtype=np.float32)[region]
    return result
