"""Type stubs for the Springwrap kernel (the public Python API of the Rust kernel).

Array contract (every function): positions are float32 ``(N, 3)``, triangles uint32
``(M, 3)``, all C-contiguous. Anything else raises :class:`ArrayError` naming the
argument, and what was expected and found; nothing is copied or reinterpreted silently.
"""

from typing import Literal, NamedTuple

import numpy as np
import numpy.typing as npt

__version__: str

MAX_COORDINATE: float
"""The largest coordinate magnitude the kernel accepts (1e8 model units, each component)."""
MAX_ELEMENTS: int
"""The largest vertex, triangle or layout vertex count (2**31 - 1)."""

# ---------------------------------------------------------------- exceptions
class SpringwrapError(ValueError):
    """Base class of every error the kernel raises."""

class ArrayError(SpringwrapError):
    """An input array has the wrong dtype, shape or memory layout."""

class EmptyMeshError(SpringwrapError):
    """The mesh has no vertices or no triangles."""

class NonFiniteError(SpringwrapError):
    """A coordinate (vertex, query point, ray) is NaN or infinite."""

class CoordinateRangeError(SpringwrapError):
    """A coordinate is finite but beyond ``MAX_COORDINATE`` (a value like 3.4e38 or 1e30), or a wrap
    constraint (anchor target, curve point, plane) lies beyond the region the wrap can reach."""

class IndexOutOfRangeError(SpringwrapError):
    """A triangle refers to a vertex index >= the vertex count, or a face-point to a triangle that does not exist."""

class DegenerateMeshError(SpringwrapError):
    """Every triangle of the mesh has zero area: there is no surface to attach to."""

class DegenerateTriangleError(SpringwrapError):
    """A triangle has zero area (only raised when ``reject_degenerate=True``)."""

class InvalidArgumentError(SpringwrapError):
    """A scalar argument is out of its domain (negative distance, zero direction...)."""

class TooLargeError(InvalidArgumentError):
    """A count is above ``MAX_ELEMENTS`` (or a limit the argument states)."""

class ArgumentTypeError(SpringwrapError, TypeError):
    """An argument has the wrong Python type (a str for a number, a float for a count...); the message
    names it."""

class FlatSurfaceError(SpringwrapError):
    """Feature detection found no curvature at the scale given (a plane): nothing to detect."""

class DivergedError(SpringwrapError):
    """The wrap diverged (a point stopped being finite or left the region it can reach); the layout
    was rolled back to before the failing step."""

class CancelledError(SpringwrapError):
    """A long computation stopped because its cancellation flag was set (:meth:`CancelFlag.cancel`)."""

class InternalError(SpringwrapError):
    """A bug in the kernel (a caught Rust panic). Please report it."""

# ---------------------------------------------------------------- results
class SurfaceHits(NamedTuple):
    """Per-query results of a surface query (closest point, ray cast, nearest vertex).

    ``triangles[i] == -1`` means query ``i`` found nothing (ray missed, or nothing within
    ``max_distance``); its other fields are then ``0`` / ``nan`` and must be ignored.
    """

    triangles: npt.NDArray[np.int32]  # (K,)   triangle index, -1 for none
    barycentrics: npt.NDArray[np.float32]  # (K, 3) weights of the triangle's 3 corners, sum 1
    positions: npt.NDArray[np.float32]  # (K, 3) the surface point
    distances: npt.NDArray[np.float32]  # (K,)   distance from the query to the surface point (ray: signed t)

class VertexHits(NamedTuple):
    """Per-query results of :meth:`TargetMesh.nearest_vertices`."""

    vertices: npt.NDArray[np.int32]  # (K,) nearest target vertex, -1 for none
    triangles: npt.NDArray[np.int32]  # (K,) a non-degenerate triangle using that vertex
    barycentrics: npt.NDArray[np.float32]  # (K, 3) the corner of that triangle (one 1, two 0)
    positions: npt.NDArray[np.float32]  # (K, 3) the vertex position
    distances: npt.NDArray[np.float32]  # (K,)

# ---------------------------------------------------------------- the mesh
class TargetMesh:
    """A triangle mesh prepared for queries: BVH over triangles, vertex tree, adjacency, normals.

    Built once: the constructor builds the face tree (parallel); the vertex tree, adjacency and
    normals are built on first use or by :meth:`prepare_all`. Every query is batched, runs on all
    cores and releases the GIL; batches are answered in spatial (Morton) order internally, so the
    caller's order does not matter for speed. Degenerate (zero-area) triangles are kept so that triangle indices
    stay those of the input, but they are never hit by rays and never chosen by
    :meth:`nearest_vertices`; a mesh whose every triangle is degenerate is refused.
    """

    def __init__(
        self,
        vertices: npt.NDArray[np.float32],
        triangles: npt.NDArray[np.uint32],
        *,
        reject_degenerate: bool = False,
    ) -> None: ...
    def prepare_all(self) -> None:
        """Build now what is otherwise built on first use (vertex tree, adjacency, normals)."""
    @property
    def vertex_count(self) -> int: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def degenerate_triangle_count(self) -> int: ...
    @property
    def boundary_edge_count(self) -> int: ...
    @property
    def non_manifold_edge_count(self) -> int: ...
    def bounding_box(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    def vertices(self) -> npt.NDArray[np.float32]: ...
    def triangles(self) -> npt.NDArray[np.uint32]: ...
    def face_normals(self) -> npt.NDArray[np.float32]:
        """(M, 3) unit normals; zero for degenerate triangles."""
    def vertex_normals(self) -> npt.NDArray[np.float32]:
        """(N, 3) angle-weighted unit normals; zero for vertices no triangle uses."""
    def triangle_neighbors(self) -> npt.NDArray[np.int32]:
        """(M, 3): entry ``[t, e]`` is the triangle across edge ``e`` of ``t`` (edge ``e`` runs from
        corner ``e`` to corner ``(e + 1) % 3``), or -1 on a boundary or non-manifold edge."""
    def boundary_edges(self) -> npt.NDArray[np.uint32]:
        """(B, 2) rows of ``(triangle, edge)`` for every edge with one triangle (holes, open borders)."""
    def closest_points(self, points: npt.NDArray[np.float32], *, max_distance: float = ...) -> SurfaceHits:
        """Exact closest point on the surface (the face tree) for every query point."""
    def nearest_vertices(self, points: npt.NDArray[np.float32], *, max_distance: float = ...) -> VertexHits:
        """Nearest mesh vertex (the fast vertex tree), as a face-point at that vertex."""
    def ray_cast(
        self,
        origins: npt.NDArray[np.float32],
        directions: npt.NDArray[np.float32],
        *,
        max_distance: float = ...,
        both_directions: bool = False,
    ) -> SurfaceHits:
        """First hit along each ray. ``directions`` need not be unit length but must not be zero.
        With ``both_directions`` the ray is also cast backwards and the nearer hit wins
        (``distances`` is then negative for hits behind the origin)."""
    def face_point_positions(
        self, triangles: npt.NDArray[np.uint32], barycentrics: npt.NDArray[np.float32]
    ) -> npt.NDArray[np.float32]:
        """Positions of face-points ``(triangle, barycentric)`` on this mesh."""
    def surface_distances(
        self,
        points: npt.NDArray[np.float64],
        *,
        near: npt.NDArray[np.uint32] | None = None,
        on_surface: float = 0.0,
    ) -> npt.NDArray[np.float64]:
        """Distance of each point (float64, this mesh's coordinates) to the closest surface point, in float64.
        ``near``: the triangle each point lies on (0xFFFFFFFF: none): within ``on_surface`` of it, the distance to
        it, else the search starts there. Non-finite points read ``inf``."""
    def icp(
        self,
        source: npt.NDArray[np.float32],
        initial: npt.NDArray[np.float64] | None = None,
        *,
        update: Literal["RIGID", "SIMILARITY"] = "RIGID",
        max_iterations: int = 50,
        trim_fraction: float = 0.1,
        max_distance: float = ...,
        tolerance: float = 1e-7,
        ignore_boundary: bool = True,
        anchor_source: npt.NDArray[np.float32] | None = None,
        anchor_target: npt.NDArray[np.float32] | None = None,
        anchor_weight: float = 1.0,
    ) -> IcpReport:
        """Point-to-plane ICP of ``source`` onto this mesh, starting from ``initial`` (a (4, 4)
        float64 affine matrix, identity when ``None``). Each iteration ignores pairs farther than
        ``max_distance``, pairs whose closest point lies on a boundary edge (with
        ``ignore_boundary``) and the worst ``trim_fraction``; it stops when the RMS distance
        changes by less than ``tolerance`` times the mesh's bounding-box diagonal. With
        ``anchor_source`` and ``anchor_target`` ((K, 3) float32, both or neither) each anchor point
        is also pulled to its target, point to point, all anchors together weighing
        ``anchor_weight`` times the surface pairs (0: ignored); convergence then judges the whole fit."""

    def principal_curvatures(self, scale: float) -> Curvatures:
        """Principal curvatures and directions of every vertex, from a quadric (plus isotropic
        quartic) fitted by weighted least squares to the vertices within ``scale`` (model units)
        of it: bumps and noise smaller than the scale are ignored. Convex is positive for outward
        normals (right-handed winding): ``+1/r`` on a sphere of radius ``r``. Raises
        :class:`InvalidArgumentError` when ``scale`` is not positive and finite or exceeds the
        mesh's bounding-box diagonal."""
    def detect_features(
        self,
        scale: float | None = None,
        *,
        layout_edge_length: float | None = None,
        flat_threshold: float = 0.1,
        ridge_threshold: float = 0.25,
        hysteresis: float = 0.5,
        min_length: float | None = None,
        join_distance: float | None = None,
    ) -> Features:
        """Curvatures, regions and ridge / valley curves. ``scale`` ``None`` or 0: automatic
        (:meth:`automatic_feature_scale`, with ``layout_edge_length`` the median edge length of the
        layout the curves are for); the result's ``scale`` says which was used. A direction is flat
        while ``|k| * scale < flat_threshold``; a ridge (valley) is where the largest (most
        negative) curvature is extremal across itself, with ``k * scale >= ridge_threshold``
        somewhere along the curve and ``hysteresis * ridge_threshold`` along the rest of it; open
        ends are extended along the crease while it stays a crest at that low threshold, up to an
        edge of the surface. Pieces whose ends are within ``join_distance`` (default ``2 * scale``)
        and continue each other are joined; curves shorter than ``min_length`` (default
        ``3 * scale``) are dropped. For the centre-lines of blends, ``scale`` about the blend
        radius. Raises :class:`FlatSurfaceError` when no vertex bends beyond ``flat_threshold``
        (a plane)."""
    def feature_curves(
        self,
        scale: float | None = None,
        *,
        layout_edge_length: float | None = None,
        flat_threshold: float = 0.1,
        ridge_threshold: float = 0.25,
        hysteresis: float = 0.5,
        min_length: float | None = None,
        join_distance: float | None = None,
    ) -> list[FeatureCurve]:
        """The curves of :meth:`detect_features` alone."""
    def automatic_feature_scale(self, layout_edge_length: float | None = None) -> float:
        """The feature scale used when none is given: ``layout_edge_length`` (a layout's median
        edge length) when given and > 0, else a tenth of the bounding-box diagonal; kept within 6
        and 30 mean edge lengths of this mesh and at most its diagonal."""

# ---------------------------------------------------------------- features
class Curvatures(NamedTuple):
    """Per-vertex principal curvatures (1 / length, convex positive, ``k1 >= k2``)."""

    k1: npt.NDArray[np.float32]  # (N,)
    k2: npt.NDArray[np.float32]  # (N,)
    d1: npt.NDArray[np.float32]  # (N, 3) unit direction of k1 (zero on vertices of no triangle)
    d2: npt.NDArray[np.float32]  # (N, 3) unit direction of k2 (normal x d1)

class FeatureCurve(NamedTuple):
    """A ridge or valley polyline on the surface (a closed one does not repeat its first point)."""

    kind: Literal["RIDGE", "VALLEY"]
    closed: bool
    points: npt.NDArray[np.float32]  # (P, 3)

class Features(NamedTuple):
    """Result of :meth:`TargetMesh.detect_features`."""

    curvatures: Curvatures
    regions: npt.NDArray[np.uint8]  # (N,) 0 flat, 1 convex, 2 concave, 3 saddle
    curves: list[FeatureCurve]
    scale: float  # the scale used: the one given, or the automatic one

# ---------------------------------------------------------------- alignment
class IcpReport(NamedTuple):
    """Result of :meth:`TargetMesh.icp`."""

    matrix: npt.NDArray[np.float64]
    """(4, 4) float64: the refined source-to-target transform."""
    iterations: int
    converged: bool
    """The RMS change fell below the tolerance before ``max_iterations``."""
    rms_before: float
    """RMS distance of the pairs used, at ``initial``."""
    rms_after: float
    """RMS distance of the pairs used, at ``matrix``."""
    pairs_used: int
    """Pairs kept in the last evaluation (after trimming, the distance and boundary checks)."""

def fit_transform(
    source: npt.NDArray[np.float32],
    target: npt.NDArray[np.float32],
    method: Literal["RIGID", "SIMILARITY", "AFFINE"] = "SIMILARITY",
    *,
    weights: npt.NDArray[np.float32] | None = None,
) -> npt.NDArray[np.float64]:
    """Least-squares transform taking anchor ``source[i]`` to ``target[i]``, as a (4, 4) float64
    matrix. Rigid and similarity fits never mirror (Umeyama); an affine fit may. Needs 3 anchors
    not on one line (rigid, similarity) or 4 not in one plane (affine), else
    :class:`InvalidArgumentError` says which; ``weights`` (float32 ``(N,)``, non-negative) weigh
    the pairs."""

# ---------------------------------------------------------------- the wrap
class LayoutStructure:
    """The structure of a layout mesh for the wrap: grid lines, corners, extraordinary vertices, curves.

    Faces are given flat: ``face_sizes[f]`` corner indices of face ``f`` follow one another in
    ``face_corners``. ``edges`` (uint32 (E, 2)) are the mesh's edges (those used by no face are
    loose curves), ``seams`` (uint32 (S, 2)) the edges marked as patch boundaries.
    """

    def __init__(
        self,
        vertex_count: int,
        face_corners: npt.NDArray[np.uint32],
        face_sizes: npt.NDArray[np.uint32],
        *,
        edges: npt.NDArray[np.uint32] | None = None,
        seams: npt.NDArray[np.uint32] | None = None,
    ) -> None: ...
    @property
    def vertex_count(self) -> int: ...
    def line_triples(self) -> npt.NDArray[np.uint32]:
        """(T, 3) rows (previous, vertex, next): ``vertex`` lies on a grid line between the two."""
    def extraordinary(self) -> npt.NDArray[np.uint32]:
        """Vertices on no grid line (the umbrella fallback acts on them)."""
    def corners(self) -> npt.NDArray[np.uint32]:
        """Patch corners: border vertices of one face (no fairness acts on them)."""
    def curves(self) -> list[tuple[str, npt.NDArray[np.uint32], bool]]:
        """(kind "BORDER" | "SEAM" | "LOOSE", vertices in order, closed) per curve."""

class StepReport(NamedTuple):
    """Progress of :meth:`WrapSolver.step`."""

    iterations: int
    total_iterations: int
    max_displacement: float
    converged: bool
    face_points: int
    space_points: int
    landed: int
    folded: int
    mean_displacement: float
    energy: float
    held_back: int
    energy_decrease: float

class WrapSettings:
    """Everything that controls a wrap besides the layout, the target and the constraints.

    Immutable. ``WrapSettings()`` holds the kernel's defaults (Rust's ``WrapSettings::default()``,
    the one place they are written; the defaults below are checked against it by the tests).
    Keyword arguments override them; a value out of its range raises :class:`InvalidArgumentError`
    naming the keyword, e.g. ``invalid thin_plate: the thin plate weight must be within [0, 0.5],
    not 0.7``. Values are float32 inside; a getter returns the shortest decimal of the float32
    (``0.2``, not ``0.20000000298023224``). Equal when every setting is.
    """

    def __init__(
        self,
        *,
        fairness: float = 0.5,
        arc_length: float = 0.5,
        thin_plate: float = 0.2,
        constraint: float = 0.5,
        folding: float = 0.3,
        tolerance: float = 0.002,
        landing_distance: float = 0.25,
        fold_tolerance: float = 1.3089969,
        schedule: Literal["AUTO", "LOCAL", "GLOBAL_TO_LOCAL"] = "AUTO",
    ) -> None: ...
    @property
    def fairness(self) -> float:
        """α: fairness, the weight of the second differences along the grid lines, 0 to 1."""
    @property
    def arc_length(self) -> float:
        """β: arc length, the weight of the edge terms (the spacing along the grid lines), 0 to 1."""
    @property
    def thin_plate(self) -> float:
        """γ_tp: thin plate, the weight of the umbrella terms at points no grid line runs straight through, 0 to 0.5."""
    @property
    def constraint(self) -> float:
        """γ_con: the pull of the layout onto the target (the data term's weight), 0 to 1."""
    @property
    def folding(self) -> float:
        """γ_fold: how far off the surface the layout is still drawn onto it (the data term's reach), 0 to 1."""
    @property
    def tolerance(self) -> float:
        """A stiffness level ends once an iteration lowers the energy by less than this fraction, (0, 1]."""
    @property
    def landing_distance(self) -> float:
        """An anchored space-point lands on its face-point target within this fraction of the mean edge length, 0 to 10."""
    @property
    def fold_tolerance(self) -> float:
        """A free point lands at the end only where the layout faces the surface within this angle (radians), 0 to pi / 2."""
    @property
    def schedule(self) -> Literal["AUTO", "LOCAL", "GLOBAL_TO_LOCAL"]:
        """The stiffness schedule: automatic (chosen from the anchors when the wrap starts: global to local for 3
        to 11 anchors, or more on a large change of shape), local, or stiff nearly affine levels first (for few
        anchors on a large change of shape)."""
    @staticmethod
    def ranges() -> dict[str, tuple[str, float, float, bool, bool]]:
        """The range of every numeric setting (the kernel's one table): keyword -> (label, low, high, low_open,
        high_open)."""
    def to_dict(self) -> dict[str, float | str]:
        """Every setting by its keyword, in the constructor's order."""
    def replace(self, **changes: float | str) -> WrapSettings:
        """A copy with the given settings changed (checked like the constructor)."""

class WrapSolver:
    """A wrap in progress (one energy minimised onto ``target``).

    One row per layout vertex: ``states`` int32 (1 face-point, 0 space-point), ``triangles`` int32
    (the face-point's target triangle, ignored for space-points), ``barycentrics`` float32 (N, 3),
    ``positions`` float32 (N, 3) (used for space-points). Anchors are parallel arrays; a negative
    anchor triangle makes a space anchor at its position. ``unreliable_triangles`` (bool, one per
    target triangle) marks noisy data: points there behave as space-points. Curve constraints are
    flat arrays: chain ``c`` is the next ``curve_vertex_counts[c]`` entries of ``curve_vertices``
    (layout vertices in order), its target polyline the next ``curve_point_counts[c]`` rows of
    ``curve_points`` (world space, same direction); matched by the chain's arc length now, or at
    ``curve_fractions`` (one per entry of ``curve_vertices``: fraction of the curve's length; a
    chain's rows all NaN: by its arc length).
    ``plane_vertices`` (uint32) are held on the plane through ``plane_point`` with normal
    ``plane_normal`` (a mirrored layout's seam: face-points slide along the target's cross-section
    with the plane, space-points move within it); all three or none. ``plane_slide=False``: held
    points only move onto the cross-section, the shortest way, and stay there.
    ``settings`` (a :class:`WrapSettings`; the kernel's defaults when ``None``) holds the energy's
    weights, the tolerance, landing, the fold tolerance and the schedule: one energy minimised by
    local-global steps with a sparse Cholesky (or, past 2 GiB of factor, preconditioned conjugate
    gradients), no layout face turned more than 90 degrees from the template's orientation.
    ``stiffness`` (float32, one per layout vertex, 0 … 1: 0 follows the target freely, 0.5 the
    wrap's own balance, 1 keeps the template's shape) and ``free_vertices`` (bool, one per layout
    vertex: no pull toward the target, they stay space-points),
    and soft pairs (``soft_pair_vertices`` uint32, ``soft_pair_positions`` float32 (S, 3),
    ``soft_pair_confidences`` float32 in (0, 1], all three or none: each vertex is pulled toward its
    point in proportion to its confidence in the warm-up and the stiff levels of the global-to-local
    schedule, then let go; not on an anchored vertex). ``settled_start``: the points are a wrap's own result,
    unchanged since, wrapped again with the same rest shape and target: the wrap re-settles them from the
    schedule's last level (no warm-up, no stiffer levels) when they lie on the target with their anchors and
    curve targets met and no plane or soft pairs, and runs the whole schedule otherwise or when its first
    iteration moves them far (a layout snapped onto the target is on it too, far from settled).
    ``region_restart``: the wrap re-settles a region of a settled layout started again, every other vertex held by
    anchors where it is: the global-to-local schedule starts at its second level, and a point the safeguard holds
    back keeps no data term for the rest of the wrap (the local schedule runs as without it).
    """

    def __init__(
        self,
        target: TargetMesh,
        structure: LayoutStructure,
        states: npt.NDArray[np.int32],
        triangles: npt.NDArray[np.int32],
        barycentrics: npt.NDArray[np.float32],
        positions: npt.NDArray[np.float32],
        *,
        anchor_vertices: npt.NDArray[np.uint32] | None = None,
        anchor_triangles: npt.NDArray[np.int32] | None = None,
        anchor_barycentrics: npt.NDArray[np.float32] | None = None,
        anchor_positions: npt.NDArray[np.float32] | None = None,
        unreliable_triangles: npt.NDArray[np.bool_] | None = None,
        curve_vertices: npt.NDArray[np.uint32] | None = None,
        curve_vertex_counts: npt.NDArray[np.uint32] | None = None,
        curve_points: npt.NDArray[np.float32] | None = None,
        curve_point_counts: npt.NDArray[np.uint32] | None = None,
        curve_fractions: npt.NDArray[np.float32] | None = None,
        rest_positions: npt.NDArray[np.float32] | None = None,
        plane_vertices: npt.NDArray[np.uint32] | None = None,
        plane_point: tuple[float, float, float] | None = None,
        plane_normal: tuple[float, float, float] | None = None,
        plane_slide: bool = True,
        settings: WrapSettings | None = None,
        stiffness: npt.NDArray[np.float32] | None = None,
        free_vertices: npt.NDArray[np.bool_] | None = None,
        soft_pair_vertices: npt.NDArray[np.uint32] | None = None,
        soft_pair_positions: npt.NDArray[np.float32] | None = None,
        soft_pair_confidences: npt.NDArray[np.float32] | None = None,
        settled_start: bool = False,
        region_restart: bool = False,
    ) -> None: ...
    def step(self, iterations: int, *, cancel: CancelFlag | None = None) -> StepReport:
        """Run up to ``iterations`` iterations (fewer once converged), GIL released; ``cancel`` set by another
        thread: ``CancelledError`` soon, the points as before the call, the solver then unusable."""
    def set_anchors(
        self,
        anchor_vertices: npt.NDArray[np.uint32] | None = None,
        anchor_triangles: npt.NDArray[np.int32] | None = None,
        anchor_barycentrics: npt.NDArray[np.float32] | None = None,
        anchor_positions: npt.NDArray[np.float32] | None = None,
    ) -> None:
        """Replace the anchors between two steps: the points stay, the schedule starts again from its warm-up."""
    def positions(self) -> npt.NDArray[np.float32]:
        """(N, 3) positions of the layout points."""
    def states(self) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.int32], npt.NDArray[np.float32]]:
        """(states, triangles, barycentrics) as given to the constructor."""
    @property
    def settings(self) -> WrapSettings:
        """The settings the wrap runs with."""

class SubdivisionStencils:
    """The limit points of a cage subdivided ``levels`` times (Catmull–Clark with the rules of Blender's
    Subdivision Surface modifier), as a sparse matrix over the cage's vertices, and the fine quads.

    Faces are given flat as for :class:`LayoutStructure`. ``boundary`` is Blender's *Boundary Smooth*:
    ``"ALL"`` (corners smoothed, the modifier's default) or ``"PRESERVE_CORNERS"`` (Keep Corners). Fine
    vertices come parents first: the cage's vertices are the first ``cage_vertex_count``. Refused
    (:class:`InvalidArgumentError`): ``levels`` outside 1..6, no faces, a face of fewer than three corners
    or with a repeated corner, an edge of three or more faces, faces of opposite winding across an edge, a
    vertex whose faces are not one fan.
    """

    def __init__(
        self,
        vertex_count: int,
        face_corners: npt.NDArray[np.uint32],
        face_sizes: npt.NDArray[np.uint32],
        levels: int,
        *,
        boundary: Literal["ALL", "PRESERVE_CORNERS"] = "ALL",
    ) -> None: ...
    @property
    def levels(self) -> int: ...
    @property
    def boundary(self) -> Literal["ALL", "PRESERVE_CORNERS"]: ...
    @property
    def cage_vertex_count(self) -> int: ...
    @property
    def fine_vertex_count(self) -> int: ...
    def matrix(self) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32], npt.NDArray[np.float64]]:
        """CSR form: row offsets (F + 1), cage vertex of each entry, weight of each entry."""
    def fine_quads(self) -> npt.NDArray[np.uint32]:
        """(Q, 4) quads of the last level over the fine vertices, wound as the cage's faces."""
    def on_surface(self) -> npt.NDArray[np.bool_]:
        """(F,) whether each fine vertex lies on the surface (not a cage vertex on no face)."""
    def apply(self, cage: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """(F, 3) limit points of the cage at ``cage`` ((N, 3))."""

class SubdivisionFit:
    """Gauss–Newton rounds moving a cage so that its subdivided (limit) surface lies on a target.

    Each :meth:`round` matches every fine point (stencils applied, plus ``offsets`` when given: what an
    exact evaluation adds to the stencils) to its closest target point, trusted within ``max_distance``,
    not on a border of the target (a hole's rim) and with normals of cosine at least ``min_facing``, and
    solves ``min Σ w |S x + o − c|² + smoothness Σ |L (x − x_prev)|² + damping |x − x_prev|²`` with the
    ``fixed`` vertices (bool per cage vertex; and those on no face) held. An anchor pulls the *limit point* of
    its cage vertex ``anchor_vertices[k]`` to ``anchor_points[k]`` (weight ``anchor_weight``) instead of its
    closest point. Defaults: :func:`subdivision_fit_defaults`.
    """

    def __init__(
        self,
        stencils: SubdivisionStencils,
        *,
        fixed: npt.NDArray[np.bool_] | None = None,
        smoothness: float | None = None,
        max_distance: float | None = None,
        min_facing: float | None = None,
        damping: float | None = None,
        anchor_vertices: npt.NDArray[np.uint32] | None = None,
        anchor_points: npt.NDArray[np.float32] | None = None,
        anchor_weight: float | None = None,
    ) -> None: ...
    def fixed(self) -> npt.NDArray[np.bool_]:
        """(N,) the cage vertices the fit holds."""
    def fine_points(
        self, cage: npt.NDArray[np.float32], offsets: npt.NDArray[np.float32] | None = None
    ) -> npt.NDArray[np.float32]:
        """(F, 3) fine points of ``cage`` plus ``offsets``."""
    def distances(
        self, target: TargetMesh, cage: npt.NDArray[np.float32], offsets: npt.NDArray[np.float32] | None = None
    ) -> npt.NDArray[np.float32]:
        """(F,) distance of each fine point to ``target`` (NaN off the surface or beyond ``max_distance``)."""
    def round(
        self,
        target: TargetMesh,
        cage: npt.NDArray[np.float32],
        offsets: npt.NDArray[np.float32] | None = None,
        *,
        cancel: CancelFlag | None = None,
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], int]:
        """One round: (the new cage, the fine points' distances before it, the trusted matches). ``cancel``: asked
        inside the round's long loops; once another thread sets it the round raises :class:`CancelledError`."""

class CancelFlag:
    """A flag another thread sets to stop a long kernel computation (``SubdivisionFit.round(..., cancel=flag)``)."""

    def __init__(self) -> None: ...
    def cancel(self) -> None:
        """Ask every computation holding this flag to stop."""
    @property
    def cancelled(self) -> bool:
        """Whether :meth:`cancel` was called."""

def feature_defaults() -> dict[str, float]:
    """The kernel's defaults of :meth:`TargetMesh.detect_features` (scale 0 = automatic, flat_threshold,
    ridge_threshold, hysteresis, min_length_scales, join_distance_scales) and of the automatic scale
    (scale_diagonal_fraction, scale_min_edges, scale_max_edges)."""

def subdivision_fit_defaults() -> dict[str, float]:
    """The kernel's defaults of :class:`SubdivisionFit` (smoothness, max_distance, min_facing, damping,
    anchor_weight) and the deepest level (max_levels)."""

def vertex_stretch(
    points: npt.NDArray[np.float64], rest: npt.NDArray[np.float64], edges: npt.NDArray[np.uint32]
) -> npt.NDArray[np.float64]:
    """(N,) mean incident edge length now over the same at rest (1 where nothing can be measured)."""

def face_normals(
    points: npt.NDArray[np.float64], face_corners: npt.NDArray[np.uint32], face_sizes: npt.NDArray[np.uint32]
) -> npt.NDArray[np.float64]:
    """(F, 3) Newell normals (twice the area vector; zero for a degenerate face)."""

def flipped_faces(
    points: npt.NDArray[np.float64],
    rest: npt.NDArray[np.float64],
    face_corners: npt.NDArray[np.uint32],
    face_sizes: npt.NDArray[np.uint32],
    edges: npt.NDArray[np.uint32],
) -> npt.NDArray[np.bool_]:
    """(F,) each face turned over against its rest shape: its normal against its rest normal carried by the best
    rotation of its neighbourhood (its corners and their edge neighbours)."""

def layout_pieces(vertex_count: int, edges: npt.NDArray[np.uint32]) -> npt.NDArray[np.uint32]:
    """(N,) piece number of each layout vertex: the connected components of ``edges`` ((E, 2)), numbered in the
    order of each piece's lowest vertex (a vertex on no edge is a piece of its own)."""

class SurfaceFollower:
    """Parts bound to the layout's surface at rest, moved by the surface's motion: each part vertex bound to its
    ``neighbours`` nearest surface vertices (a soft one to its ``soft_neighbours`` nearest); a rigid piece moves by
    the best similarity (rotation, translation and, with ``scale``, a uniform scale) of the surface around all its
    vertices, a soft vertex by its own neighbourhood's. A rigid piece's fit is reweighted ``robust_rounds`` times
    (0 to 16), each round weighting down the surface vertices the last fit carries worst (Geman-McClure: a misfit of
    the weighted median keeps a quarter of its weight): the piece follows the surroundings that move as one body, not
    skin folding over it."""

    def __init__(
        self,
        surface_rest: npt.NDArray[np.float64],
        part_rest: npt.NDArray[np.float64],
        pieces: npt.NDArray[np.uint32],
        rigid: npt.NDArray[np.bool_],
        *,
        neighbours: int = 64,
        soft_neighbours: int = 256,
        scale: bool = False,
        robust_rounds: int = 0,
    ) -> None: ...
    @property
    def part_count(self) -> int:
        """Number of part vertices."""

    def apply(self, surface_now: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """(P, 3) part positions for the surface at ``surface_now`` ((S, 3), in the order given at rest)."""

def layout_readout(
    points: npt.NDArray[np.float64],
    rest: npt.NDArray[np.float64] | None,
    face_corners: npt.NDArray[np.uint32],
    face_sizes: npt.NDArray[np.uint32],
    edges: npt.NDArray[np.uint32],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_], float]:
    """(stretch (N,), flipped (F,), diagonal): :func:`vertex_stretch`, :func:`flipped_faces` and the finite points'
    bounding-box diagonal in one pass; ``rest`` None: no usable rest shape (the stretch reads 1, no face is
    flipped)."""

def placed_readout(
    mesh: TargetMesh,
    positions: npt.NDArray[np.float32],
    rest: npt.NDArray[np.float32] | None,
    matrix: npt.NDArray[np.float64],
    face_corners: npt.NDArray[np.uint32],
    face_sizes: npt.NDArray[np.uint32],
    edges: npt.NDArray[np.uint32],
    *,
    origin: npt.NDArray[np.float64] | None = None,
    near: npt.NDArray[np.uint32] | None = None,
    on_surface: float | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_], float]:
    """(distances (N,), stretch (N,), flipped (F,), diagonal): the whole read-out of a layout as its object stores
    it, in one call. ``positions`` and ``rest`` (N, 3) float32 in the object's space (``rest`` None: no rest shape;
    one with a point not finite in the world is not used either), ``matrix`` (4, 4) float64 affine, the object's
    space to the world; ``mesh``'s coordinates are the world's less ``origin`` ((3,) float64, default zero);
    ``near`` and ``on_surface`` as in :meth:`TargetMesh.surface_distances`. The same numbers as
    :func:`layout_readout` of the world positions and rest shape and ``surface_distances`` of the positions."""

# ---------------------------------------------------------------- correspondence proposals

class Proposals(NamedTuple):
    """Proposed pairs, most confident first."""

    vertices: npt.NDArray[np.uint32]  # (P,) layout vertices
    triangles: npt.NDArray[np.uint32]  # (P,) target triangles
    barycentric: npt.NDArray[np.float32]  # (P, 3)
    positions: npt.NDArray[np.float32]  # (P, 3) the target points
    confidences: npt.NDArray[np.float32]  # (P,) in [0, 1]

def propose_correspondences(
    mesh: TargetMesh,
    rest: npt.NDArray[np.float32],
    current: npt.NDArray[np.float32],
    face_corners: npt.NDArray[np.uint32],
    face_sizes: npt.NDArray[np.uint32],
    anchor_vertices: npt.NDArray[np.uint32],
    anchor_targets: npt.NDArray[np.float32],
    *,
    max_count: int = 40,
    min_confidence: float = 0.5,
    search_radius: float = 0.06,
    feature_scale: float = 0.03,
) -> Proposals:
    """Further layout-vertex → target-point pairs where both shapes say where a point goes: distinct
    points (tips, pits) of the layout's rest shape and of the target, matched by position after the
    current fit, protrusion and geodesic ratios to the anchors, reciprocally, outliers rejected.
    Raises :class:`InvalidArgumentError` for fewer than 3 anchors on distinct vertices, coincident
    anchors or a setting out of range; :class:`IndexOutOfRangeError`, :class:`NonFiniteError`,
    :class:`ArrayError` for bad arrays."""

def proposal_defaults() -> dict[str, float | int]:
    """The proposals' defaults: max_count, min_confidence, search_radius, feature_scale, min_anchors."""

# ---------------------------------------------------------------- feature lines
def layout_feature_lines(
    positions: npt.NDArray[np.float32],
    face_corners: npt.NDArray[np.uint32],
    face_sizes: npt.NDArray[np.uint32],
    *,
    marked: npt.NDArray[np.uint32] | None = None,
    crease_degrees: float = 30.0,
    borders: bool = True,
    min_edges: int = 2,
) -> list[tuple[str, str, npt.NDArray[np.uint32], bool, float]]:
    """The layout's feature lines: (kind RIDGE/VALLEY/BORDER/ANY, source MARKED/CREASE/BORDER, vertices,
    closed, mean signed dihedral in degrees) each. ``marked``: (K, 2) edges the artist marked; creases
    beyond ``crease_degrees`` (0: none) and open borders (``borders``) are found on ``positions``. A
    marked line that crosses itself raises InvalidArgumentError."""

class LinePairing(NamedTuple):
    """One feature line's outcome of :func:`pair_feature_lines`."""

    curve: int | None
    reason: str | None
    confidence: float
    chain: npt.NDArray[np.uint32]
    target: npt.NDArray[np.float32]

def pair_feature_lines(
    positions: npt.NDArray[np.float32],
    lines: list[tuple[npt.NDArray[np.uint32], bool, str]],
    curves: list[tuple[str, npt.NDArray[np.float32], bool]],
    *,
    max_distance: float,
    max_angle: float = 30.0,
    min_confidence: float = 0.5,
) -> list[LinePairing]:
    """Pairs feature lines with target curves (close, parallel, same kind, similar length) under the current
    fit; one :class:`LinePairing` per line, the curve index or why it stays free."""
