"""Springwrap's Rust kernel: target meshes, exact closest point, ray casts and face-points.

The native module ``springwrap_kernel._native`` does the work; this package re-exports it and
names the results. The array contract: positions float32 ``(N, 3)``, triangles uint32
``(M, 3)``, C-contiguous; anything else raises :class:`ArrayError` saying what was wrong. Every
other argument is converted by the binding: a value out of its range raises
:class:`InvalidArgumentError` (:class:`TooLargeError` for a count above what the kernel supports), a
value of the wrong Python type :class:`ArgumentTypeError` (a ``SpringwrapError`` and a
``TypeError``), each naming the argument. Coordinates must be finite and within ``MAX_COORDINATE``
(1e8) of the origin (:class:`NonFiniteError`, :class:`CoordinateRangeError`).
"""

from typing import NamedTuple

import numpy as np

from . import _native
from ._native import (
    MAX_COORDINATE,
    MAX_ELEMENTS,
    ArgumentTypeError,
    ArrayError,
    CancelFlag,
    CancelledError,
    CoordinateRangeError,
    DegenerateMeshError,
    DegenerateTriangleError,
    DivergedError,
    EmptyMeshError,
    FlatSurfaceError,
    IndexOutOfRangeError,
    InternalError,
    InvalidArgumentError,
    LayoutStructure,
    NonFiniteError,
    SpringwrapError,
    SubdivisionFit,
    SubdivisionStencils,
    SurfaceFollower,
    TooLargeError,
    WrapSettings,
    __version__,
    face_normals,
    feature_defaults,
    fit_transform,
    flipped_faces,
    layout_feature_lines,
    layout_pieces,
    layout_readout,
    placed_readout,
    proposal_defaults,
    subdivision_fit_defaults,
    vertex_stretch,
)

__all__ = [
    "ArgumentTypeError",
    "ArrayError",
    "CoordinateRangeError",
    "Curvatures",
    "DegenerateMeshError",
    "DegenerateTriangleError",
    "CancelFlag",
    "CancelledError",
    "DivergedError",
    "EmptyMeshError",
    "FeatureCurve",
    "Features",
    "FlatSurfaceError",
    "IcpReport",
    "IndexOutOfRangeError",
    "LinePairing",
    "Proposals",
    "InternalError",
    "InvalidArgumentError",
    "LayoutStructure",
    "MAX_COORDINATE",
    "MAX_ELEMENTS",
    "NonFiniteError",
    "SpringwrapError",
    "StepReport",
    "SubdivisionFit",
    "SubdivisionStencils",
    "SurfaceFollower",
    "SurfaceHits",
    "TargetMesh",
    "TooLargeError",
    "VertexHits",
    "WrapSettings",
    "WrapSolver",
    "__version__",
    "face_normals",
    "feature_defaults",
    "fit_transform",
    "flipped_faces",
    "layout_feature_lines",
    "layout_pieces",
    "layout_readout",
    "pair_feature_lines",
    "placed_readout",
    "proposal_defaults",
    "propose_correspondences",
    "subdivision_fit_defaults",
    "vertex_stretch",
]


class SurfaceHits(NamedTuple):
    """Per-query surface results; ``triangles[i] == -1`` means query ``i`` found nothing."""

    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray
    distances: np.ndarray


class VertexHits(NamedTuple):
    """Per-query nearest-vertex results; ``vertices[i] == -1`` means query ``i`` found nothing."""

    vertices: np.ndarray
    triangles: np.ndarray
    barycentrics: np.ndarray
    positions: np.ndarray
    distances: np.ndarray


class IcpReport(NamedTuple):
    """Result of :meth:`TargetMesh.icp`."""

    matrix: np.ndarray
    """(4, 4) float64: the refined source-to-target transform."""
    iterations: int
    converged: bool
    rms_before: float
    rms_after: float
    pairs_used: int


class Curvatures(NamedTuple):
    """Per-vertex principal curvatures (convex positive, ``k1 >= k2``) and unit directions."""

    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray


class FeatureCurve(NamedTuple):
    """A ridge or valley polyline: ``kind`` is ``'RIDGE'`` or ``'VALLEY'``."""

    kind: str
    closed: bool
    points: np.ndarray


class Features(NamedTuple):
    """Result of :meth:`TargetMesh.detect_features`."""

    curvatures: Curvatures
    regions: np.ndarray
    """(N,) uint8: 0 flat, 1 convex, 2 concave, 3 saddle."""
    curves: list
    scale: float
    """The scale used: the one given, or the automatic one."""


class LinePairing(NamedTuple):
    """One feature line's outcome of :func:`pair_feature_lines`."""

    curve: int | None
    """The index of the curve it follows, or None when it stays free."""
    reason: str | None
    """Why it stays free (NONE_NEARBY, NOT_PARALLEL, LENGTH_DIFFERS, LOW_CONFIDENCE, TAKEN), or None."""
    confidence: float
    chain: np.ndarray
    """(C,) uint32 the layout chain to constrain (a closed line ends on its first vertex again)."""
    target: np.ndarray
    """(P, 3) float32 the target polyline in the chain's direction."""


def pair_feature_lines(positions, lines, curves, **settings) -> list:
    """Pairs layout feature lines with target feature curves under the current fit (``positions``,
    (N, 3) float32). ``lines``: (vertices uint32, closed, kind) each, ``curves``: (kind, points
    (P, 3) float32, closed) each; settings ``max_distance`` (required), ``max_angle`` (degrees),
    ``min_confidence``. A :class:`LinePairing` per line."""
    return [LinePairing(*outcome) for outcome in _native.pair_feature_lines(positions, lines, curves, **settings)]


class Proposals(NamedTuple):
    """Result of :func:`propose_correspondences`: proposed pairs, most confident first."""

    vertices: np.ndarray
    """(P,) uint32 layout vertices."""
    triangles: np.ndarray
    """(P,) uint32 target triangles."""
    barycentric: np.ndarray
    """(P, 3) float32 weights in those triangles."""
    positions: np.ndarray
    """(P, 3) float32 the target points."""
    confidences: np.ndarray
    """(P,) float32 in [0, 1]."""


def propose_correspondences(
    mesh, rest, current, face_corners, face_sizes, anchor_vertices, anchor_targets, **settings
) -> Proposals:
    """Further layout-vertex → target-point pairs from the anchors given and the current fit.

    ``rest`` and ``current``: the layout's (N, 3) float32 rest shape and positions in the target's
    space; ``face_corners``/``face_sizes``: its faces (uint32); ``anchor_vertices`` (K,) uint32 and
    ``anchor_targets`` (K, 3) float32, K >= 3. Settings (keywords): ``max_count``,
    ``min_confidence``, ``search_radius`` and ``feature_scale`` (fractions of the diagonals); see
    :func:`proposal_defaults`."""
    return Proposals(
        *_native.propose_correspondences(
            mesh, rest, current, face_corners, face_sizes, anchor_vertices, anchor_targets, **settings
        )
    )


class TargetMesh(_native.TargetMesh):
    """A triangle mesh prepared for queries: BVH over triangles, vertex tree, adjacency, normals.

    ``TargetMesh(vertices, triangles, *, reject_degenerate=False)``. Queries are batched, run on
    all cores and release the GIL.
    """

    __slots__ = ()

    def closest_points(self, points, *, max_distance=float("inf")):
        """Exact closest point on the surface (the face tree) for every query point."""
        return SurfaceHits(*super().closest_points(points, max_distance=max_distance))

    def nearest_vertices(self, points, *, max_distance=float("inf")):
        """Nearest mesh vertex (the fast vertex tree), as a face-point at that vertex."""
        return VertexHits(*super().nearest_vertices(points, max_distance=max_distance))

    def icp(self, source, initial=None, **settings):
        """Point-to-plane ICP of ``source`` onto this mesh from ``initial`` (see the stubs)."""
        return IcpReport(*super().icp(source, initial, **settings))

    def principal_curvatures(self, scale):
        """Principal curvatures and directions of every vertex, fitted over ``scale`` (see the stubs)."""
        return Curvatures(*_native.principal_curvatures(self, scale))

    def detect_features(self, scale=None, **settings):
        """Curvatures, concave / convex / flat regions and ridge / valley curves (see the stubs)."""
        used, k1, k2, d1, d2, regions, curves = _native.detect_features(self, scale, **settings)
        return Features(Curvatures(k1, k2, d1, d2), regions, [FeatureCurve(*curve) for curve in curves], used)

    def feature_curves(self, scale=None, **settings):
        """The ridge and valley curves of :meth:`detect_features` alone."""
        return self.detect_features(scale, **settings).curves

    def automatic_feature_scale(self, layout_edge_length=None):
        """The scale :meth:`detect_features` uses when none is given (see the stubs)."""
        return _native.automatic_feature_scale(self, layout_edge_length)

    def ray_cast(self, origins, directions, *, max_distance=float("inf"), both_directions=False):
        """First hit along each ray (signed distance; backwards too with ``both_directions``)."""
        return SurfaceHits(
            *super().ray_cast(origins, directions, max_distance=max_distance, both_directions=both_directions)
        )


class StepReport(NamedTuple):
    """Progress of :meth:`WrapSolver.step`."""

    iterations: int
    """Iterations run by this call."""
    total_iterations: int
    """Iterations since the solver was made."""
    max_displacement: float
    """Largest move of the last iteration, as a fraction of the layout's size."""
    converged: bool
    """The stiffness schedule is done and the points have landed."""
    face_points: int
    space_points: int
    landed: int
    """Anchored points on the surface at the landing (during this call)."""
    folded: int
    """Free points that landed on the surface at the end (during this call)."""
    mean_displacement: float
    """Mean move of the last iteration, as a fraction of the layout's size."""
    energy: float
    """The energy after the last iteration."""
    held_back: int
    """Points whose last step was shortened or refused so that no layout face turned over."""
    energy_decrease: float
    """How much the last iteration lowered the energy, relative to it (each stiffness level ends below the
    settings' tolerance); NaN for a level's first iteration."""


class WrapSolver(_native.WrapSolver):
    """A wrap in progress (one energy minimised level by level): ``step(n)``, then ``positions()`` / ``states()``.

    ``WrapSolver(target, structure, states, triangles, barycentrics, positions, *, anchor_vertices=None,
    anchor_triangles=None, anchor_barycentrics=None, anchor_positions=None,
    unreliable_triangles=None, curve_vertices=None, curve_vertex_counts=None, curve_points=None,
    curve_point_counts=None, curve_fractions=None, rest_positions=None, plane_vertices=None,
    plane_point=None, plane_normal=None, plane_slide=True, settings=None, stiffness=None, free_vertices=None,
    soft_pair_vertices=None, soft_pair_positions=None, soft_pair_confidences=None, settled_start=False,
    region_restart=False)``;
    ``settings`` is a :class:`WrapSettings` (weights, tolerance, landing, fold tolerance, schedule), the
    kernel's defaults when ``None``; ``curve_fractions`` (float32, one per entry of ``curve_vertices``) says where
    along its curve each chain vertex goes (fraction of the curve's length; a chain's rows all NaN: as it is
    spaced); ``stiffness`` is float32 per vertex (0 … 1), ``free_vertices`` bool per vertex; the soft pairs (vertices, points, confidences in (0, 1]) pull in the stiff levels only;
    ``region_restart``: a region of a settled layout started again, every other vertex held by anchors where it is
    (the global-to-local schedule starts at its second level; a point held back keeps no data term).
    """

    __slots__ = ()

    def step(self, iterations, *, cancel=None):
        """Run up to ``iterations`` iterations (fewer once converged); the GIL is released meanwhile. ``cancel``: a
        :class:`CancelFlag` the step asks inside its long loops; once another thread set it the step raises
        :class:`CancelledError`, ``positions()`` / ``states()`` read the points as before the call and every later
        step raises again (the half-stepped solver is dropped)."""
        progress, energy, held_back, energy_decrease = super().step(iterations, cancel=cancel)
        return StepReport(*progress, energy, held_back, energy_decrease)
