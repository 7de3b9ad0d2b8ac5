"""The wrap's inputs on arrays (paper, section 2.5): parameters, checks, anchors, unreliable triangles,
the rest shape, the fine stage of a spring resolution above 1, and the kernel's ``WrapSolver`` built from them.
Numpy and the kernel, no ``bpy``.
"""

from typing import Any, NamedTuple

import numpy as np

import springwrap_kernel

from . import curves, defaults, input_policy, layout_state, transforms
from .anchors import anchor_count, check_anchor_vertices, take
from .errors import LayoutError
from .layout_state import LayoutArrays, check_finite
from .subdivision import MAX_RESOLUTION
from .target import Target, resolve_topology
from .transforms import world_positions

COLLAPSED_EDGE = 1e-6
"""An edge shorter than this fraction of the layout's mean edge length has collapsed (a rest shape refuses it)."""


NEUTRAL_STIFFNESS = 0.5
"""The stiffness of a layout vertex outside the Stiffness group: the wrap's own balance."""


def group_stiffness(weights: np.ndarray, in_group: np.ndarray) -> np.ndarray:
    """(N,) float32 per-vertex stiffness: the group's weight (0 follows the target freely … 1 keeps the template's
    shape) on its vertices, :data:`NEUTRAL_STIFFNESS` elsewhere."""
    weights = np.clip(np.asarray(weights, dtype=np.float32), 0.0, 1.0)
    return np.where(np.asarray(in_group, dtype=bool), weights, np.float32(NEUTRAL_STIFFNESS)).astype(np.float32)


def check_rest_edges(positions: np.ndarray, edges: np.ndarray) -> None:
    """Raise :class:`~.errors.LayoutError` when an edge of ``positions`` has collapsed to (nearly) zero
    length: a rest shape must give every edge a length, or the wrap cannot keep it (a snap to the target's
    vertices or closed lips put two vertices on one point)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if edges.size == 0:
        return
    positions = np.asarray(positions, dtype=np.float64)
    lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    positive = lengths[lengths > 0.0]
    limit = COLLAPSED_EDGE * float(positive.mean()) if positive.size else 0.0
    collapsed = np.flatnonzero(lengths <= limit)
    if collapsed.size:
        a, b = (int(vertex) for vertex in edges[collapsed[0]])
        raise LayoutError(
            f"The edge between layout vertices {a} and {b} has zero length ({collapsed.size} such edges, e.g. "
            "where a snap put two vertices on one point): move them apart, or set the rest shape before snapping"
        )


UNRELIABLE_WEIGHT = 0.5
"""A target triangle is unreliable when all three corners weigh more than this in the unreliable group."""


class WrapParameters(NamedTuple):
    """What the user sets for a wrap: the iteration limit, the spring resolution and the kernel's settings."""

    max_iterations: int = defaults.MAX_ITERATIONS
    settings: Any = None  # springwrap_kernel.WrapSettings (weights, tolerance, schedule); None: the kernel's defaults
    spring_resolution: int = (
        defaults.SPRING_RESOLUTION
    )  # > 1: relax, then relax again the faces cut k x k (coarse to fine)
    stiffness_group: str = ""  # layout vertex group of per-vertex stiffness; "": the layout's setting
    free_group: str = ""  # layout vertex group of vertices without a pull to the target; "": the layout's setting


class WrapInputs(NamedTuple):
    """Everything the kernel's ``WrapSolver`` takes besides the target and the layout structure.

    Coordinates are in the kernel's frame: world minus ``origin``, the centre of the target's
    bounding box (``target.CentredMesh``), so that float32 keeps the precision far from the world
    origin. Add ``origin`` back (in float64) to get world coordinates.
    """

    states: np.ndarray  # (N,) int32 1 face-point, 0 space-point
    triangles: np.ndarray  # (N,) int32 face-point triangle, -1 for space-points
    barycentrics: np.ndarray  # (N, 3) float32
    positions: np.ndarray  # (N, 3) float32 positions, kernel frame (used for space-points)
    anchor_vertices: np.ndarray  # (A,) uint32
    anchor_triangles: np.ndarray  # (A,) int32, -1 for a space anchor
    anchor_barycentrics: np.ndarray  # (A, 3) float32
    anchor_positions: np.ndarray  # (A, 3) float32 target points, kernel frame
    unreliable_triangles: np.ndarray | None  # (M,) bool, or None when no group is set
    curve_vertices: np.ndarray | None = None  # (sum C,) uint32 chains one after another; None: no curves
    curve_vertex_counts: np.ndarray | None = None  # (K,) uint32 vertices per chain
    curve_points: np.ndarray | None = None  # (sum P, 3) float32 target polylines one after another, kernel frame
    curve_point_counts: np.ndarray | None = None  # (K,) uint32 points per polyline
    curve_fractions: np.ndarray | None = None  # (sum C,) float32 where each chain vertex goes, NaN: as spaced
    rest_positions: np.ndarray | None = None  # (N, 3) float32 template shape the wrap keeps, kernel frame
    plane_vertices: np.ndarray | None = None  # (S,) uint32 vertices held on the mirror plane; None: no plane
    plane_point: tuple | None = None  # (3,) point of the mirror plane, kernel frame
    plane_normal: tuple | None = None  # (3,) world normal of the mirror plane
    plane_slide: bool = True  # held points slide along the target's cross-section (False: only move onto it)
    stiffness: np.ndarray | None = None  # (N,) float32 per-vertex stiffness 0 … 1; None: neutral
    free_vertices: np.ndarray | None = None  # (N,) bool vertices without a data term; None: none
    soft_pair_vertices: np.ndarray | None = None  # (S,) uint32 accepted proposals as soft pairs
    soft_pair_positions: np.ndarray | None = None  # (S, 3) float32 their target points, kernel frame
    soft_pair_confidences: np.ndarray | None = None  # (S,) float32 their confidences in (0, 1]
    origin: np.ndarray = np.zeros(3)  # (3,) float64 world point the kernel frame is centred on


def to_frame(inputs: WrapInputs, world_points) -> np.ndarray:
    """(N, 3) float32 kernel-frame coordinates of world points, for ``inputs``."""
    return transforms.as_float32_points(np.asarray(world_points, dtype=np.float64).reshape(-1, 3) - inputs.origin)


def from_frame(inputs: WrapInputs, kernel_points) -> np.ndarray:
    """(N, 3) float64 world coordinates of kernel-frame points of ``inputs``."""
    return np.asarray(kernel_points, dtype=np.float64).reshape(-1, 3) + inputs.origin


def check_wrap_parameters(parameters: WrapParameters) -> None:
    """Raise :class:`~.errors.LayoutError` naming the first parameter out of its range.

    The kernel's settings were checked by the kernel when they were made (``WrapSettings(...)``).
    """
    if int(parameters.max_iterations) < 1:
        raise LayoutError(f"Max Iterations must be at least 1, not {parameters.max_iterations}")
    if not 1 <= int(parameters.spring_resolution) <= MAX_RESOLUTION:
        raise LayoutError(
            f"The spring resolution must be within 1 .. {MAX_RESOLUTION}, not {parameters.spring_resolution}"
        )


def check_wrappable(layout_name: str, face_count: int, edge_count: int) -> None:
    """Raise :class:`~.errors.LayoutError` when the layout is points alone: nothing for the springs (or the mirror,
    the fit, the read-out) to act on."""
    if face_count == 0 and edge_count == 0:
        raise LayoutError(f"Layout '{layout_name}' has no faces and no edges, only points: {POINTS_ONLY}")


def check_something_pulled(layout_name: str, free_vertices: "np.ndarray | None", free_group: str) -> None:
    """Refuse a wrap in which every vertex is in the Free group: none would be pulled onto the target, and the
    wrap would "converge" with the layout where it was."""
    if free_vertices is not None and np.asarray(free_vertices).size and np.asarray(free_vertices).all():
        raise LayoutError(
            f"Every vertex of layout '{layout_name}' is in the Free group '{free_group}' (weight above 0): none "
            "would be pulled onto the target, so the wrap would leave the layout where it is. Keep in the group "
            "only what should stay off the surface (sockets, teeth), or clear Free Group"
        )


POINTS_ONLY = (
    "wrapping, mirroring, fitting a subdivision, spreading anchors and the quality read-out need faces or edges "
    "(Snap, Project and Detach move points alone)"
)
"""What a layout of points alone can and cannot be given to."""


def unreliable_triangles(triangles: np.ndarray, vertex_weights: np.ndarray) -> np.ndarray:
    """(M,) bool: the triangles whose three corners all weigh more than :data:`UNRELIABLE_WEIGHT`.

    ``triangles`` (M, 3) vertex indices of the target, ``vertex_weights`` (V,) one weight per
    target vertex (0 for vertices outside the group).
    """
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    heavy = np.asarray(vertex_weights, dtype=np.float64).reshape(-1) > UNRELIABLE_WEIGHT
    return np.ascontiguousarray(heavy[triangles].all(axis=1), dtype=bool)


def wrap_anchor_arrays(
    anchor_list, vertex_count: int, origin=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's anchor arrays (vertices, triangles, barycentrics, positions) from an anchor list.

    ``anchor_list`` is an ``anchors.Anchors`` (resolved on the current target: face anchors have
    valid triangles, locations are current); the positions are given relative to ``origin`` (the
    kernel's frame). Raises :class:`~.errors.LayoutError` naming the anchors whose vertex the
    layout no longer has.
    """
    check_anchor_vertices(anchor_list, vertex_count)
    vertex_indices = np.asarray(anchor_list.vertex_indices, dtype=np.int64).reshape(-1)
    is_face = np.asarray(anchor_list.kinds) == layout_state.FACE_POINT
    triangles = np.where(is_face, anchor_list.triangles, layout_state.NO_FACE).astype(np.int32)
    return (
        np.ascontiguousarray(vertex_indices, dtype=np.uint32),
        np.ascontiguousarray(triangles),
        transforms.as_float32_points(anchor_list.barycentrics),
        transforms.as_float32_points(
            np.asarray(anchor_list.locations, dtype=np.float64).reshape(-1, 3) - (0.0 if origin is None else origin)
        ),
    )


def refine_wrap_inputs(inputs: WrapInputs, fine, positions: np.ndarray, states, target: Target) -> WrapInputs:
    """The solver's inputs for the fine stage of a wrap (see ``subdivision``), from where the coarse stage ended.

    ``positions`` and ``states`` (states, triangles, barycentrics) are the coarse solver's (kernel frame). The layout's
    vertices keep their state; a new point starts blended from its layout vertices and lands on the
    closest surface point when all of them are face-points and that point is within half a fine edge;
    otherwise it starts as a space-point. The rest shape is blended the same way; anchors, unreliable
    triangles and target curves are the same; each curve chain takes the points cut into its edges.
    """
    coarse_states, coarse_triangles, coarse_barycentrics = (np.asarray(array) for array in states)
    count = coarse_states.shape[0]
    fine_positions = fine.interpolate(np.asarray(positions, dtype=np.float64))
    fine_count = fine_positions.shape[0]
    on_surface = np.ones(fine_count, dtype=bool)
    for column in range(fine.sources.shape[1]):
        used = fine.weights[:, column] > 0.0
        on_surface[used] &= coarse_states[fine.sources[used, column]] == layout_state.FACE_POINT
    new = np.arange(fine_count) >= count
    fine_states = np.zeros(fine_count, dtype=np.int32)
    fine_triangles = np.full(fine_count, layout_state.NO_FACE, dtype=np.int32)
    fine_barycentrics = np.zeros((fine_count, 3), dtype=np.float32)
    fine_states[:count] = coarse_states
    fine_triangles[:count] = coarse_triangles
    fine_barycentrics[:count] = coarse_barycentrics
    candidates = np.flatnonzero(new & on_surface)
    if candidates.size:
        corners = fine.topology.face_corners.astype(np.int64)
        sizes = fine.topology.face_sizes.astype(np.int64)
        ring_next = np.roll(np.arange(corners.size), -1)
        starts = np.repeat(np.concatenate([[0], np.cumsum(sizes)[:-1]]), sizes)
        ends = starts + np.repeat(sizes, sizes)
        ring_next = np.where(ring_next == ends, starts, ring_next)
        lengths = np.linalg.norm(fine_positions[corners] - fine_positions[corners[ring_next]], axis=1)
        reach = 0.5 * float(np.median(lengths)) if lengths.size else 0.0
        hits = target.mesh.kernel.closest_points(  # kernel frame in, kernel frame out
            transforms.as_float32_points(fine_positions[candidates]), max_distance=max(reach, 1e-12)
        )
        found = hits.triangles >= 0
        landed = candidates[found]
        fine_states[landed] = layout_state.FACE_POINT
        fine_triangles[landed] = hits.triangles[found]
        fine_barycentrics[landed] = hits.barycentrics[found]
        fine_positions[landed] = hits.positions[found]
    curve_arguments = {}
    if inputs.curve_vertices is not None:
        chains, placed, offset = [], [], 0
        given = getattr(inputs, "curve_fractions", None)
        for size in inputs.curve_vertex_counts.astype(np.int64):
            chain = inputs.curve_vertices[offset : offset + size].astype(np.int64)
            chains.append(fine.expand_chain(chain))
            fractions = np.full(size, np.nan) if given is None else given[offset : offset + size]
            placed.append(_expanded_fractions(chain, chains[-1], fractions))
            offset += size
        curve_arguments = {
            "curve_vertices": np.ascontiguousarray(np.concatenate(chains), dtype=np.uint32),
            "curve_vertex_counts": np.array([len(chain) for chain in chains], dtype=np.uint32),
            "curve_fractions": None if given is None else np.ascontiguousarray(np.concatenate(placed), np.float32),
        }
    rest = (
        None if inputs.rest_positions is None else transforms.as_float32_points(fine.interpolate(inputs.rest_positions))
    )
    return inputs._replace(
        states=fine_states,
        triangles=fine_triangles,
        barycentrics=fine_barycentrics,
        positions=transforms.as_float32_points(fine_positions),
        rest_positions=rest,
        **curve_arguments,
    )


def rest_world_positions(layout: LayoutArrays, rest: np.ndarray) -> np.ndarray:
    """The stored rest shape (local, (N, 3)) in world space (float64), checked: one finite row per layout vertex."""
    rest = np.asarray(rest, dtype=np.float64)
    vertex_count = layout.positions.shape[0]
    if rest.shape != (vertex_count, 3):
        raise LayoutError(f"The stored rest shape has {rest.shape[0]} points for a layout of {vertex_count} vertices")
    bad = np.flatnonzero(~np.isfinite(rest).all(axis=1))
    if bad.size:
        raise LayoutError(f"The stored rest shape of vertex {int(bad[0])} is not finite")
    world = transforms.transform_points(layout.matrix_world, rest)
    input_policy.check_points(
        world, lambda row: f"The stored rest shape of vertex {row}", fix="press Set Rest Shape (or use Rest Shape Even)"
    )
    return world


def prepare_wrap(
    layout: LayoutArrays,
    target: Target,
    stored_signature: str,
    anchor_list,
    unreliable: np.ndarray | None,
    curve_constraints=(),
    rest: np.ndarray | None = None,
    soft_proposals: bool = False,
) -> tuple[WrapInputs, layout_state.Resolution]:
    """The solver's inputs: the layout's current state (after the deleted-face rule) and positions.

    ``anchor_list``: resolved anchors (see :func:`wrap_anchor_arrays`); with ``soft_proposals`` the accepted
    proposals among them (a confidence above 0) are soft pairs, the others anchors;
    ``unreliable``: (M,) bool
    flags of the target's triangles, or None; ``curve_constraints``: ``curves.CurveConstraint``
    with current polylines (checked by ``curves.kernel_arrays``); ``rest``: (N, 3) local template shape the
    springs rest in (None: the positions now). Every vertex must be finite in world space.
    The inputs are in the kernel's frame, centred on the target (``target.mesh.origin``).
    Returns the inputs and the topology resolution of the layout's face-points (to report).
    """
    origin = np.asarray(target.mesh.origin, dtype=np.float64)
    vertex_count = layout.positions.shape[0]
    check_finite(layout, np.ones(vertex_count, dtype=bool))
    resolution = resolve_topology(layout, target, stored_signature)
    state = resolution.state
    soft = np.zeros(anchor_count(anchor_list), dtype=bool)
    if soft_proposals:
        soft = np.asarray(anchor_list.confidences, dtype=np.float32).reshape(-1) > 0.0
    soft_list = take(anchor_list, soft)
    anchor_list = take(anchor_list, ~soft)
    anchor_vertices, anchor_triangles, anchor_barycentrics, anchor_positions = wrap_anchor_arrays(
        anchor_list, vertex_count, origin
    )
    if unreliable is not None:
        unreliable = np.ascontiguousarray(unreliable, dtype=bool).reshape(-1)
        if unreliable.shape[0] != target.mesh.triangle_count:
            raise LayoutError(
                f"{unreliable.shape[0]} unreliable-triangle flags for a target of {target.mesh.triangle_count} triangles"
            )
    anchored = np.zeros(vertex_count, dtype=bool)
    anchored[anchor_vertices] = True
    curve_arrays = curves.kernel_arrays(curve_constraints, vertex_count, anchored, origin) or (None,) * 5
    inputs = WrapInputs(
        states=np.ascontiguousarray(state.states, dtype=np.int32),
        triangles=np.ascontiguousarray(state.faces, dtype=np.int32),
        barycentrics=transforms.as_float32_points(state.barycentrics),
        positions=transforms.as_float32_points(world_positions(layout) - origin),
        anchor_vertices=anchor_vertices,
        anchor_triangles=anchor_triangles,
        anchor_barycentrics=anchor_barycentrics,
        anchor_positions=anchor_positions,
        unreliable_triangles=unreliable,
        curve_vertices=curve_arrays[0],
        curve_vertex_counts=curve_arrays[1],
        curve_points=curve_arrays[2],
        curve_point_counts=curve_arrays[3],
        curve_fractions=curve_arrays[4],
        rest_positions=None
        if rest is None
        else transforms.as_float32_points(rest_world_positions(layout, rest) - origin),
        origin=origin,
    )
    if soft.any():
        check_anchor_vertices(soft_list, vertex_count)
        inputs = inputs._replace(
            soft_pair_vertices=np.ascontiguousarray(soft_list.vertex_indices, dtype=np.uint32),
            soft_pair_positions=transforms.as_float32_points(
                np.asarray(soft_list.locations, dtype=np.float64).reshape(-1, 3) - origin
            ),
            soft_pair_confidences=np.ascontiguousarray(soft_list.confidences, dtype=np.float32),
        )
    return inputs, resolution


def _expanded_fractions(chain: np.ndarray, fine_chain: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """A chain's placements along its curve (``fractions``, one per vertex of ``chain``, NaN: none) for the chain
    with the fine points of its edges put in (``fine_chain``, ``chain``'s vertices among them in order): each fine
    point between two of the chain's vertices evenly between their fractions."""
    rows = np.flatnonzero(np.isin(fine_chain, chain))  # the fine points are new vertices, never the chain's
    return np.interp(np.arange(fine_chain.size), rows, np.asarray(fractions, dtype=np.float64))


_SOLVER_KEYWORDS = (
    "anchor_vertices",
    "anchor_triangles",
    "anchor_barycentrics",
    "anchor_positions",
    "unreliable_triangles",
    "rest_positions",
)
"""The ``WrapInputs`` fields the kernel's ``WrapSolver`` takes as keywords of the same names."""
_CURVE_KEYWORDS = ("curve_vertices", "curve_vertex_counts", "curve_points", "curve_point_counts", "curve_fractions")
"""The ``WrapInputs`` fields of the curve constraints, passed to ``WrapSolver`` when there are any."""


def make_wrap_solver(
    target: Target, structure, inputs, parameters, settled_start: bool = False, region_restart: bool = False
):
    """A kernel ``WrapSolver`` for the prepared inputs (``core.wrap_inputs.WrapInputs``, the kernel's frame);
    ``settled_start``: the positions are a wrap's own result, unchanged since, wrapped again with the same rest
    shape, target and parameters (the kernel then re-settles them from its schedule's last level);
    ``region_restart``: a region of a settled layout started again, the rest held (``core.follow``: the kernel then
    leaves out its stiffest level and keeps a point the safeguard held back without its data term)."""
    keywords = {name: getattr(inputs, name) for name in _SOLVER_KEYWORDS}
    if inputs.curve_vertices is not None:
        keywords |= {name: getattr(inputs, name) for name in _CURVE_KEYWORDS}
    if getattr(inputs, "plane_vertices", None) is not None:
        keywords |= {
            "plane_vertices": inputs.plane_vertices,
            "plane_point": tuple(float(value) for value in inputs.plane_point),
            "plane_normal": tuple(float(value) for value in inputs.plane_normal),
            "plane_slide": bool(inputs.plane_slide),
        }
    keywords |= _soft_pair_keywords(inputs)
    return springwrap_kernel.WrapSolver(
        target.mesh.kernel,
        structure,
        inputs.states,
        inputs.triangles,
        inputs.barycentrics,
        inputs.positions,
        settings=parameters.settings,
        stiffness=getattr(inputs, "stiffness", None),
        free_vertices=getattr(inputs, "free_vertices", None),
        settled_start=settled_start,
        region_restart=region_restart,
        **keywords,
    )


def settled_key(target_signature: str, positions, rest, parameters, inputs=None) -> tuple:
    """What a wrap's result is, to know it again unchanged: the target's signature, the layout's local positions and
    rest shape (as the mesh stores them, float32), the wrap's parameters and the plane its ``inputs`` (the
    kernel's, optional) hold points on (which points, where, sliding or not; None without one). See
    :func:`is_settled_start`."""
    digest = [np.ascontiguousarray(array, dtype=np.float32).tobytes() for array in (positions, rest)]
    plane = None
    if inputs is not None and getattr(inputs, "plane_vertices", None) is not None:
        held = np.ascontiguousarray(inputs.plane_vertices, dtype=np.uint32).tobytes()
        plane = (hash(held), tuple(inputs.plane_point), tuple(inputs.plane_normal), bool(inputs.plane_slide))
    return (target_signature, hash(digest[0]), hash(digest[1]), repr(parameters), plane)


def is_settled_start(last, key, holding: bool) -> bool:
    """Whether a wrap of ``key`` (:func:`settled_key`) starts from a settled wrap, the result ``last`` (the key of
    the layout's last wrap, None: none) as it left it: the same target, positions, rest shape and parameters; a
    wrap that holds points (``holding``: a plane, pins) only from a result held the same way (a wrap holding
    nothing re-settles any of them). Then :func:`make_wrap_solver`'s ``settled_start``."""
    if last is None:
        return False
    return last[:-1] == key[:-1] and (not holding or last[-1] == key[-1])


def _soft_pair_keywords(inputs) -> dict:
    """The soft pairs' keywords of ``WrapSolver`` (none without soft pairs), those on a vertex anchored since
    (a mirror's pin) left out: the anchor holds it."""
    vertices = getattr(inputs, "soft_pair_vertices", None)
    if vertices is None:
        return {}
    free = ~np.isin(vertices, inputs.anchor_vertices)
    return {
        "soft_pair_vertices": np.ascontiguousarray(vertices[free]),
        "soft_pair_positions": np.ascontiguousarray(inputs.soft_pair_positions[free]),
        "soft_pair_confidences": np.ascontiguousarray(inputs.soft_pair_confidences[free]),
    }
