"""Mirroring a surfaced half of a layout (paper, section 3, "Mirroring example"; no ``bpy``).

The layout's surfaced half is reflected across a plane; the vertices on the plane (the **seam**)
are snapped onto it and shared by both halves; the new half's faces are the old ones with their
winding reversed (so both halves face the same way). Then the new half is wrapped onto the
target's other half, with the surfaced half held where it is and the seam held on the plane.

Everything here is plain numpy on world-space arrays: the operator (``operators.mirror``) reads,
``blender.mirror`` duplicates the mesh, this module decides and computes.

- The **plane** is the layout object's local X, Y or Z plane (``axis='X'``: the plane x = 0 of
  the object, normal its X axis), or the same plane of another object (an empty): its local YZ
  plane for X, XZ for Y, XY for Z, as Blender's Mirror modifier does with a mirror object. The
  reflection is the true reflection across that plane in world space (where the target is), so
  it stays right for a non-uniformly scaled layout object.
- A vertex is on the **seam** when its distance from the plane is at most ``weld_fraction``
  times the mean length of its own edges (a local measure: a body's layout is dense on the face
  and sparse on the back), or when it is on the layout's open border at the plane wherever a wrap
  left it (``mirror_seam.border_seam``). Seam vertices are brought back onto the plane.
- A **crossing** face has corners off the seam clearly on both sides (beyond their weld distance):
  the surfaced half spills over the plane there, and its mirror overlaps it. It is reported.
- A plane that **misses** the layout (no vertex within its weld distance) is refused; so is a layout
  that already covers both sides of it, and one whose open border at the plane drifted too far from it
  to be welded (``mirror_seam``).
"""

from typing import NamedTuple

import numpy as np

from . import anchors as anchor_module
from . import defaults, layout_state, mirror_seam, transforms
from .errors import LayoutError
from .layout_state import LayoutState
from .mirror_seam import vertex_edge_lengths
from .wrap_inputs import check_rest_edges

AXES = ("X", "Y", "Z")
"""The mirror axes: the plane is perpendicular to this axis of the layout (or of the mirror object)."""

DEFAULT_WELD_FRACTION = defaults.WELD_FRACTION
"""Default weld distance of a vertex: this fraction of the mean length of its edges (``core.defaults``)."""


class Plane(NamedTuple):
    """A plane in world space: a point and a unit normal (float64)."""

    point: np.ndarray  # (3,)
    normal: np.ndarray  # (3,) unit


class MirrorPlan(NamedTuple):
    """What mirroring a layout will do, decided before anything is written."""

    seam: np.ndarray  # (N,) bool: vertices on the plane, shared by both halves
    distances: np.ndarray  # (N,) float64 signed distances from the plane (world units)
    weld_distances: np.ndarray  # (N,) float64 each vertex's own weld distance
    duplicate_faces: np.ndarray  # (F,) bool: faces that get a mirrored copy (not lying in the plane)
    duplicate_edges: np.ndarray  # (E,) bool: loose edges that get a mirrored copy
    crossing_faces: np.ndarray  # (K,) int64 faces with corners clearly on both sides
    in_plane_faces: int  # faces lying in the plane (not copied: they would be their own mirror)
    drifted: np.ndarray  # (N,) bool: seam vertices beyond their weld distance (an open border a wrap moved off it)


class MirrorLayout(NamedTuple):
    """The mirrored layout's vertices, given where each came from (``source``) and whether it is a copy."""

    positions: np.ndarray  # (M, 3) float64 world positions
    state: LayoutState  # face-points of the surfaced half kept; copies are space-points
    rest: np.ndarray  # (M, 3) float64 world rest shape (the template's, reflected the same way)
    seam: np.ndarray  # (M,) bool
    is_copy: np.ndarray  # (M,) bool: the new, mirrored half (the seam is not a copy)


def plane_from_matrix(matrix_world, axis: str) -> Plane:
    """The plane perpendicular to ``axis`` (``'X'``, ``'Y'``, ``'Z'``) through the origin of an object.

    ``matrix_world`` is the object's 4x4 world matrix: the plane is its local plane ``axis = 0``
    in world space (normal: the inverse transpose of the matrix applied to the local axis, which is
    the plane's true normal under any scale or shear). Raises :class:`LayoutError` for an unknown
    axis or a matrix that cannot be inverted (zero scale).
    """
    if axis not in AXES:
        raise LayoutError(f"The mirror axis must be one of {', '.join(AXES)}, not {axis!r}")
    matrix = np.asarray(matrix_world, dtype=np.float64).reshape(4, 4)
    if not np.all(np.isfinite(matrix)):
        raise LayoutError("The mirror plane's object has a NaN or infinite transform: its plane is undefined")
    if not transforms.is_invertible(matrix):
        raise LayoutError("The mirror plane's object has zero scale: its plane is undefined")
    linear = matrix[:3, :3]
    normal = np.linalg.inv(linear).T @ np.eye(3)[AXES.index(axis)]
    length = float(np.linalg.norm(normal))
    if not np.isfinite(length) or length == 0.0:
        raise LayoutError("The mirror plane's object has zero scale: its plane is undefined")
    return Plane(matrix[:3, 3].copy(), normal / length)


def signed_distances(points: np.ndarray, plane: Plane) -> np.ndarray:
    """(N,) float64 signed distances of ``points`` from ``plane`` (positive on the normal's side)."""
    return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - plane.point) @ plane.normal


def reflect(points: np.ndarray, plane: Plane) -> np.ndarray:
    """(N, 3) float64 ``points`` reflected across ``plane``."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points - 2.0 * np.outer(signed_distances(points, plane), plane.normal)


def reflect_local_normals(normals: np.ndarray, matrix_world: np.ndarray, plane: Plane) -> np.ndarray:
    """(K, 3) unit normals of an object's local space reflected across a world ``plane``, in local space.

    Normals go to world space by the inverse transpose of the object's matrix and come back by its
    transpose, so a scaled or sheared object's normals are reflected right.
    """
    linear = np.asarray(matrix_world, dtype=np.float64)[:3, :3]
    reflection = np.eye(3) - 2.0 * np.outer(plane.normal, plane.normal)
    mapping = linear.T @ reflection @ np.linalg.inv(linear).T
    reflected = np.asarray(normals, dtype=np.float64).reshape(-1, 3) @ mapping.T
    lengths = np.linalg.norm(reflected, axis=1, keepdims=True)
    return np.divide(reflected, lengths, out=np.zeros_like(reflected), where=lengths > 0.0)


def project(points: np.ndarray, plane: Plane) -> np.ndarray:
    """(N, 3) float64 ``points`` moved straight onto ``plane``."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points - np.outer(signed_distances(points, plane), plane.normal)


def face_ids(face_sizes: np.ndarray) -> np.ndarray:
    """(C,) the face of each corner, for corners listed face by face."""
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    return np.repeat(np.arange(sizes.size), sizes)


def plan(
    world_positions: np.ndarray,
    face_corners: np.ndarray,
    face_sizes: np.ndarray,
    edges: np.ndarray,
    plane: Plane,
    weld_fraction: float = DEFAULT_WELD_FRACTION,
    layout_name: str = "the layout",
    axis: str = "X",
) -> MirrorPlan:
    """Decide the seam, which faces and loose edges are copied, and which faces cross the plane.

    ``face_corners`` / ``face_sizes``: the faces' vertices one face after another; ``edges``: all
    edges (those on no face are loose curves and are copied too). Raises :class:`LayoutError`
    when the weld fraction is not positive, the plane misses the layout (no vertex within its
    weld distance of it), the layout already covers both sides of it, or its open border at the
    plane lies too far from it to be welded (``axis`` names the plane in that message's advice).
    """
    weld_fraction = float(weld_fraction)
    if not (np.isfinite(weld_fraction) and weld_fraction > 0.0):
        raise LayoutError(f"The weld distance must be a positive fraction of the edge length, not {weld_fraction:g}")
    positions = np.asarray(world_positions, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(positions).all():
        raise LayoutError(f"{layout_name} has NaN or infinite coordinates")
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    distances = signed_distances(positions, plane)
    edge_lengths = vertex_edge_lengths(positions, edges)
    weld = weld_fraction * edge_lengths
    near = np.abs(distances) <= weld
    if not near.any():
        nearest = float(np.abs(distances).min()) if distances.size else float("inf")
        sides = "on both sides of it" if (distances > 0).any() and (distances < 0).any() else "all on one side"
        raise LayoutError(
            f"The mirror plane misses {layout_name}: no vertex lies on it (within {weld_fraction:g} of its edge "
            f"length; the nearest is {nearest:.4g} away, the vertices are {sides}). Pick the axis or the mirror "
            "object whose plane runs along the layout's open side"
        )
    side = mirror_seam.surfaced_side(distances, weld)
    open_edges = mirror_seam.border_edges(mirror_seam.face_edges(corners, sizes))
    on_border, left_out = mirror_seam.border_seam(
        positions, edges, open_edges, distances, edge_lengths, plane.normal, side
    )
    seam = near | on_border
    mirror_seam.check_one_side(distances, edge_lengths, seam, side, layout_name)
    mirror_seam.check_drifted_border(left_out, distances, layout_name, axis)
    faces = face_ids(sizes)
    face_count = sizes.size
    clear = ~seam[corners]
    above = np.bincount(faces, weights=clear & (distances[corners] > weld[corners]), minlength=face_count) > 0
    below = np.bincount(faces, weights=clear & (distances[corners] < -weld[corners]), minlength=face_count) > 0
    off_seam = np.bincount(faces, weights=~seam[corners], minlength=face_count) > 0
    face_edge_keys = _edge_keys(mirror_seam.face_edges(corners, sizes))
    loose = ~np.isin(_edge_keys(edges), face_edge_keys)
    duplicate_edges = loose & ~(seam[edges[:, 0]] & seam[edges[:, 1]]) if edges.size else np.zeros(0, dtype=bool)
    return MirrorPlan(
        seam=seam,
        distances=distances,
        weld_distances=weld,
        duplicate_faces=off_seam,
        duplicate_edges=duplicate_edges,
        crossing_faces=np.flatnonzero(above & below),
        in_plane_faces=int(face_count - off_seam.sum()),
        drifted=seam & ~near,
    )


def _edge_keys(edges: np.ndarray) -> np.ndarray:
    """One int64 key per undirected edge."""
    edges = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    return edges[:, 0] * (1 << 32) + edges[:, 1]


def mirrored_layout(
    world_positions: np.ndarray,
    state: LayoutState,
    world_rest: np.ndarray,
    source: np.ndarray,
    seam: np.ndarray,
    plane: Plane,
    keep_seam_face_points: bool,
    on_plane_tolerance: float,
) -> MirrorLayout:
    """Positions, state and rest shape of the mirrored layout.

    ``source`` (M,) is the original vertex each vertex of the mirrored mesh comes from (the first
    N are the originals, in order; the copies follow); ``seam`` (N,) marks the originals on the
    plane. Copies are reflected across the plane and are space-points (to be wrapped); seam
    vertices are snapped onto the plane. A seam face-point keeps its face when
    ``keep_seam_face_points`` (a wrap follows and walks it onto the plane along the target) or
    when it was within ``on_plane_tolerance`` of the plane already; otherwise it becomes a
    space-point where it now is, on the plane.
    """
    source = np.asarray(source, dtype=np.int64).reshape(-1)
    original_count = np.asarray(world_positions).reshape(-1, 3).shape[0]
    if source.shape[0] < original_count or not np.array_equal(source[:original_count], np.arange(original_count)):
        raise LayoutError("The mirrored mesh does not start with the layout's own vertices in order")
    is_copy = np.arange(source.shape[0]) >= original_count
    seam = np.asarray(seam, dtype=bool).reshape(-1)
    seam_all = np.zeros(source.shape[0], dtype=bool)
    seam_all[:original_count] = seam
    if (seam[source[is_copy]]).any():
        raise LayoutError("A seam vertex was copied: the seam must be shared by both halves")

    def place(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        placed = points[source].copy()
        placed[is_copy] = reflect(placed[is_copy], plane)
        placed[seam_all] = project(placed[seam_all], plane)
        return placed

    positions = place(world_positions)
    moved = np.abs(signed_distances(np.asarray(world_positions, dtype=np.float64)[seam], plane)) > on_plane_tolerance
    states = np.asarray(state.states)[source].copy()
    faces = np.asarray(state.faces)[source].copy()
    barycentrics = np.asarray(state.barycentrics)[source].copy()
    detach = is_copy.copy()
    if not keep_seam_face_points:
        seam_indices = np.flatnonzero(seam)
        detach[seam_indices[moved]] = True
    states[detach] = layout_state.SPACE_POINT
    faces[detach] = layout_state.NO_FACE
    barycentrics[detach] = 0.0
    return MirrorLayout(
        positions=positions,
        state=layout_state.normalized_state(states, faces, barycentrics),
        rest=place(world_rest),
        seam=seam_all,
        is_copy=is_copy,
    )


def partner_errors(positions: np.ndarray, source: np.ndarray, is_copy: np.ndarray, plane: Plane) -> np.ndarray:
    """(K,) distance of each copy from the reflection of its source: 0 for a perfectly symmetric layout."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    source = np.asarray(source, dtype=np.int64).reshape(-1)
    is_copy = np.asarray(is_copy, dtype=bool).reshape(-1)
    return np.linalg.norm(positions[is_copy] - reflect(positions[source[is_copy]], plane), axis=1)


def hold_inputs(
    inputs,
    pinned: np.ndarray,
    plane_vertices: np.ndarray,
    plane: Plane,
    slide: bool = True,
    rest: "np.ndarray | None" = None,
):
    """The wrap's inputs (``wrap_inputs.WrapInputs``) for the mirrored half: the surfaced half pinned, the seam on the plane.

    Each ``pinned`` vertex gets an anchor at itself (its own face-point, or its own position for a
    space-point): the kernel pins an anchored point that sits on its anchor, so the surfaced half
    does not move at all. User anchors on pinned vertices are replaced by these pins; the others
    stay. ``plane_vertices`` are held on the plane (the kernel leaves anchored ones to their anchors);
    with ``slide`` they slide along the target's cross-section with it, else they only move onto it.
    ``rest`` (world, one row per vertex), when given, is the shape the wrap keeps instead of the stored one
    (:func:`surfaced_rest`).
    """
    if rest is not None:
        inputs = inputs._replace(rest_positions=transforms.as_float32_points(np.asarray(rest) - inputs.origin))
    pinned = np.asarray(pinned, dtype=bool).reshape(-1)
    keep = ~pinned[np.asarray(inputs.anchor_vertices, dtype=np.int64)]
    pins = np.flatnonzero(pinned)
    on_face = np.asarray(inputs.states)[pins] == layout_state.FACE_POINT
    pin_triangles = np.where(on_face, np.asarray(inputs.triangles)[pins], layout_state.NO_FACE).astype(np.int32)
    pin_barycentrics = np.where(on_face[:, None], np.asarray(inputs.barycentrics)[pins], 0.0)
    return inputs._replace(
        anchor_vertices=np.ascontiguousarray(np.concatenate([inputs.anchor_vertices[keep], pins]), dtype=np.uint32),
        anchor_triangles=np.ascontiguousarray(
            np.concatenate([inputs.anchor_triangles[keep], pin_triangles]), dtype=np.int32
        ),
        anchor_barycentrics=transforms.as_float32_points(
            np.concatenate([inputs.anchor_barycentrics[keep], pin_barycentrics])
        ),
        anchor_positions=transforms.as_float32_points(
            np.concatenate([inputs.anchor_positions[keep], np.asarray(inputs.positions)[pins]])
        ),
        plane_vertices=np.ascontiguousarray(plane_vertices, dtype=np.uint32),
        plane_point=tuple(float(value) for value in plane.point - inputs.origin),
        plane_normal=tuple(float(value) for value in plane.normal),
        plane_slide=bool(slide),
    )


def surfaced_rest(mirrored: MirrorLayout, edges: np.ndarray) -> "np.ndarray | None":
    """The rest shape for wrapping the new half next to a pinned surfaced half: the surfaced half as it is,
    its copy reflected (``mirrored.positions`` as :func:`mirrored_layout` placed them, before any landing).

    The new half then keeps the shape the artist gave the surfaced half rather than the template's, so on a
    symmetric target it stays the surfaced half's exact reflection and on an asymmetric one it looks like it.
    ``None`` when that shape has a collapsed edge (a snap put two vertices on one point): the stored rest
    shape is kept then.
    """
    shape = np.asarray(mirrored.positions, dtype=np.float64)
    try:
        check_rest_edges(shape, edges)
    except LayoutError:
        return None
    return shape.copy()


class MirroredAnchors(NamedTuple):
    """The anchor list after mirroring, and what changed."""

    anchors: object  # anchors.Anchors: the kept ones, then the mirrored ones
    mirrored_count: int  # anchors added on the new half
    dropped_count: int  # anchors that were on seam vertices (the seam is held on the plane instead)


def mirrored_anchors(
    anchor_list,
    source: np.ndarray,
    is_copy: np.ndarray,
    seam: np.ndarray,
    plane: Plane,
    target=None,
    mirror: bool = True,
) -> MirroredAnchors:
    """The anchors of the mirrored layout.

    Anchors on seam vertices are dropped (the plane holds the seam). With ``mirror``, each anchor
    of the surfaced half gets a partner on its vertex's copy, at its location reflected across the
    plane, put on the closest point of ``target`` (a ``target.Target``) when one is given
    (a face anchor), else left there (a space anchor). On a near-symmetric target the reflected
    point is a guess, as good as the symmetry.
    """
    source = np.asarray(source, dtype=np.int64).reshape(-1)
    is_copy = np.asarray(is_copy, dtype=bool).reshape(-1)
    seam = np.asarray(seam, dtype=bool).reshape(-1)
    vertices = np.asarray(anchor_list.vertex_indices, dtype=np.int64)
    on_seam = seam[vertices] if vertices.size else np.zeros(0, dtype=bool)
    kept = anchor_module.take(anchor_list, ~on_seam)
    if not mirror or anchor_module.anchor_count(kept) == 0:
        return MirroredAnchors(kept, 0, int(on_seam.sum()))
    copy_of = np.full(int(seam.shape[0]), -1, dtype=np.int64)
    copies = np.flatnonzero(is_copy)
    copy_of[source[copies]] = copies
    partners = copy_of[kept.vertex_indices.astype(np.int64)]
    has_partner = partners >= 0
    locations = reflect(kept.locations[has_partner], plane)
    count = locations.shape[0]
    kinds = np.full(count, anchor_module.SPACE_ANCHOR, dtype=np.int32)
    triangles = np.full(count, layout_state.NO_FACE, dtype=np.int32)
    barycentrics = np.zeros((count, 3), dtype=np.float32)
    if target is not None and count:
        hits = target.mesh.closest_points(locations)
        found = hits.triangles >= 0
        kinds[found] = anchor_module.FACE_ANCHOR
        triangles[found] = hits.triangles[found]
        barycentrics[found] = hits.barycentrics[found]
        locations[found] = hits.positions[found]
    added = anchor_module.make_anchors(partners[has_partner], kinds, triangles, barycentrics, locations)
    return MirroredAnchors(anchor_module.concatenate(kept, added), count, int(on_seam.sum()))


def land_copies(mirrored: MirrorLayout, edge_lengths: np.ndarray, target, reach_fraction: float) -> MirrorLayout:
    """The copies that lie on the target already (within ``reach_fraction`` of their own mean edge length of its
    surface) made face-points there; the others stay space-points for the wrap to fold.

    On a symmetric target the reflection of a face-point is on the surface, and its closest point
    is itself: the copy starts exactly where the wrap would put it. ``edge_lengths`` (M,) per vertex.
    """
    candidates = np.flatnonzero(mirrored.is_copy)
    if candidates.size == 0:
        return mirrored
    hits = target.mesh.closest_points(mirrored.positions[candidates])
    reach = reach_fraction * np.asarray(edge_lengths, dtype=np.float64)[candidates]
    found = (hits.triangles >= 0) & (np.asarray(hits.distances, dtype=np.float64) <= reach)
    landed = candidates[found]
    states = mirrored.state.states.copy()
    faces = mirrored.state.faces.copy()
    barycentrics = mirrored.state.barycentrics.copy()
    positions = mirrored.positions.copy()
    states[landed] = layout_state.FACE_POINT
    faces[landed] = hits.triangles[found]
    barycentrics[landed] = hits.barycentrics[found]
    positions[landed] = hits.positions[found]
    return mirrored._replace(positions=positions, state=layout_state.normalized_state(states, faces, barycentrics))


def held_on_plane(
    inputs, world_positions: np.ndarray, edges: np.ndarray, plane: Plane, weld_fraction: float = DEFAULT_WELD_FRACTION
):
    """The wrap's inputs (``wrap_inputs.WrapInputs``) with the layout's vertices on ``plane`` held on it.

    For a half to be mirrored: its midline (each vertex within ``weld_fraction`` of its own mean
    edge length of the plane, as the mirror's seam) stays on the plane while the half is wrapped,
    so that the mirror finds it there. Held points slide along the target's cross-section.

    The kernel lets an anchor win over the plane; here the plane wins: anchors on held vertices are
    left out of this wrap (the layout keeps them). An anchor's target off the plane (the closest
    point of a snapped midline vertex beside a nose, say) would pull the midline off it, and a
    target moved onto the plane may lie off the surface. Raises :class:`LayoutError` when no vertex
    lies on the plane.
    """
    distances = np.abs(signed_distances(world_positions, plane))
    on_plane = distances <= weld_fraction * vertex_edge_lengths(world_positions, edges)
    if not on_plane.any():
        raise LayoutError(
            f"No layout vertex lies on the hold plane (the nearest is {distances.min():.4g} from it): "
            "choose the axis (or the Mirror Object) of the plane the half's midline lies on"
        )
    free_anchor = ~on_plane[np.asarray(inputs.anchor_vertices, dtype=np.int64)]
    inputs = inputs._replace(
        anchor_vertices=np.ascontiguousarray(inputs.anchor_vertices[free_anchor]),
        anchor_triangles=np.ascontiguousarray(inputs.anchor_triangles[free_anchor]),
        anchor_barycentrics=np.ascontiguousarray(inputs.anchor_barycentrics[free_anchor]),
        anchor_positions=np.ascontiguousarray(inputs.anchor_positions[free_anchor]),
    )
    return inputs._replace(
        plane_vertices=np.ascontiguousarray(np.flatnonzero(on_plane), dtype=np.uint32),
        plane_point=tuple(float(value) for value in plane.point - inputs.origin),
        plane_normal=tuple(float(value) for value in plane.normal),
        plane_slide=True,
    )


class MirrorOutcome:
    """What a mirror did, for the report (and for scripts: ``SPRINGWRAP_OT_mirror.last_outcome``)."""

    def __init__(self, **values):
        self.__dict__.update(values)
