"""The add-on's one input policy: which coordinates an operation accepts (no ``bpy``).

Every operator's common opening (``operators.base``) runs these checks on what the operation reads —
the layout's vertices, its anchors' target points, its curve constraints' polylines, a mirror plane,
a 3D cursor or typed location, the target's own vertices — before anything is computed or written,
and reports the first problem as an error. A coordinate is refused when it is

- not finite (NaN, infinity), or
- beyond :data:`ABSOLUTE_LIMIT` from the world origin: Blender stores an ``inf`` typed into a
  property as FLT_MAX (3.4e38), and float32 keeps no usable precision that far out anyway; or
- farther from the centre of the target's bounding box than :data:`RELATIVE_LIMIT` times the
  target's bounding-box diagonal (when the operation has a target): a layout vertex or an anchor
  1e30 away is a typo or broken data, and would make the kernel's searches and the wrap's steps
  take minutes instead of milliseconds.

The messages name the item (vertex, anchor, curve constraint point, plane) and say what to do.

Numbers the user sets (every float setting of every operator, checked by ``operators.base`` before the
operator runs; the command line's numbers, by ``blender_scripts/headless.finite_number``) must be finite:
:func:`setting_problem`. Vertex-group weights and shape-key coordinates a wrap reads follow the same rules
(``blender.layout.read_layout_group``, ``core.shape_transfer.check_keys``).
"""

from typing import NamedTuple

import numpy as np

from .errors import LayoutError

ABSOLUTE_LIMIT = 1e9
"""Largest distance from the world origin a coordinate may have (world units)."""

RELATIVE_LIMIT = 1e3
"""Largest distance from the target's bounding-box centre, in target bounding-box diagonals."""


class Extent(NamedTuple):
    """Where the target is: its bounding-box centre and diagonal (world space, float64)."""

    name: str  # the target object's name, for the messages
    centre: np.ndarray  # (3,) float64
    diagonal: float

    @property
    def reach(self) -> float:
        """Farthest distance from :attr:`centre` a coordinate may have."""
        return RELATIVE_LIMIT * max(self.diagonal, np.finfo(np.float32).tiny)


def extent_of(name: str, bounding_box_min, bounding_box_max) -> Extent:
    """The :class:`Extent` of a target from its bounding box."""
    low = np.asarray(bounding_box_min, dtype=np.float64).reshape(3)
    high = np.asarray(bounding_box_max, dtype=np.float64).reshape(3)
    return Extent(name, 0.5 * (low + high), float(np.linalg.norm(high - low)))


def _format_point(point) -> str:
    return "(" + ", ".join(f"{float(value):.4g}" for value in np.asarray(point).reshape(-1)) + ")"


def _more(count: int) -> str:
    return f" ({count} such)" if count > 1 else ""


def check_points(points, describe, extent: Extent | None = None, fix: str = "") -> None:
    """Raise :class:`LayoutError` for the first row of ``points`` (world space, (N, 3)) the policy refuses.

    ``describe(row)`` names a row (``"Layout vertex 7"``, ``"Anchor 2 (vertex 40)"``); ``extent`` is the
    target's (None: no target, only finiteness and :data:`ABSOLUTE_LIMIT` apply); ``fix`` ends the
    message (what the user can do).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not points.shape[0]:
        return
    ending = f": {fix}" if fix else ""
    finite = np.all(np.isfinite(points), axis=1)
    bad = np.flatnonzero(~finite)
    if bad.size:
        raise LayoutError(f"{describe(int(bad[0]))} has a NaN or infinite coordinate{_more(bad.size)}{ending}")
    far = np.flatnonzero(np.abs(points).max(axis=1) > ABSOLUTE_LIMIT)
    if far.size:
        row = int(far[0])
        raise LayoutError(
            f"{describe(row)} is at {_format_point(points[row])}, beyond {ABSOLUTE_LIMIT:g} from the world origin"
            f"{_more(far.size)} (an infinity typed into a Blender field is stored as 3.4e38){ending}"
        )
    if extent is None:
        return
    distances = np.linalg.norm(points - extent.centre, axis=1)
    absurd = np.flatnonzero(distances > extent.reach)
    if absurd.size:
        row = int(absurd[0])
        raise LayoutError(
            f"{describe(row)} is at {_format_point(points[row])}, {distances[row]:.3g} from the centre of target "
            f"'{extent.name}', more than {RELATIVE_LIMIT:g} times the target's size ({extent.diagonal:.3g}): "
            f"an absurd coordinate{_more(absurd.size)}{ending}"
        )


def check_layout_points(layout_name: str, world_positions, extent: Extent | None = None) -> None:
    """The policy for a layout's vertices (world space)."""
    check_points(
        world_positions,
        lambda row: f"Layout vertex {row}",
        extent,
        f"fix layout '{layout_name}' (Mesh › Clean Up, or undo the edit that broke it)",
    )


def check_anchor_points(vertex_indices, locations, extent: Extent | None = None) -> None:
    """The policy for anchors' target points (world space), in list order."""
    vertex_indices = np.asarray(vertex_indices).reshape(-1)
    check_points(
        locations,
        lambda row: f"Anchor {row} (vertex {int(vertex_indices[row])})",
        extent,
        "remove that anchor, or set its target location",
    )


def check_curve_points(constraints, extent: Extent | None = None) -> None:
    """The policy for the cached target polylines of curve constraints (``curves.CurveConstraint``, world)."""
    for number, constraint in enumerate(constraints):
        check_points(
            constraint.points,
            lambda row, number=number: f"Curve constraint {number}'s target point {row}",
            extent,
            "remove that constraint, or fix its curve",
        )


def check_location(location, what: str, extent: Extent | None = None) -> np.ndarray:
    """A single point the user gave (the 3D cursor, a typed location) as a (3,) float64 array, checked."""
    point = np.asarray(location, dtype=np.float64).reshape(-1)
    if point.shape != (3,):
        raise LayoutError(f"{what} must be three numbers, not {point.size}")
    check_points(point, lambda _row: what, extent)
    return point


def check_plane(point, normal, owner: str, extent: Extent | None = None) -> None:
    """The policy for a mirror or hold plane (world space): a sane point and a finite, non-zero normal."""
    check_points(point, lambda _row: f"The plane of '{owner}'", extent, f"fix the transform of '{owner}'")
    normal = np.asarray(normal, dtype=np.float64).reshape(-1)
    if normal.shape != (3,) or not np.all(np.isfinite(normal)) or not np.any(normal):
        raise LayoutError(f"The plane of '{owner}' has no direction (its transform is not finite or has zero scale)")


def setting_problem(label: str, value) -> str | None:
    """Why a number the user set (an operator's setting: a distance, a spacing, a length, a weight; each value
    of a vector) is refused, or None: it must be finite. NaN is never "unlimited" or "automatic"; the settings
    that have such a value say which (0), and an infinity typed into a field is stored as 3.4e38 (finite)."""
    values = np.asarray(value, dtype=np.float64).reshape(-1)
    if np.all(np.isfinite(values)):
        return None
    shown = ", ".join(f"{float(item):g}" for item in values)
    return f"{label} must be a finite number, not {shown}"


def check_settings(settings: dict) -> None:
    """Raise :class:`LayoutError` for the first of ``settings`` (label: value) :func:`setting_problem` refuses."""
    for label, value in settings.items():
        problem = setting_problem(label, value)
        if problem is not None:
            raise LayoutError(problem)


STORAGE_TOLERANCE = 1e-5
"""A layout whose float32 storage rounds its vertices by more than this fraction of the target's size is
reported (the result is rounded to what the stored coordinates can hold)."""


def storage_precision_note(layout_name: str, local_positions, matrix_world, extent: Extent | None) -> str | None:
    """What to tell the user when the layout's stored (local, float32) coordinates cannot hold a result as
    precisely as the kernel computes it: they lie far from the object's origin. None when they can.

    The computation is as precise far from the world origin as near it (the kernel's frame is centred
    on the target); what is stored is each vertex relative to its object's origin, in float32.
    """
    local = np.asarray(local_positions, dtype=np.float64).reshape(-1, 3)
    if extent is None or not local.shape[0] or not extent.diagonal > 0.0:
        return None
    largest = float(np.abs(local).max())
    if not np.isfinite(largest):
        return None
    scale = float(np.abs(np.asarray(matrix_world, dtype=np.float64).reshape(4, 4)[:3, :3]).sum(axis=1).max())
    rounding = float(np.spacing(np.float32(largest))) * scale
    if rounding <= STORAGE_TOLERANCE * extent.diagonal:
        return None
    return (
        f"Layout '{layout_name}' stores its vertices up to {largest:.3g} from its object origin: float32 keeps them "
        f"only to {rounding:.2g} ({100.0 * rounding / extent.diagonal:.2g} % of the target's size), so the result "
        "is rounded to that. Object › Set Origin › Origin to Geometry brings the origin to the mesh (full precision)"
    )
