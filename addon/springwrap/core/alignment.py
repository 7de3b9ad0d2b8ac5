"""Alignment on arrays (paper section 2.2): numpy and the kernel, no ``bpy``.

A template is brought into place before it is attached: a transform fitted to the anchors (each
anchor pairs a layout vertex with a target point) by least squares, then optionally refined by
ICP against the target surface. Everything is in world space: the result is one 4x4 matrix ``M``
that takes the layout's current world positions to their aligned ones. The operator applies it to
the layout object's transform (``new matrix_world = M @ matrix_world``) or bakes it into the
vertices (``new local = matrix_world⁻¹ @ M @ matrix_world @ local``).

Nothing is written here; the functions check everything and return the complete result.
"""

from typing import Any, NamedTuple

import numpy as np

import springwrap_kernel

from . import anchors as anchor_arrays
from . import layout_state, transforms
from .errors import LayoutError
from .layout_state import LayoutArrays
from .target import Target

METHODS = ("RIGID", "SIMILARITY", "AFFINE")
"""Transforms fitted to the anchors: rotation + translation, + uniform scale, or any affine map."""
MIN_ANCHORS = {"RIGID": 3, "SIMILARITY": 3, "AFFINE": 4}
"""Anchors each method needs (not all on one line; for AFFINE not all in one plane)."""
ICP_UPDATE = {"RIGID": "RIGID", "SIMILARITY": "SIMILARITY", "AFFINE": "SIMILARITY"}
"""The ICP step that refines each method's fit (an affine fit is refined by similarity steps)."""
APPLY_MODES = ("OBJECT", "BAKE")
"""Where the transform goes: the layout object's transform, or the mesh's vertices."""
SHEAR_TOLERANCE = 1e-5
"""An object transform holds rotation and per-axis scale only: columns of its linear part must be
orthogonal to this relative tolerance, else the operator asks to bake instead."""


class AlignParameters(NamedTuple):
    method: str  # one of METHODS
    use_anchors: bool  # fit to the anchors (else start from the current placement)
    use_icp: bool  # refine by ICP against the target
    icp_iterations: int
    trim_fraction: float  # fraction of the farthest pairs ICP ignores each iteration, [0, 1)
    max_distance: float  # ICP ignores pairs farther apart than this (world units); 0: no limit
    only_selected: bool  # ICP uses the selected layout vertices only
    anchor_weight: float = 0.3  # ICP keeps the anchors: their share of the fit (0: ICP ignores them)


class AlignOutcome(NamedTuple):
    """The alignment found, and what to report."""

    matrix: np.ndarray  # (4, 4) float64 world-space transform applied to the layout
    anchor_count: int  # anchors the fit used (0 without use_anchors)
    anchor_rms_before: float  # RMS distance layout vertex -> anchor target, before (world units)
    anchor_rms_after: float  # the same after the whole alignment
    icp: Any | None  # springwrap_kernel.IcpReport, None without ICP
    icp_point_count: int  # layout vertices fed to ICP


def check_parameters(parameters: AlignParameters) -> None:
    """Raise :class:`LayoutError` for parameters no alignment can use."""
    if parameters.method not in METHODS:
        raise LayoutError(f"Unknown alignment method {parameters.method!r}; expected one of {', '.join(METHODS)}")
    if not (parameters.use_anchors or parameters.use_icp):
        raise LayoutError("Nothing to do: enable the anchor fit, ICP, or both")
    if parameters.use_icp:
        if parameters.icp_iterations < 1:
            raise LayoutError(f"ICP needs at least 1 iteration, got {parameters.icp_iterations}")
        if not 0.0 <= parameters.trim_fraction < 1.0:
            raise LayoutError(f"The ICP trim fraction must be in [0, 1), got {parameters.trim_fraction}")
        if not (np.isfinite(parameters.max_distance) and parameters.max_distance >= 0.0):
            raise LayoutError(f"The ICP max distance must be 0 (no limit) or positive, got {parameters.max_distance}")
        if not (np.isfinite(parameters.anchor_weight) and parameters.anchor_weight >= 0.0):
            raise LayoutError(f"The ICP anchor weight must be 0 or positive, got {parameters.anchor_weight}")


def anchor_pairs(
    anchor_list: anchor_arrays.Anchors, world_points: np.ndarray, method: str
) -> tuple[np.ndarray, np.ndarray]:
    """(source, target) world points of the anchors: layout vertex -> anchor target.

    Raises :class:`LayoutError` when an anchor names a vertex the layout no longer has (as the wrap
    does), when there are fewer than the method needs, or a location is not finite.
    """
    anchor_arrays.check_anchor_vertices(anchor_list, world_points.shape[0])
    needed = MIN_ANCHORS[method]
    count = anchor_arrays.anchor_count(anchor_list)
    if count < needed:
        extra = " not all in one plane" if method == "AFFINE" else " not all on one line"
        raise LayoutError(
            f"{method.title()} alignment needs at least {needed} anchors{extra}; the layout has {count}. "
            "Add anchors (Springwrap > Anchors) or align by ICP alone"
        )
    anchor_arrays.check_anchor_locations(anchor_list)
    source = world_points[np.asarray(anchor_list.vertex_indices, dtype=np.int64)]
    target = np.asarray(anchor_list.locations, dtype=np.float64)
    return source, target


def rms_distance(first: np.ndarray, second: np.ndarray) -> float:
    """Root-mean-square distance between paired rows; 0 for none."""
    if len(first) == 0:
        return 0.0
    return float(np.sqrt(np.mean(np.sum((np.asarray(first) - np.asarray(second)) ** 2, axis=1))))


def align(
    layout: LayoutArrays,
    anchor_list: anchor_arrays.Anchors,
    target: Target,
    parameters: AlignParameters,
) -> AlignOutcome:
    """The world-space transform that aligns the layout: anchor fit, then ICP (as ``parameters`` say).

    Raises :class:`LayoutError` or a kernel error (too few, coincident, collinear or coplanar
    anchors; non-finite input) before anything is written.
    """
    check_parameters(parameters)
    everything = np.ones(layout.positions.shape[0], dtype=bool)
    layout_state.check_finite(layout, everything)
    world = transforms.world_positions(layout)

    matrix = np.eye(4)
    source = target_points = np.empty((0, 3))
    if parameters.use_anchors:
        source, target_points = anchor_pairs(anchor_list, world, parameters.method)
        # Fitted in the target's frame (float32 keeps the precision far from the origin), mapped back.
        matrix = target.mesh.matrix_from_kernel(
            np.asarray(
                springwrap_kernel.fit_transform(
                    target.mesh.to_kernel(source), target.mesh.to_kernel(target_points), parameters.method
                ),
                dtype=np.float64,
            )
        )

    report = None
    icp_points = 0
    if parameters.use_icp:
        mask = layout_state.operation_mask(layout, parameters.only_selected)
        icp_points = int(mask.sum())
        if icp_points < 3:
            raise LayoutError(f"ICP needs at least 3 layout vertices; {icp_points} are selected")
        options = {}
        if parameters.max_distance > 0.0:
            options["max_distance"] = float(parameters.max_distance)
        if len(source) and parameters.anchor_weight > 0.0:
            options["anchor_source"] = source
            options["anchor_target"] = target_points
            options["anchor_weight"] = float(parameters.anchor_weight)
        report = target.mesh.icp(
            world[mask],
            np.ascontiguousarray(matrix, dtype=np.float64),
            update=ICP_UPDATE[parameters.method],
            max_iterations=int(parameters.icp_iterations),
            trim_fraction=float(parameters.trim_fraction),
            **options,
        )
        matrix = np.asarray(report.matrix, dtype=np.float64)

    if not np.all(np.isfinite(matrix)) or not transforms.is_invertible(matrix):
        raise LayoutError("The alignment found no usable transform (it collapses or is not finite)")
    return AlignOutcome(
        matrix=matrix,
        anchor_count=len(source),
        anchor_rms_before=rms_distance(source, target_points),
        anchor_rms_after=rms_distance(transforms.transform_points(matrix, source), target_points),
        icp=report,
        icp_point_count=icp_points,
    )


def baked_positions(layout: LayoutArrays, matrix: np.ndarray) -> np.ndarray:
    """(N, 3) float32 local positions of the layout with the world transform ``matrix`` baked in."""
    world = transforms.transform_points(matrix, transforms.world_positions(layout))
    return transforms.to_local(layout.matrix_world, world)


def object_basis(matrix: np.ndarray, matrix_world: np.ndarray, parent_matrix: np.ndarray) -> np.ndarray:
    """The object's new local matrix (``matrix_basis``) for the aligned transform ``matrix @ matrix_world``.

    ``parent_matrix`` maps the object's basis to world space (``matrix_world @ matrix_basis⁻¹``:
    the parent's world matrix times the parent inverse, identity without a parent). Raises
    :class:`LayoutError` when the basis would need a shear, which location / rotation / scale
    cannot hold (an affine fit, or a rotation under a non-uniformly scaled parent).
    """
    if not transforms.is_invertible(parent_matrix):
        raise LayoutError("The layout's parent has zero scale: bake the alignment into the vertices instead")
    new_world = np.asarray(matrix, dtype=np.float64) @ np.asarray(matrix_world, dtype=np.float64)
    basis = transforms.inverse_matrix(parent_matrix) @ new_world
    columns = basis[:3, :3]
    lengths = np.linalg.norm(columns, axis=0)
    if np.any(lengths <= 0.0) or not np.all(np.isfinite(lengths)):
        raise LayoutError("The aligned object transform has zero scale")
    unit = columns / lengths
    gram = unit.T @ unit
    if np.max(np.abs(gram - np.eye(3))) > SHEAR_TOLERANCE:
        raise LayoutError(
            "The alignment shears the layout, which an object transform (location, rotation, scale) cannot "
            "hold: choose Apply: Bake into Vertices"
        )
    return basis


def scale_factor(matrix: np.ndarray) -> float:
    """The mean scale of a transform's linear part (cube root of its determinant's magnitude)."""
    return float(abs(np.linalg.det(np.asarray(matrix, dtype=np.float64)[:3, :3])) ** (1.0 / 3.0))


def rotation_degrees(matrix: np.ndarray) -> float:
    """The angle (degrees) of the rotation nearest to a transform's linear part."""
    linear = np.asarray(matrix, dtype=np.float64)[:3, :3]
    u, _s, vt = np.linalg.svd(linear)
    rotation = u @ vt
    cosine = np.clip((np.trace(rotation) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.degrees(np.arccos(cosine)))


def floating_state(layout: LayoutArrays) -> layout_state.LayoutState:
    """The layout's state after alignment: every vertex a space-point (the template floats free)."""
    return layout_state.space_state(layout.positions.shape[0])


def detached_count(layout: LayoutArrays) -> int:
    """Face-points that alignment turns into space-points."""
    return layout_state.point_counts(layout.state.states)[0]


def summary(
    name: str, parameters: AlignParameters, outcome: AlignOutcome, detached: int, apply: str, milliseconds: float
) -> str:
    """The report of a finished alignment."""
    parts = [f"Aligned '{name}'"]
    if outcome.anchor_count:
        parts.append(
            f"{parameters.method.lower()} fit to {outcome.anchor_count} anchors "
            f"(RMS {outcome.anchor_rms_before:.4g} -> {outcome.anchor_rms_after:.4g})"
        )
    if outcome.icp is not None:
        state = "converged" if outcome.icp.converged else "not converged"
        parts.append(
            f"ICP on {outcome.icp_point_count} points, {outcome.icp.iterations} iterations, {state} "
            f"(RMS {outcome.icp.rms_before:.4g} -> {outcome.icp.rms_after:.4g}, {outcome.icp.pairs_used} pairs)"
        )
    parts.append(
        f"rotation {rotation_degrees(outcome.matrix):.2f} deg, scale {scale_factor(outcome.matrix):.4g}, "
        f"{'object transform' if apply == 'OBJECT' else 'baked into vertices'}"
    )
    if detached:
        parts.append(f"{detached} face-points detached")
    return "; ".join(parts) + f" ({milliseconds:.0f} ms)"
