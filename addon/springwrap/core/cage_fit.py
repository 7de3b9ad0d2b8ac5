"""The subdivision cage fit on arrays (no ``bpy``): which cage vertices move, the Gauss–Newton rounds, the
matching of Blender's subdivided points to the kernel's stencils, and the distances reported.

The kernel's ``SubdivisionStencils`` give the limit points of the cage's Catmull–Clark subdivision as a
sparse matrix ``S``; they are Blender's Subdivision Surface points to float precision except near smooth
corners of a border (a border vertex of one face under *Boundary Smooth: All*), where Blender's patches
approximate the limit surface. Each round therefore takes the fine points as Blender computes them when
``evaluate`` is given (``blender.cage_fit`` evaluates the modifier), passes their difference from ``S x``
to the kernel as offsets, and lets the kernel solve with ``S`` as the Jacobian.
"""

import os
import threading
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
    kept_round: int = 0  # the round whose cage is the result


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


class FitSize(NamedTuple):
    """What a fit at one level costs, estimated before it starts."""

    levels: int
    points: int  # points of the subdivided surface (one per fine quad, about)
    bytes: int  # peak memory of a round
    seconds: float  # one round


BYTES_PER_FINE_POINT = 1900
"""Peak memory of a round per subdivided point: the stencils, the normal equations and their factor, Blender's
subdivided mesh (measured: a 1,352-vertex cage at level 6, 5.5M points, peaked at 10 GB)."""
SECONDS_PER_FINE_POINT = 14e-6
"""Time of a round per subdivided point (measured on the same fit: 77 s a round)."""
MEMORY_SHARE = 0.8
"""A fit may use this share of the memory the system has available when it starts."""
MODAL_SECONDS = 1.0
"""A fit estimated longer than this runs as a modal operator in the interface: progress, Esc between rounds."""


def fit_size(face_sizes: np.ndarray, levels: int) -> FitSize:
    """The estimated cost of a fit at ``levels`` of a cage with faces of ``face_sizes`` corners: an n-gon becomes
    n quads at level 1, and each quad four at the next."""
    quads = int(np.asarray(face_sizes, dtype=np.int64).sum()) * 4 ** (int(levels) - 1)
    return FitSize(int(levels), quads, quads * BYTES_PER_FINE_POINT, quads * SECONDS_PER_FINE_POINT)


def available_memory() -> int | None:
    """Bytes of memory the system has available now (Linux's MemAvailable, else free pages), None if unknown."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return None


def _gigabytes(count: int) -> str:
    return f"{count / 1e9:.2g} GB"


def check_levels(levels: int, max_levels: int) -> None:
    """Raise :class:`LayoutError` for a level outside 1 to ``max_levels`` (a script's ``levels=99``), naming the
    range: the fit never clamps it."""
    if not 1 <= int(levels) <= int(max_levels):
        raise LayoutError(f"Levels must be 1 to {int(max_levels)}, not {int(levels)}")


def check_fit_size(face_sizes: np.ndarray, levels: int, available: int | None) -> FitSize:
    """The :class:`FitSize` of the fit; raises :class:`LayoutError` when its memory would exceed
    :data:`MEMORY_SHARE` of ``available`` (bytes; None: unknown, not judged), saying why and which level fits."""
    size = fit_size(face_sizes, levels)
    if available is None or size.bytes <= MEMORY_SHARE * available:
        return size
    fitting = [fit_size(face_sizes, level) for level in range(int(levels) - 1, 0, -1)]
    fitting = [smaller for smaller in fitting if smaller.bytes <= MEMORY_SHARE * available]
    advice = (
        f"level {fitting[0].levels} ({fitting[0].points:,} points, about {_gigabytes(fitting[0].bytes)}) fits"
        if fitting
        else "no level fits: use a smaller cage"
    )
    raise LayoutError(
        f"Level {size.levels} of this cage has {size.points:,} subdivided points: a round needs about "
        f"{_gigabytes(size.bytes)} and {_gigabytes(available)} is available; {advice}"
    )


MAX_GROWTH = 0.1
"""A round whose max distance grows by more than this fraction makes the fit worse, whatever its mean (a fold or a
point thrown off the surface). Less growth is allowed with a smaller mean: over a hole the max is measured across
it to the far rim and grows a little as the cage settles."""


def _better(first: FitDistances, second: FitDistances) -> bool:
    """Whether ``first`` fits better than ``second``: a smaller mean distance (the fit's own aim) without the max
    growing by more than :data:`MAX_GROWTH`."""
    if not (np.isfinite(first.max) and np.isfinite(first.mean)):
        return False
    if not (np.isfinite(second.max) and np.isfinite(second.mean)):
        return True
    return first.mean < second.mean and first.max <= second.max * (1.0 + MAX_GROWTH)


class CageFitRun:
    """A fit, round by round: built (stencils, the kernel's fit, Blender's points paired) and measured when
    created, then :meth:`step` runs one Gauss–Newton round; :meth:`outcome` is the best round's cage (the first
    round makes the fit; a later round that makes it worse, :func:`_better`, is measured and set aside). See :func:`fit_cage` for the arguments.
    """

    def __init__(
        self,
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
    ) -> None:
        if rounds < 1:
            raise LayoutError("The fit needs at least one round")
        check_levels(levels, fit_defaults()["max_levels"])
        cage = np.asarray(cage_world, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(cage).all():
            raise LayoutError("The layout has NaN or infinite coordinates: the cage cannot be fitted")
        self.target_mesh = target_mesh
        self.rounds = int(rounds)
        self.evaluate = evaluate
        self.stencils = springwrap_kernel.SubdivisionStencils(
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
        anchored = 0
        if anchor_vertices is not None and len(anchor_vertices):
            settings["anchor_vertices"] = np.ascontiguousarray(anchor_vertices, dtype=np.uint32)
            settings["anchor_points"] = transforms.as_float32_points(anchor_points)
            anchored = int(sum(1 for vertex in anchor_vertices if movable[vertex]))
        self.anchors = anchored
        self.fit = springwrap_kernel.SubdivisionFit(self.stencils, **settings)
        self.positions = transforms.as_float32_points(cage)
        self.on_surface = np.asarray(self.stencils.on_surface(), dtype=bool)
        self.matching = None
        blender_points = None
        if evaluate is not None:
            blender_points, blender_triangles = evaluate(self.positions)
            self.matching = match_fine_points(
                self.stencils.apply(self.positions),
                self.stencils.fine_quads(),
                blender_points,
                blender_triangles,
                self.on_surface,
            )
        self.offsets = self._offsets_at(self.positions, blender_points)
        self.before = self._distances_at(self.positions, self.offsets)
        self.best = (self.positions, self.before, 0)  # (cage, its distances, the round that made it)
        self.round = 0
        self.trusted = 0

    @property
    def done(self) -> bool:
        """Every round has run."""
        return self.round >= self.rounds

    def _offsets_at(self, cage_points: np.ndarray, evaluated: np.ndarray | None = None) -> np.ndarray | None:
        """What Blender's subdivision adds to the stencils' points at this cage (None: the stencils alone)."""
        if self.matching is None:
            return None
        if evaluated is None:
            evaluated, _ = self.evaluate(cage_points)
        fine = self.stencils.apply(cage_points).astype(np.float64)
        exact = fine.copy()
        on_surface = self.on_surface
        exact[on_surface] = np.asarray(evaluated, dtype=np.float64).reshape(-1, 3)[self.matching[on_surface]]
        return transforms.as_float32_points(exact - fine)

    def _distances_at(self, cage_points: np.ndarray, offsets: np.ndarray | None) -> FitDistances:
        """The subdivided surface's distances to the target, with no distance limit."""
        fine = self.fit.fine_points(cage_points, offsets)[self.on_surface]
        return summarize(self.target_mesh.closest_points(fine).distances)

    def step(self) -> None:
        """One round from the last cage; the best cage so far is kept."""
        self.advance(self.solve())

    def solve(self, cancel=None) -> tuple:
        """The kernel's part of the next round (reads no Blender data, so it may run in a worker thread: the
        kernel frees the GIL). ``cancel``: a ``springwrap_kernel.CancelFlag`` the round asks inside its long
        loops; once set, the round raises ``springwrap_kernel.CancelledError`` and nothing here changed."""
        return self.fit.round(self.target_mesh, self.positions, self.offsets, cancel=cancel)

    def advance(self, solved: tuple) -> None:
        """Take a round :meth:`solve` made: Blender's subdivision at its cage (``evaluate``), its distances, the
        best cage so far kept."""
        self.positions, _, self.trusted = solved
        self.offsets = self._offsets_at(self.positions)
        self.round += 1
        distances = self._distances_at(self.positions, self.offsets)
        if self.round == 1 or _better(distances, self.best[1]):  # the first round is the fit; the others refine it
            self.best = (self.positions, distances, self.round)

    def outcome(self) -> CageFitOutcome:
        """What the fit did: the best cage seen, and its distances."""
        positions, after, kept = self.best
        return CageFitOutcome(
            positions=np.asarray(positions, dtype=np.float64),
            moved=~np.asarray(self.fit.fixed(), dtype=bool),
            before=self.before,
            after=after,
            rounds=self.round,
            trusted=int(self.trusted),
            anchors=self.anchors,
            fine_vertex_count=int(np.count_nonzero(self.on_surface)),
            exact=self.matching is not None,
            kept_round=kept,
        )


class RoundWorker:
    """The kernel's part of one round (:meth:`CageFitRun.solve`) in a worker thread, so that the interface keeps
    handling events (Esc) while it runs: :meth:`stop` sets its cancellation flag, which the kernel asks inside
    its loops, and waits for the thread; :meth:`outcome` is the solved round (or raises what the round raised)."""

    def __init__(self, run: CageFitRun) -> None:
        self.cancel_flag = springwrap_kernel.CancelFlag()
        self._outcome = None
        self._error = None
        self._thread = threading.Thread(target=self._solve, args=(run,), name="springwrap fit round", daemon=True)
        self._thread.start()

    def _solve(self, run: CageFitRun) -> None:
        try:
            self._outcome = run.solve(self.cancel_flag)
        except BaseException as error:  # noqa: BLE001  (handed to the main thread, raised there by outcome())
            self._error = error

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def outcome(self) -> tuple:
        """The solved round (waits for it); raises the round's exception."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._outcome

    def stop(self) -> None:
        """Ask the round to stop and wait for the thread (the kernel answers within milliseconds)."""
        self.cancel_flag.cancel()
        self._thread.join()


def fit_cage(target_mesh, cage_world: np.ndarray, face_corners, face_sizes, movable, **options) -> CageFitOutcome:
    """Fit the cage (world positions) so that its level-``levels`` subdivided surface lies on ``target_mesh``.

    ``evaluate(cage_world)`` returns Blender's subdivided points and triangles for a cage (world space);
    without it, or when its points cannot be paired with the stencils', the stencils' surface is fitted.
    ``max_distance`` 0 means no limit. Anchors (cage vertex, world point) hold where the subdivided surface
    passes at their vertex: its limit point is pulled onto the anchor's point. Every round runs; the best cage
    is the result (:class:`CageFitRun`). Raises :class:`LayoutError` or a kernel error on bad input, before
    anything is changed (nothing here writes).
    """
    run = CageFitRun(target_mesh, cage_world, face_corners, face_sizes, movable, **options)
    while not run.done:
        run.step()
    return run.outcome()


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
    if outcome.kept_round != outcome.rounds:
        text += f"; kept round {outcome.kept_round}'s cage (the later rounds made the fit worse)"
    text += f", in {milliseconds:.0f} ms"
    if not outcome.exact:
        text += " (Blender's subdivided points could not be paired with the fit's: the fit's own surface was used)"
    return text
