"""The target mesh as the operations see it, and the deleted-face rule applied through it (no ``bpy``).

``blender.target`` builds a :class:`Target` from the evaluated target object; everything here works
on it with the kernel's queries.
"""

from typing import Any, NamedTuple

import numpy as np

from . import layout_state, transforms
from .layout_state import LayoutArrays, LayoutState


class Target(NamedTuple):
    """A target mesh prepared for queries, in world space."""

    name: str  # the target object's name
    mesh: Any  # springwrap_kernel.TargetMesh
    triangle_polygons: np.ndarray  # (M,) int32, the polygon of each loop triangle
    signature: str  # topology signature, see layout_state.target_signature
    reattach_tolerance: float  # see layout_state.reattach_tolerance


def resolve_topology(layout: LayoutArrays, target: Target, stored_signature: str) -> layout_state.Resolution:
    """Re-attach or detach the face-points whose face may be gone (paper section 2.1).

    Applies to the whole layout, whatever the selection: when the target's topology changed
    since the face-points were written (or a face index is out of range), each face-point is
    looked up on the current surface at its current position.
    """
    mask = layout_state.face_points_to_resolve(
        layout.state, target.mesh.triangle_count, stored_signature, target.signature
    )
    if not mask.any():
        return layout_state.Resolution(layout.state, 0, 0)
    layout_state.check_finite(layout, mask)
    return resolve_points(layout.state, mask, transforms.world_positions(layout)[mask], target)


def resolve_points(
    state: LayoutState, mask: np.ndarray, world_points: np.ndarray, target: Target
) -> layout_state.Resolution:
    """The deleted-face rule for the face-points in ``mask``, looked up at ``world_points`` (mask order).

    Each is found again on the current target surface (the exact closest point): within the
    target's re-attach tolerance it re-attaches there, otherwise it becomes a space-point. Used
    for layout vertices (at their positions) and for anchors (at their cached target points).
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return layout_state.Resolution(state, 0, 0)
    hits = target.mesh.closest_points(transforms.as_float32_points(world_points))
    return layout_state.resolve_face_points(
        state, mask, hits.triangles, hits.barycentrics, hits.distances, target.reattach_tolerance
    )
