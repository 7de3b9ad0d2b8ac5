"""Parts: pieces of a layout the target does not have (eyeballs, teeth, tongue, lashes), which follow the
deformation of the layout's surface around them and are never pulled onto the target. Numpy and the kernel,
no ``bpy``.

Which vertices are parts (:func:`plan_parts`), per separate piece of the layout (its connected components,
``springwrap_kernel.layout_pieces``):

- the **Surface** group's pieces are wrapped like the body, whatever the guess;
- the **Follow** and **Follow Soft** groups' vertices are parts (soft: each vertex follows its own
  neighbourhood; else each connected piece of them moves rigidly), whatever the guess, except the vertices
  holding an anchor or a curve constraint (those are wrapped onto their targets);
- with **Find Parts** on, every other piece that the target's surface does not need (:func:`guess_parts`:
  the target points closest to most of its vertices are not clearly nearer to it than to the layout's largest
  piece:
  eyeballs behind the lids, teeth inside the lips, lashes in front of them, anything away from the target)
  is a part: rigid, or soft when it is an open strip (lashes, :func:`soft_guess`). Pieces without faces
  (loose edge chains), and pieces holding an anchor or a curve constraint, are never guessed.

The wrap leaves the parts out of the target's pull (the solver's free vertices) and moves them by the
surface's motion from the wrap's start (``springwrap_kernel.SurfaceFollower``; in the wrap's result, by the surface
it holds on the target alone, and each rigid piece that its own skin covers placed by that skin's registration onto
the target, ``core.part_registration``: :func:`follow`). With parts found or chosen, the
surface the target does not show (:func:`unseen_surface`: the inside of the mouth behind the lips, the socket
behind a closing eyelid) is left out of the pull too: the springs carry it with the skin around it, so that the
parts following it are not dragged onto the lips' or the lids' outer skin.
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import part_registration
from .errors import LayoutError
from .follow import restrict

PART_ATTRIBUTE = "springwrap_part"
"""POINT INT attribute the wrap writes: 2 a rigid part's vertex, 1 a soft part's, 0 the surface (the read-out
does not judge a part's distance to the target)."""
CLAIMED_SHARE = 0.5
"""A piece is needed by the target's surface when more than this share of its vertices claim their closest target
point (see :data:`MAIN_TOLERANCE`)."""
MAIN_TOLERANCE = 2.0
"""A piece's vertex claims its closest target point when it is nearer to it than the largest piece is by more than
this many times the largest piece's median distance to the target (how far the alignment left it)."""
MAIN_SAMPLE = 4000
"""Vertices of the largest piece measured for that median, at most (evenly spread through its numbering)."""
STRIP_RATIO = 0.5
"""An open piece whose second principal extent is below this share of its first is a strip (lashes): soft."""


UNSEEN_FACING = -0.5
"""A surface vertex faces away from the target where the cosine between its normal and its closest target point's
normal is below this (the mouth's inside behind the lips looks inwards, the lips' skin outwards).

A closed template mouth onto an open one (``benchmarks/parts.py``'s expression cases) puts the lower lip's midline
in the target's open mouth, facing away from its closest target point: it is left free and carried by the springs.
That is not what drags the lower teeth: the skin held on the target round them slides along it too (within 5 mm of
them it carries 0.33 to 0.39 of its true motion, 0.67 to 0.70 with the lower lip anchored); pulling the lip in the
open mouth, or freeing its corners in the safeguard, changed the teeth's max error by under 2 %."""
UNSEEN_DEPTH = 4.0
"""A surface vertex is hidden inside the target when it lies behind its closest target point by more than this many
times the surface's median distance to the target (how far the alignment left it)."""


class PartPlan(NamedTuple):
    """Which layout vertices are parts and how each piece of them follows the surface."""

    parts: np.ndarray  # (N,) bool: the vertex follows the surface (no pull to the target)
    soft: np.ndarray  # (N,) bool: a part vertex that follows its own neighbourhood (else its piece moves rigidly)
    pieces: np.ndarray  # (N,) int64 piece number of each vertex (the layout's connected components)
    rows: tuple  # (PieceRow, ...): the pieces treated as parts, for the report
    unseen: np.ndarray | None = None  # (N,) bool surface vertices the target does not show (no pull), or None

    @property
    def any(self) -> bool:
        return bool(self.parts.any())


class PieceRow(NamedTuple):
    """One piece treated as a part: its number, vertex count, how it follows and why."""

    piece: int
    vertices: int
    mode: str  # "rigid", "soft" or "mixed"
    reason: str  # "found", "Follow group"


def layout_pieces(topology) -> np.ndarray:
    """(N,) int64 piece number of each layout vertex (``topology``: a ``core.subdivision.LayoutTopology``)."""
    edges = np.ascontiguousarray(np.asarray(topology.edges).reshape(-1, 2), dtype=np.uint32)
    return springwrap_kernel.layout_pieces(int(topology.vertex_count), edges).astype(np.int64)


def fan_triangles(face_corners: np.ndarray, face_sizes: np.ndarray, keep_face: np.ndarray) -> np.ndarray:
    """(T, 3) int64 triangles of the kept faces, each cut as a fan from its first corner."""
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    fans = np.where(np.asarray(keep_face, dtype=bool), np.maximum(sizes - 2, 0), 0)
    faces = np.repeat(np.arange(sizes.size), fans)
    step = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans)
    first = starts[faces]
    return np.stack([corners[first], corners[first + step + 1], corners[first + step + 2]], axis=1)


def faces_without(topology, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(face_corners, face_sizes) of ``topology``'s faces with no corner among ``vertices`` ((N,) bool)."""
    sizes = np.asarray(topology.face_sizes, dtype=np.int64).reshape(-1)
    corners = np.asarray(topology.face_corners, dtype=np.int64).reshape(-1)
    face_of_corner = np.repeat(np.arange(sizes.size), sizes)
    touched = np.zeros(sizes.size, dtype=bool)
    np.logical_or.at(touched, face_of_corner, np.asarray(vertices, dtype=bool)[corners])
    kept = ~touched[face_of_corner]
    return (
        np.ascontiguousarray(corners[kept], dtype=np.uint32),
        np.ascontiguousarray(sizes[~touched], dtype=np.uint32),
    )


def face_pieces(topology, pieces: np.ndarray) -> np.ndarray:
    """(F,) int64 piece of each face (its first corner's)."""
    return np.asarray(pieces, dtype=np.int64)[face_corners_first(topology)]


def guess_parts(world_positions: np.ndarray, topology, pieces: np.ndarray, target_mesh, pinned: np.ndarray) -> set:
    """The pieces the target's surface does not need (see the module's docstring): a set of piece numbers.

    ``target_mesh`` is a ``core.target.CentredMesh``; ``pinned`` (N,) bool marks vertices holding an anchor or a
    curve constraint (their pieces are never guessed)."""
    world_positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    counts = np.bincount(pieces)
    if counts.size < 2:
        return set()
    faced = np.zeros(counts.size, dtype=bool)
    faced[face_pieces(topology, pieces)] = True
    main = int(np.argmax(np.where(faced, counts, -1)))
    keep = face_pieces(topology, pieces) == main
    triangles = fan_triangles(topology.face_corners, topology.face_sizes, keep)
    candidates = [piece for piece in range(counts.size) if piece != main and faced[piece]]
    pinned_pieces = set(np.unique(pieces[np.asarray(pinned, dtype=bool)]).tolist())
    candidates = [piece for piece in candidates if piece not in pinned_pieces]
    if not candidates or triangles.size == 0:
        return set()
    origin = np.asarray(target_mesh.origin, dtype=np.float64)
    try:
        main_mesh = springwrap_kernel.TargetMesh(
            np.ascontiguousarray(world_positions - origin, dtype=np.float32),
            np.ascontiguousarray(triangles, dtype=np.uint32),
        )
    except springwrap_kernel.SpringwrapError:
        return set()  # the largest piece has no surface to compare with (every face degenerate)
    chosen = np.flatnonzero(np.isin(pieces, candidates))
    closest = target_mesh.closest_points(world_positions[chosen])
    target_points = np.asarray(closest.positions, dtype=np.float64)
    own = np.linalg.norm(target_points - world_positions[chosen], axis=1)
    main_hits = main_mesh.closest_points(np.ascontiguousarray(target_points - origin, dtype=np.float32))
    main_distance = np.asarray(main_hits.distances, dtype=np.float64)
    # The largest piece's own distance from the target (how well it is aligned) is the tolerance: a vertex claims
    # its target point only when it is clearly nearer to it than the largest piece is.
    main_vertices = np.flatnonzero(pieces == main)
    sample = main_vertices[:: max(1, main_vertices.size // MAIN_SAMPLE)]
    tolerance = MAIN_TOLERANCE * float(np.median(target_mesh.closest_points(world_positions[sample]).distances))
    claimed = own + tolerance < main_distance
    guessed = set()
    for piece in candidates:
        members = pieces[chosen] == piece
        if claimed[members].mean() <= CLAIMED_SHARE:
            guessed.add(piece)
    return guessed


def soft_guess(world_positions: np.ndarray, topology, members: np.ndarray) -> bool:
    """Whether a guessed piece (``members``: its vertex numbers) follows softly: an open strip (it has border
    edges, and its second principal extent is below :data:`STRIP_RATIO` of its first), as lashes are."""
    points = np.asarray(world_positions, dtype=np.float64)[members]
    if points.shape[0] < 3:
        return False
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if not spread[0] > 0.0 or spread[1] >= STRIP_RATIO * spread[0]:
        return False
    member = np.zeros(np.asarray(world_positions).shape[0], dtype=bool)
    member[members] = True
    corners = np.asarray(topology.face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(topology.face_sizes, dtype=np.int64).reshape(-1)
    following = np.arange(corners.size) + 1
    ends = np.cumsum(sizes)
    following[ends - 1] = ends - sizes  # each face's last corner goes round to its first
    a, b = corners, corners[following]
    inside = member[a] & member[b]
    keys = np.minimum(a, b)[inside] * (corners.max() + 1) + np.maximum(a, b)[inside]
    _unique, uses = np.unique(keys, return_counts=True)
    return bool((uses == 1).any())


class PartGroups(NamedTuple):
    """The artist's choices, each (N,) bool or None when not set: Follow, Follow Soft, Surface."""

    follow: np.ndarray | None = None
    soft: np.ndarray | None = None
    surface: np.ndarray | None = None


def plan_parts(
    layout_name: str,
    world_positions: np.ndarray,
    topology,
    groups: PartGroups,
    find: bool,
    target_mesh=None,
    pinned: np.ndarray | None = None,
) -> PartPlan:
    """Which vertices are parts (see the module's docstring). ``find``: guess the pieces the target does not
    need (``target_mesh``, a ``CentredMesh``, is then required); with parts and ``target_mesh``, the plan's
    ``unseen`` surface (:func:`unseen_surface`). Raises :class:`LayoutError` when every vertex
    would be a part (nothing left to wrap and follow)."""
    count = int(topology.vertex_count)
    pieces = layout_pieces(topology)
    pinned = np.zeros(count, dtype=bool) if pinned is None else np.asarray(pinned, dtype=bool)
    parts = np.zeros(count, dtype=bool)
    soft = np.zeros(count, dtype=bool)
    reasons: dict[int, str] = {}
    surface_pieces = set() if groups.surface is None else set(np.unique(pieces[groups.surface]).tolist())
    if find and target_mesh is not None:
        for piece in sorted(guess_parts(world_positions, topology, pieces, target_mesh, pinned) - surface_pieces):
            members = np.flatnonzero(pieces == piece)
            parts[members] = True
            soft[members] = soft_guess(world_positions, topology, members)
            reasons[piece] = "found"
    chosen = np.zeros(count, dtype=bool)
    for flags in (groups.follow, groups.soft):
        if flags is not None:
            chosen |= np.asarray(flags, dtype=bool)
    if groups.surface is not None:
        chosen &= ~np.isin(pieces, sorted(surface_pieces))
    chosen &= ~pinned  # an anchor or a curve constraint holds its vertex: it is wrapped
    parts |= chosen
    if groups.soft is not None:
        soft[chosen] = np.asarray(groups.soft, dtype=bool)[chosen]
    if groups.follow is not None:
        soft[chosen & np.asarray(groups.follow, dtype=bool) & ~soft] = False
    for piece in np.unique(pieces[chosen]).tolist():
        reasons[piece] = "Follow group"
    soft &= parts
    if count and parts.all():
        raise LayoutError(
            f"Every vertex of layout '{layout_name}' would follow the surface as a part: nothing is left to wrap "
            "onto the target for them to follow. Take the body out of the Follow groups (or put it in the "
            "Surface group)"
        )
    rows = []
    for piece in sorted(reasons):
        members = (pieces == piece) & parts
        softness = soft[members]
        mode = "soft" if softness.all() else "rigid" if not softness.any() else "mixed"
        rows.append(PieceRow(int(piece), int(members.sum()), mode, reasons[piece]))
    unseen = None
    if target_mesh is not None and parts.any():
        unseen = unseen_surface(world_positions, topology, parts, pieces, target_mesh, pinned)
    return PartPlan(parts, soft, pieces, tuple(rows), unseen)


def vertex_normals(world_positions: np.ndarray, topology) -> np.ndarray:
    """(N, 3) float64 unit area-weighted normals of the layout's vertices (zero for a vertex without a face)."""
    points = np.ascontiguousarray(np.asarray(world_positions, dtype=np.float64).reshape(-1, 3))
    corners = np.asarray(topology.face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(topology.face_sizes, dtype=np.int64).reshape(-1)
    faces = springwrap_kernel.face_normals(
        points, np.ascontiguousarray(corners, dtype=np.uint32), np.ascontiguousarray(sizes, dtype=np.uint32)
    )
    normals = np.zeros_like(points)
    np.add.at(normals, corners, np.repeat(np.asarray(faces, dtype=np.float64), sizes, axis=0))
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0.0)


def beside_parts(world_positions: np.ndarray, topology, parts: np.ndarray, pieces: np.ndarray, origin) -> np.ndarray:
    """(N,) bool: the vertices within reach of a part's faces: nearer to them than the radius of the piece they are
    nearest to (its vertices' mean distance from their centre: an eyeball's socket, a mouth round its teeth)."""
    world_positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    beside = np.zeros(world_positions.shape[0], dtype=bool)
    faced = np.asarray(parts, dtype=bool)[face_corners_first(topology)]
    triangles = fan_triangles(topology.face_corners, topology.face_sizes, faced)
    if triangles.size == 0:
        return beside
    radius = np.zeros(int(pieces.max()) + 1)
    for piece in np.unique(pieces[parts]).tolist():
        members = world_positions[pieces == piece]
        radius[piece] = float(np.linalg.norm(members - members.mean(axis=0), axis=1).mean())
    try:
        part_mesh = springwrap_kernel.TargetMesh(
            np.ascontiguousarray(world_positions - origin, dtype=np.float32),
            np.ascontiguousarray(triangles, dtype=np.uint32),
        )
    except springwrap_kernel.SpringwrapError:
        return beside  # every part face degenerate
    hits = part_mesh.closest_points(np.ascontiguousarray(world_positions - origin, dtype=np.float32))
    found = np.asarray(hits.triangles) >= 0
    nearest_piece = pieces[triangles[np.maximum(np.asarray(hits.triangles), 0), 0]]
    beside[found] = np.asarray(hits.distances, dtype=np.float64)[found] < radius[nearest_piece[found]]
    return beside


def face_corners_first(topology) -> np.ndarray:
    """(F,) int64 the first corner of each face."""
    sizes = np.asarray(topology.face_sizes, dtype=np.int64).reshape(-1)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    return np.asarray(topology.face_corners, dtype=np.int64).reshape(-1)[starts] if sizes.size else starts


def unseen_surface(
    world_positions: np.ndarray, topology, parts: np.ndarray, pieces: np.ndarray, target_mesh, pinned: np.ndarray
) -> np.ndarray:
    """(N,) bool: the surface vertices (not ``parts``, not ``pinned``) beside the parts (:func:`beside_parts`) that
    the target does not show, facing away from their closest target point (:data:`UNSEEN_FACING`) or hidden deep
    inside the target (:data:`UNSEEN_DEPTH`); none when most of the surface faces away from the target (its
    normals, or the layout's, point inwards). ``target_mesh``: a ``CentredMesh``."""
    world_positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    parts = np.asarray(parts, dtype=bool)
    unseen = np.zeros(world_positions.shape[0], dtype=bool)
    normals = vertex_normals(world_positions, topology)
    surface = np.flatnonzero(~parts & ~np.asarray(pinned, dtype=bool))
    surface = surface[np.linalg.norm(normals[surface], axis=1) > 0.0]
    if surface.size == 0:
        return unseen
    hits = target_mesh.closest_points(world_positions[surface])
    found = np.asarray(hits.triangles) >= 0
    # The alignment's own distance from the target (over the whole surface) is the depth's tolerance; a layout
    # lying exactly on the target has none: depths within rounding are not hidden.
    size = float(np.linalg.norm(np.ptp(world_positions, axis=0)))
    tolerance = max(UNSEEN_DEPTH * float(np.median(np.asarray(hits.distances, dtype=np.float64)[found])), 1e-6 * size)
    target_normals = np.asarray(target_mesh.kernel.face_normals(), dtype=np.float64)[np.asarray(hits.triangles)]
    facing = np.einsum("ij,ij->i", normals[surface], target_normals)
    if not np.median(facing[found]) > 0.0:
        return unseen  # the surface mostly faces away: the target's normals (or the layout's) point inwards
    depth = -np.einsum(
        "ij,ij->i", world_positions[surface] - np.asarray(hits.positions, dtype=np.float64), target_normals
    )
    near = found & beside_parts(world_positions, topology, parts, pieces, np.asarray(target_mesh.origin))[surface]
    hidden = near & ((facing < UNSEEN_FACING) | (depth > tolerance))
    unseen[surface[hidden]] = True
    return unseen


HELD_SHARE = 0.5
"""The parts follow only the surface the wrap holds on the target (:func:`follow`'s ``held``) when it is at least
this share of the surface; else (a wrap stopped early) the whole surface."""


RIGID_NEIGHBOURS = 1024
"""The surface vertices each vertex of a rigid piece is bound to (the kernel's most): a piece's binding reaches past
the skin that folds or stretches over it (lips round the teeth and tongue, a closing eyelid) to the skin that moves
as one body with it, which :data:`ROBUST_ROUNDS` then picks out."""
ROBUST_ROUNDS = 16
"""Reweighting rounds of a rigid piece's fit (the kernel's ``robust_rounds``): each round weights down the bound
surface vertices the last fit carries badly, so the piece follows the largest part of its surroundings that moves
rigidly, not the average of skin moving several ways. Measured (``benchmarks/parts.py``, the tongue's mean error, %
of the diagonal, wrap twice on expression / face-expression / head-nose / heavy): 64 neighbours and no rounds 0.217 /
0.196 / 0.181 / 0.046; 64 and 8 rounds 0.223 / 0.116 / 0.127 / 0.055; 1024 and 16 rounds 0.161 / 0.127 / 0.096 /
0.017."""


class PartFollower(NamedTuple):
    """The parts bound to the layout's surface at rest (:func:`make_follower`)."""

    kernel: object  # springwrap_kernel.SurfaceFollower bound to every surface vertex
    rest: np.ndarray  # (N, 3) float64 the layout where it was bound (the wrap's start)
    neighbours: int | None  # the surface vertices bound to each rigid piece's vertex (None: RIGID_NEIGHBOURS)


def bind_parts(plan: PartPlan, rest: np.ndarray, surface: np.ndarray, neighbours: int | None = None):
    """A ``springwrap_kernel.SurfaceFollower`` binding the plan's parts at ``rest`` ((N, 3)) to the ``surface``
    vertices ((N,) bool, no part among them). Each connected piece of rigid part vertices moves as one, bound to the
    ``neighbours`` (default :data:`RIGID_NEIGHBOURS`) surface vertices nearest to each of its vertices and fitted
    with :data:`ROBUST_ROUNDS` reweighting rounds; soft vertices each on their own."""
    part_vertices = np.flatnonzero(plan.parts)
    rigid_pieces = np.where(plan.soft[part_vertices], -1, plan.pieces[part_vertices])
    # Soft vertices share one piece number (its flag soft); each rigid piece has its own.
    numbers, renumbered = np.unique(rigid_pieces, return_inverse=True)
    rigid = numbers >= 0
    return springwrap_kernel.SurfaceFollower(
        np.ascontiguousarray(rest[surface]),
        np.ascontiguousarray(rest[part_vertices]),
        np.ascontiguousarray(renumbered, dtype=np.uint32),
        np.ascontiguousarray(rigid),
        neighbours=RIGID_NEIGHBOURS if neighbours is None else int(neighbours),
        robust_rounds=ROBUST_ROUNDS,
    )


def make_follower(plan: PartPlan, positions: np.ndarray, neighbours: int | None = None) -> PartFollower:
    """The plan's parts bound to the rest of the layout at ``positions`` ((N, 3), any frame: :func:`follow` must
    be given the same frame)."""
    positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
    return PartFollower(bind_parts(plan, positions, ~plan.parts, neighbours), positions, neighbours)


def follow(
    follower: PartFollower,
    plan: PartPlan,
    positions: np.ndarray,
    held: np.ndarray | None = None,
    target=None,
    placed: list | None = None,
):
    """``positions`` ((N, 3), the frame the follower was made in) with the parts moved by the surface's motion.

    ``held`` (optional, (N,) bool): the surface vertices the wrap holds on the target (its face points). When
    they are at least :data:`HELD_SHARE` of the surface, the parts follow them alone (bound again, at rest, to
    those): the surface left off the target (the free and unseen skin round a mouth, lips that did not reach
    their place) is carried by the springs and lags behind the skin the target holds. With ``target`` (a
    ``core.target.CentredMesh`` in the same frame) too, each rigid piece that its own held skin covers is placed by
    that skin's registration onto the target (``core.part_registration``): skin that slid does not drag it; the
    pieces so placed are appended to ``placed`` (optional list) for the report."""
    positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
    surface = ~plan.parts
    kernel = follower.kernel
    registered = False
    if held is not None:
        kept = surface & np.asarray(held, dtype=bool)
        if kept.sum() >= HELD_SHARE * surface.sum():
            registered = target is not None
            if not np.array_equal(kept, surface):
                surface = kept
                kernel = bind_parts(plan, follower.rest, surface, follower.neighbours)
    positions[plan.parts] = kernel.apply(np.ascontiguousarray(positions[surface]))
    if registered:
        positions = part_registration.place_pieces(plan, follower.rest, positions, surface, target, placed)
    return positions


def part_codes(plan: PartPlan) -> np.ndarray:
    """(N,) int32 values of :data:`PART_ATTRIBUTE`: 2 rigid part, 1 soft part, 0 surface."""
    return np.where(plan.parts, np.where(plan.soft, 1, 2), 0).astype(np.int32)


def report_text(plan: PartPlan, placed=()) -> str:
    """One line saying which pieces followed the surface and how, or "" when none did; ``placed``: the pieces placed
    by their own skin's registration on the target (``core.part_registration``)."""
    if not plan.rows:
        return ""
    placed = set(placed)
    described = ", ".join(
        f"piece {row.piece} ({row.vertices} vertices, {row.mode}"
        + (", placed by its skin on the target" if row.piece in placed else "")
        + f", {row.reason})"
        for row in plan.rows
    )
    total = int(plan.parts.sum())
    text = f"Parts: {len(plan.rows)} pieces ({total} vertices) followed the surface, not the target: {described}"
    unseen = 0 if plan.unseen is None else int(plan.unseen.sum())
    if unseen:
        text += f"; {unseen} surface vertices the target does not show (facing away or inside it) were not pulled"
    return text


def surface_readout(readout, part_flags: np.ndarray | None):
    """The quality read-out (``core.quality.Readout``) of the surface alone: the parts' distances and stretch left
    out (a part is off the target by design), the flips and the diagonal as they are. ``part_flags`` None or
    without a part: ``readout`` itself."""
    if readout is None or part_flags is None or not np.asarray(part_flags).any():
        return readout
    kept = ~np.asarray(part_flags, dtype=bool)
    return readout._replace(distances=readout.distances[kept], stretch=readout.stretch[kept])


def cut_out(topology, inputs, plan: PartPlan, positions: np.ndarray, region: np.ndarray | None = None):
    """(``core.follow.Restriction``, its inputs): the layout without its part pieces, for the solver, so that the
    parts take no part in the surface's wrap at all (its statistics, such as the mean edge length, and its
    correspondences are the surface's alone); every part vertex is written back as it was, for :func:`follow` to
    move. ``region`` (optional, (N,) bool): re-settle only these vertices of the surface (the caller holds the
    others, ``core.follow.held``). A part vertex that shares a face with the surface (a Follow group that cuts a
    piece) stays in the solve as a free vertex. None when there is no part to leave out."""
    if not plan.any:
        return None
    solved = ~plan.parts if region is None else np.asarray(region, dtype=bool) & ~plan.parts
    curves, plane = inputs.curve_vertices, inputs.plane_vertices
    cut = restrict(topology, inputs._replace(curve_vertices=None, plane_vertices=None), solved, positions)
    if cut is None:
        return None
    restriction, cut_inputs = cut
    number = np.full(int(topology.vertex_count), -1, dtype=np.int64)
    number[restriction.kept] = np.arange(restriction.kept.size)
    if curves is not None:
        chained = number[np.asarray(curves, dtype=np.int64)]
        if (chained < 0).any():
            return None  # a curve runs through a part (never planned so: only by a caller's own inputs)
        cut_inputs = cut_inputs._replace(curve_vertices=np.ascontiguousarray(chained, dtype=np.uint32))
    if plane is not None:
        held = number[np.asarray(plane, dtype=np.int64)]
        cut_inputs = cut_inputs._replace(plane_vertices=np.ascontiguousarray(held[held >= 0], dtype=np.uint32))
    return restriction, cut_inputs
