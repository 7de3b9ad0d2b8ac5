"""The subdivision cage fit on arrays (no ``bpy``): which cage vertices move, the Gauss–Newton rounds, the
matching of Blender's subdivided points to the kernel's stencils, and the distances reported.

The kernel's ``SubdivisionStencils`` give the limit points of the cage's Catmull–Clark subdivision as a
sparse matrix ``S``; they are Blender's Subdivision Surface points to float precision except near smooth
corners of a border (a border vertex of one face under *Boundary Smooth: All*), where Blender's patches
approximate the limit surface. Each round therefore takes the fine points as Blender computes them when
``evaluate`` is given (``blender.cage_fit`` evaluates the modifier), passes their difference from ``S x``
to the kernel as offsets, and lets the kernel solve with ``S`` as the Jacobian.
"""

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import transforms
from .errors import LayoutError

DEFAULT_LEVELS = 2
"""The subdivision level fitted by default (the modifier's render level)."""
DEFAULT_ROUNDS = 5
"""Gauss–Newton rounds by default."""
BOUNDARY_ITEMS = (
    ("ALL", "All", "Smooth the corners of open borders (Blender's default)"),
    ("PRESERVE_CORNERS", "Keep Corners", "Keep the corners of open borders where they are"),
)
"""Blender's Subdivision Surface *Boundary Smooth* choices: the fit must use the modifier's."""
MATCH_TOLERANCE = 1.0
"""Blender's subdivided points are paired with the stencils' when the two are each other's nearest and each
lies within this fraction of the shortest fine edge at its stencil point (they differ where Blender's patches
approximate the limit surface, or a loose edge makes a vertex non-manifold for OpenSubdiv)."""


class FitDistances(NamedTuple):
    """Distances of the subdivided surface's points to the target (world units)."""

    mean: float
    max: float
    matched: int  # fine points with a target point within the match distance
    count: int  # fine points on the surface


class CageFitOutcome(NamedTuple):
    """What a cage fit did."""

    positions: np.ndarray  # (N, 3) float64 world positions of the cage after the fit
    moved: np.ndarray  # (N,) bool: the cage vertices the fit was free to move
    before: FitDistances
    after: FitDistances
    rounds: int
    trusted: int  # fine points matched and trusted in the last round
    anchors: int  # anchors whose vertex's limit point was held
    fine_vertex_count: int  # points of the subdivided surface (cage vertices on no face not counted)
    exact: bool  # the rounds used Blender's own subdivided points (else the stencils alone)


def fit_defaults() -> dict:
    """The kernel's defaults of the fit (smoothness, max_distance, min_facing, damping, max_levels)."""
    return springwrap_kernel.subdivision_fit_defaults()


def movable_mask(vertex_count: int, on_face: np.ndarray, selection: np.ndarray, only_selected: bool) -> np.ndarray:
    """(N,) bool: the cage vertices the fit may move: on a face, and selected when asked."""
    movable = np.asarray(on_face, dtype=bool).copy()
    if only_selected:
        movable &= np.asarray(selection, dtype=bool)
    if movable.shape != (vertex_count,):
        raise ValueError(f"expected {vertex_count} flags, got {movable.shape}")
    return movable


def summarize(distances: np.ndarray) -> FitDistances:
    """Mean and max of the finite distances (NaN: off the surface or beyond the match distance)."""
    distances = np.asarray(distances, dtype=np.float64)
    finite = distances[np.isfinite(distances)]
    if finite.size == 0:
        return FitDistances(float("nan"), float("nan"), 0, int(distances.size))
    return FitDistances(float(finite.mean()), float(finite.max()), int(finite.size), int(distances.size))


def match_fine_points(
    stencil_points: np.ndarray,
    fine_quads: np.ndarray,
    blender_points: np.ndarray,
    blender_triangles: np.ndarray,
    on_surface: np.ndarray | None = None,
) -> np.ndarray | None:
    """For each stencil fine point on the surface (``on_surface``, default all), the index of Blender's
    subdivided point at the same place (-1 for the others: cage vertices on no face); None when they do not
    pair up as each other's nearest (up to coincident points), within :data:`MATCH_TOLERANCE` of the local fine
    edge length.

    Blender numbers its subdivided vertices its own way (cage vertices first, then per edge and per face, and
    the points of loose edges too); the stencils' numbering is another, so the two are paired by position
    once, at the start of a fit.
    """
    stencil_points = np.asarray(stencil_points, dtype=np.float64).reshape(-1, 3)
    blender_points = np.asarray(blender_points, dtype=np.float64).reshape(-1, 3)
    if on_surface is None:
        on_surface = np.ones(stencil_points.shape[0], dtype=bool)
    on_surface = np.asarray(on_surface, dtype=bool)
    if blender_points.shape[0] < np.count_nonzero(on_surface) or len(blender_triangles) == 0:
        return None
    mesh = springwrap_kernel.TargetMesh(
        transforms.as_float32_points(blender_points), np.ascontiguousarray(blender_triangles, dtype=np.uint32)
    )
    hits = mesh.nearest_vertices(transforms.as_float32_points(stencil_points[on_surface]))
    indices = np.asarray(hits.vertices, dtype=np.int64)
    if (indices < 0).any():
        return None
    quads = np.asarray(fine_quads, dtype=np.int64)
    edge_lengths = np.linalg.norm(stencil_points[quads] - stencil_points[np.roll(quads, -1, axis=1)], axis=2)
    shortest = np.full(stencil_points.shape[0], np.inf)
    np.minimum.at(shortest, quads.reshape(-1), edge_lengths.reshape(-1))
    np.minimum.at(shortest, np.roll(quads, -1, axis=1).reshape(-1), edge_lengths.reshape(-1))
    if np.any(np.asarray(hits.distances) > MATCH_TOLERANCE * shortest[on_surface]):
        return None
    # Each other's nearest: Blender's paired points find their stencil points back.
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    stencil_mesh = springwrap_kernel.TargetMesh(
        transforms.as_float32_points(stencil_points), np.ascontiguousarray(triangles, dtype=np.uint32)
    )
    # Coincident points (two cage vertices snapped to one target point) may pair either way: they are one point.
    own = np.flatnonzero(on_surface)
    back = np.asarray(stencil_mesh.nearest_vertices(transforms.as_float32_points(blender_points[indices])).vertices)
    apart = np.linalg.norm(stencil_points[back] - stencil_points[own], axis=1)
    if np.any((back != own) & (apart > 1e-3 * shortest[own])):
        return None
    matching = np.full(stencil_points.shape[0], -1, dtype=np.int64)
    matching[on_surface] = indices
    return matching


def fit_cage(
    target_mesh,
    cage_world: np.ndarray,
    face_corners: np.ndarray,
    face_sizes: np.ndarray,
    movable: np.ndarray,
    *,
    levels: int = DEFAULT_LEVELS,
    rounds: int = DEFAULT_ROUNDS,
    boundary: str = "ALL",
    smoothness: float | None = None,
    max_distance: float = 0.0,
    anchor_vertices: np.ndarray | None = None,
    anchor_points: np.ndarray | None = None,
    evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> CageFitOutcome:
    """Fit the cage (world positions) so that its level-``levels`` subdivided surface lies on ``target_mesh``.

    ``evaluate(cage_world)`` returns Blender's subdivided points and triangles for a cage (world space);
    without it, or when its points cannot be paired with the stencils', the stencils' surface is fitted.
    ``max_distance`` 0 means no limit. Anchors (cage vertex, world point) hold where the subdivided surface
    passes at their vertex: its limit point is pulled onto the anchor's point. Raises :class:`LayoutError` or a kernel error on bad input, before
    anything is changed (nothing here writes).
    """
    if rounds < 1:
        raise LayoutError("The fit needs at least one round")
    cage = np.asarray(cage_world, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(cage).all():
        raise LayoutError("The layout has NaN or infinite coordinates: the cage cannot be fitted")
    stencils = springwrap_kernel.SubdivisionStencils(
        cage.shape[0],
        np.ascontiguousarray(face_corners, dtype=np.uint32),
        np.ascontiguousarray(face_sizes, dtype=np.uint32),
        int(levels),
        boundary=boundary,
    )
    settings = {"fixed": np.ascontiguousarray(~np.asarray(movable, dtype=bool))}
    if smoothness is not None:
        settings["smoothness"] = float(smoothness)
    if max_distance > 0.0:
        settings["max_distance"] = float(max_distance)
    if anchor_vertices is not None and len(anchor_vertices):
        settings["anchor_vertices"] = np.ascontiguousarray(anchor_vertices, dtype=np.uint32)
        settings["anchor_points"] = transforms.as_float32_points(anchor_points)
    fit = springwrap_kernel.SubdivisionFit(stencils, **settings)
    positions = transforms.as_float32_points(cage)
    on_surface = np.asarray(stencils.on_surface(), dtype=bool)

    matching = None
    blender_points = None
    if evaluate is not None:
        blender_points, blender_triangles = evaluate(positions)
        matching = match_fine_points(
            stencils.apply(positions), stencils.fine_quads(), blender_points, blender_triangles, on_surface
        )

    def offsets_at(cage_points: np.ndarray, evaluated: np.ndarray | None = None) -> np.ndarray | None:
        """What Blender's subdivision adds to the stencils' points at this cage (None: the stencils alone)."""
        if matching is None:
            return None
        if evaluated is None:
            evaluated, _ = evaluate(cage_points)
        fine = stencils.apply(cage_points).astype(np.float64)
        exact = fine.copy()
        exact[on_surface] = np.asarray(evaluated, dtype=np.float64).reshape(-1, 3)[matching[on_surface]]
        return transforms.as_float32_points(exact - fine)

    def distances_at(cage_points: np.ndarray, offsets: np.ndarray | None) -> FitDistances:
        """The subdivided surface's distances to the target, with no distance limit."""
        fine = fit.fine_points(cage_points, offsets)[on_surface]
        return summarize(target_mesh.closest_points(fine).distances)

    offsets = offsets_at(positions, blender_points)
    before = distances_at(positions, offsets)
    trusted = 0
    for _ in range(rounds):
        positions, _, trusted = fit.round(target_mesh, positions, offsets)
        offsets = offsets_at(positions)
    after = distances_at(positions, offsets)
    return CageFitOutcome(
        positions=np.asarray(positions, dtype=np.float64),
        moved=~np.asarray(fit.fixed(), dtype=bool),
        before=before,
        after=after,
        rounds=rounds,
        trusted=int(trusted),
        anchors=int(sum(1 for vertex in (anchor_vertices if anchor_vertices is not None else []) if movable[vertex])),
        fine_vertex_count=int(np.count_nonzero(on_surface)),
        exact=matching is not None,
    )


def summary(outcome: CageFitOutcome, levels: int, milliseconds: float) -> str:
    """The report of a finished fit."""
    before, after = outcome.before, outcome.after
    text = (
        f"Fitted the level-{levels} subdivision surface ({outcome.fine_vertex_count} points) in {outcome.rounds} "
        f"rounds: distance to the target mean {before.mean:.4g} -> {after.mean:.4g}, "
        f"max {before.max:.4g} -> {after.max:.4g}; {int(outcome.moved.sum())} cage vertices free to move"
    )
    if outcome.anchors:
        text += f", {outcome.anchors} anchors held on the surface"
    text += f", in {milliseconds:.0f} ms"
    if not outcome.exact:
        text += " (Blender's subdivided points could not be paired with the fit's: the fit's own surface was used)"
    return text
