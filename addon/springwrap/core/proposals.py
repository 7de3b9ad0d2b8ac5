"""Correspondence proposals on arrays (numpy and the kernel, no ``bpy``).

From the pairs placed by hand (or accepted) and the layout's current fit, the kernel
(``springwrap_kernel.propose_correspondences``) proposes further pairs where both shapes say where a point goes:
tips and pits of the layout's rest shape matched to those of the target. They are stored as anchors flagged
*proposed*, with their confidence; a wrap leaves them out until they are accepted (:func:`accept`), and
:func:`reject` removes them. ``accept=True`` in :func:`propose` stores them accepted at once (the command line's
``--propose-anchors``).
"""

import numpy as np

import springwrap_kernel

from . import layout_state, transforms
from .anchors import (
    FACE_ANCHOR,
    AnchorOutcome,
    Anchors,
    anchor_count,
    concatenate,
    make_anchors,
    resolve,
    take,
)
from .errors import LayoutError
from .layout_state import LayoutArrays
from .target import Target

DEFAULTS = springwrap_kernel.proposal_defaults()
"""The kernel's defaults: ``max_count``, ``min_confidence``, ``search_radius``, ``feature_scale``, ``min_anchors``."""


def propose(
    layout: LayoutArrays,
    rest: np.ndarray,
    face_corners: np.ndarray,
    face_sizes: np.ndarray,
    existing: Anchors,
    target: Target,
    stored_signature: str,
    max_count: int = DEFAULTS["max_count"],
    min_confidence: float = DEFAULTS["min_confidence"],
    search_radius: float = DEFAULTS["search_radius"],
    feature_scale: float = DEFAULTS["feature_scale"],
    accept: bool = False,
) -> AnchorOutcome:
    """The anchors with new proposed pairs added (the previous, un-accepted proposals replaced).

    ``rest``: the layout's rest shape (local (N, 3)); ``face_corners``/``face_sizes``: its faces. The pairs
    placed by hand or accepted are the starting anchors (at least ``DEFAULTS['min_anchors']``); their vertices
    get no proposal. Raises :class:`LayoutError` with too few of them, the kernel's errors for bad input.
    """
    anchors, resolution = resolve(existing, target, stored_signature)
    given = used_by_wrap(anchors)
    needed = int(DEFAULTS["min_anchors"])
    if anchor_count(given) < needed:
        raise LayoutError(
            f"Propose Anchors starts from the pairs placed by hand: place at least {needed} anchors on distinct "
            f"vertices first ({anchor_count(given)} now)"
        )
    layout_state.check_finite(layout, np.ones(layout.positions.shape[0], dtype=bool))
    world = transforms.world_positions(layout)
    mesh = target.mesh
    found = springwrap_kernel.propose_correspondences(
        mesh.kernel,
        transforms.as_float32_points(rest),
        mesh.to_kernel(world),
        np.ascontiguousarray(face_corners, dtype=np.uint32),
        np.ascontiguousarray(face_sizes, dtype=np.uint32),
        np.ascontiguousarray(given.vertex_indices, dtype=np.uint32),
        mesh.to_kernel(given.locations),
        max_count=int(max_count),
        min_confidence=float(min_confidence),
        search_radius=float(search_radius),
        feature_scale=float(feature_scale),
    )
    count = found.vertices.shape[0]
    new = make_anchors(
        found.vertices.astype(np.int32),
        np.full(count, FACE_ANCHOR),
        found.triangles.astype(np.int32),
        found.barycentric,
        mesh.from_kernel(found.positions),
        proposed=np.full(count, not accept),
        confidences=found.confidences,
    )
    result = concatenate(given, new)
    return AnchorOutcome(
        anchors=result,
        active_index=-1,
        added_count=count,
        replaced_count=anchor_count(anchors) - anchor_count(given),
        topology_detached_count=resolution.detached_count,
        topology_reattached_count=resolution.reattached_count,
    )


def used_by_wrap(anchors: Anchors) -> Anchors:
    """The anchors a wrap pulls by (and Align fits, and the cage fit holds): all but the proposed pairs not yet
    accepted."""
    return take(anchors, ~np.asarray(anchors.proposed, dtype=bool))


def _chosen(anchors: Anchors, index: int) -> np.ndarray:
    """(K,) bool: the proposed pair at ``index`` (-1: every proposed pair); :class:`LayoutError` when there is none."""
    proposed = np.asarray(anchors.proposed, dtype=bool)
    if index < 0:
        if not proposed.any():
            raise LayoutError("The layout has no proposed pairs (Propose Anchors makes them)")
        return proposed
    if index >= anchor_count(anchors):
        raise LayoutError(f"There is no anchor {index} (the layout has {anchor_count(anchors)})")
    if not proposed[index]:
        raise LayoutError(f"Anchor {index} (vertex {int(anchors.vertex_indices[index])}) is not a proposed pair")
    chosen = np.zeros_like(proposed)
    chosen[index] = True
    return chosen


def accept(anchors: Anchors, index: int = -1) -> tuple[Anchors, int]:
    """The anchors with the proposed pair at ``index`` (-1: all) accepted (the wrap uses it: a soft pair with the energy solver); how many."""
    chosen = _chosen(anchors, index)
    return anchors._replace(proposed=np.asarray(anchors.proposed, dtype=bool) & ~chosen), int(chosen.sum())


def reject(anchors: Anchors, index: int = -1) -> tuple[Anchors, int]:
    """The anchors without the proposed pair at ``index`` (-1: all); how many were removed."""
    chosen = _chosen(anchors, index)
    return take(anchors, ~chosen), int(chosen.sum())
