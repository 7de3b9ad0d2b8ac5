"""Follow, without Blender: which layout vertices a change of the target concerns, and the wrap's inputs that
re-settle only those (the others held where they are). No ``bpy``.

A vertex is concerned when its distance to the target's surface changed (measured from where it is, before
and after the change), or when it is a face-point whose point on the surface moved; the region re-settled is
those vertices grown by a few rings of layout edges, so the layout eases into the change. Every other vertex
is held by an anchor where it is (a face anchor on its face when it is a face-point) and written back exactly
as it was. A sequence's later frame starts the region again from the template's shape (placed onto the vertices
around it), its springs resting in that shape, as a wrap from the template would: where the target went back
(a mouth that opened and closed again) the region comes back to where such a wrap puts it, instead of keeping
the shape the frames before it carried. That region is wrapped with the global-to-local schedule when the wrap's
is Auto and vertices around it are held (:func:`restart_parameters`).
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import layout_state, transforms
from .subdivision import LayoutTopology
from .wrap_inputs import WrapInputs

CHANGE_FRACTION = 1e-5
"""A distance that changed by less than this fraction of the target's bounding-box diagonal did not change
(the float32 frame the target is held in moves points by about 1e-7 of it)."""

RINGS = 2
"""Rings of layout edges the changed vertices are grown by."""

RESTART_RINGS = 3
"""Rings of layout edges a sequence's changed vertices are grown by, the region started again from the template
(:func:`restarted`): one more than :data:`RINGS`, so that the region's wrap reaches farther past the change
(measured on the body's expression sequence, ``benchmarks/sequence.py``: closer to a wrap of the whole frame)."""

FIT_RINGS = 3
"""Rings of layout edges around vertices started again from the template that the template is fitted to."""

TEMPLATE_SHARE = 0.3
"""A sequence's later frame: the template's share in the rest shape of the springs held around the region it
re-settles (the previous frame's shape the rest); the region itself starts again from the template and rests in
its shape (:func:`restarted`)."""


RESTART_SCHEDULE = "GLOBAL_TO_LOCAL"
"""The schedule a region started again from the template is wrapped with when the wrap's is Auto and vertices
around it are held: stiff, nearly affine levels first, as for a large change of shape. Auto would take the local
one (the held vertices are many anchors), which settles the region farther from where a wrap of the whole layout
puts it (measured on the body's expression sequence: ``benchmarks/sequence.py``)."""


def restart_parameters(parameters, region: np.ndarray):
    """``parameters`` (``core.wrap_inputs.WrapParameters``) for the ``region`` ((N,) bool) started again from the
    template: the Auto schedule replaced by :data:`RESTART_SCHEDULE` (``settings`` None: the kernel's defaults so
    replaced) when some vertex is held around it; a schedule chosen by the user is kept, and so is Auto for the
    whole layout (nothing held: the wrap from the template that the first frame was)."""
    settings = parameters.settings if parameters.settings is not None else springwrap_kernel.WrapSettings()
    if settings.schedule != "AUTO" or np.asarray(region, dtype=bool).all():
        return parameters
    return parameters._replace(settings=settings.replace(schedule=RESTART_SCHEDULE))


def changed_vertices(before: np.ndarray, after: np.ndarray, moved: np.ndarray, tolerance: float) -> np.ndarray:
    """(N,) bool: vertices whose surface distance changed (``before`` → ``after``, NaN: unknown, taken as
    changed) or whose face-point moved (``moved``: how far, 0 for space-points) by more than ``tolerance``."""
    before, after = np.asarray(before, dtype=np.float64), np.asarray(after, dtype=np.float64)
    difference = np.abs(after - before)
    return ~(difference <= tolerance) | (np.asarray(moved, dtype=np.float64) > tolerance)


def grow(mask: np.ndarray, edges: np.ndarray, rings: int = RINGS) -> np.ndarray:
    """``mask`` grown by ``rings`` rings of ``edges`` ((E, 2) vertex pairs)."""
    grown = np.asarray(mask, dtype=bool).copy()
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    for _ring in range(int(rings)):
        touched = grown[edges[:, 0]] | grown[edges[:, 1]]
        if not touched.any():
            break
        grown[edges[touched].reshape(-1)] = True
    return grown


def surface_distances(target, world: np.ndarray) -> np.ndarray:
    """(N,) float64 distance of each world point to the target's surface (``core.target.Target``)."""
    return np.asarray(target.mesh.closest_points(world).distances, dtype=np.float64)


def changed_region(target, world, state, same_topology: bool, before, edges, rings: int = RINGS):
    """(region, after): the layout vertices a change of the target concerns, grown by ``rings`` rings of
    ``edges``, and (N,) every vertex's surface distance now.

    ``world``: (N, 3) the layout's world positions; ``state``: its ``LayoutState``; ``same_topology``: the
    target has the topology the face-points were written against (then a face-point whose point on the surface
    moved is concerned too); ``before``: (N,) the distances when last measured (NaN: unknown: a face-point lay
    on the surface, a space-point is not taken as changed)."""
    world = np.asarray(world, dtype=np.float64)
    count = world.shape[0]
    after = surface_distances(target, world)
    moved = np.zeros(count)
    on_face = (state.states == layout_state.FACE_POINT) & (state.faces >= 0)
    if same_topology and on_face.any():
        on_face &= state.faces < target.mesh.triangle_count
        surface = target.mesh.face_point_positions(
            np.ascontiguousarray(state.faces[on_face], dtype=np.uint32),
            np.ascontiguousarray(state.barycentrics[on_face], dtype=np.float32),
        )
        moved[on_face] = np.linalg.norm(surface - world[on_face], axis=1)
    before = np.asarray(before, dtype=np.float64)
    before = np.where(np.isnan(before) & on_face, 0.0, before)
    before = np.where(np.isnan(before), after, before)
    low, high = target.mesh.bounding_box()
    tolerance = CHANGE_FRACTION * float(np.linalg.norm(high - low))
    changed = changed_vertices(before, after, moved, tolerance)
    return grow(changed, edges, rings) if changed.any() else changed, after


def similar(template: np.ndarray, positions: np.ndarray, fitted: np.ndarray | None = None) -> np.ndarray | None:
    """(N, 3) float64 ``template`` moved onto ``positions`` by the similarity that fits it best (over the
    ``fitted`` vertices, (N,) bool, when given); None when none is fitted (fewer than 3 points, or on one line)."""
    template = transforms.as_float32_points(template)
    positions = transforms.as_float32_points(positions)
    if fitted is not None:
        fitted = np.asarray(fitted, dtype=bool)
        if int(fitted.sum()) < 3:
            return None
    chosen = slice(None) if fitted is None else fitted
    try:
        matrix = springwrap_kernel.fit_transform(template[chosen], positions[chosen], "SIMILARITY")
    except springwrap_kernel.SpringwrapError:
        return None
    return transforms.transform_points(matrix, template)


def blended_rest(positions: np.ndarray, template: np.ndarray | None, share: float) -> np.ndarray:
    """(N, 3) float32 rest shape: ``positions`` (the layout as it is) and, ``share`` of it, ``template`` (the
    template's shape) moved onto them by the similarity that fits it best. ``positions`` alone without a template
    or a share, or when no similarity is fitted (the points on one line)."""
    positions = np.asarray(positions, dtype=np.float32)
    if template is None or not share > 0.0:
        return positions
    placed = similar(template, positions)
    if placed is None:
        return positions
    return transforms.as_float32_points((1.0 - share) * positions.astype(np.float64) + share * placed)


def restarted(inputs: WrapInputs, restart: np.ndarray, edges: np.ndarray, rings: int = FIT_RINGS) -> WrapInputs:
    """``inputs`` with the ``restart`` vertices ((N,) bool) started again from the template's shape (the inputs'
    rest), as a wrap from the template starts them: space-points at the template's positions, placed by the
    similarity that fits the template to the vertices around them (``rings`` rings of ``edges`` outside
    ``restart``), or where the template is when those are too few to fit (``restart`` the whole layout: the
    start of a wrap from the template itself). As they were without a rest shape."""
    restart = np.asarray(restart, dtype=bool)
    if not restart.any() or inputs.rest_positions is None:
        return inputs
    placed = similar(inputs.rest_positions, inputs.positions, grow(restart, edges, rings) & ~restart)
    if placed is None:
        placed = inputs.rest_positions
    states, triangles = inputs.states.copy(), inputs.triangles.copy()
    barycentrics, positions = inputs.barycentrics.copy(), inputs.positions.copy()
    states[restart] = layout_state.SPACE_POINT
    triangles[restart] = layout_state.NO_FACE
    barycentrics[restart] = 0.0
    positions[restart] = np.asarray(placed)[restart]
    return inputs._replace(
        states=np.ascontiguousarray(states, dtype=np.int32),
        triangles=np.ascontiguousarray(triangles, dtype=np.int32),
        barycentrics=transforms.as_float32_points(barycentrics),
        positions=transforms.as_float32_points(positions),
    )


def held(inputs: WrapInputs, region: np.ndarray, template_share: float = 0.0, restart=None, warm=None) -> WrapInputs:
    """``inputs`` with every vertex outside ``region`` held where it starts (the layout's own anchors kept):
    a face anchor on its face for a face-point, a space anchor at its position for a space-point; the
    springs resting in the layout's shape as it is (``warm``, (N, 3) kernel frame: as it was before
    :func:`restarted` moved some; None: the inputs' positions), with ``template_share`` of the template's shape
    (the inputs' rest) blended in (:func:`blended_rest`), and in the template's shape alone at the ``restart``
    vertices ((N,) bool, optional); and no soft pairs (they steer a whole wrap's stiff levels, not a re-settle)."""
    region = np.asarray(region, dtype=bool)
    anchored = np.zeros(region.shape[0], dtype=bool)
    anchored[inputs.anchor_vertices.astype(np.int64)] = True
    vertices = np.flatnonzero(~region & ~anchored)
    on_face = inputs.states[vertices] == layout_state.FACE_POINT
    triangles = np.where(on_face, inputs.triangles[vertices], layout_state.NO_FACE).astype(np.int32)
    barycentrics = np.where(on_face[:, None], inputs.barycentrics[vertices], 0.0)
    return inputs._replace(
        anchor_vertices=np.ascontiguousarray(np.concatenate([inputs.anchor_vertices, vertices]), dtype=np.uint32),
        anchor_triangles=np.ascontiguousarray(np.concatenate([inputs.anchor_triangles, triangles]), dtype=np.int32),
        anchor_barycentrics=transforms.as_float32_points(np.concatenate([inputs.anchor_barycentrics, barycentrics])),
        anchor_positions=transforms.as_float32_points(
            np.concatenate([inputs.anchor_positions, inputs.positions[vertices]])
        ),
        rest_positions=_rest(inputs, template_share, restart, warm),
        soft_pair_vertices=None,
        soft_pair_positions=None,
        soft_pair_confidences=None,
    )


def _rest(inputs: WrapInputs, template_share: float, restart, warm) -> np.ndarray:
    """The rest shape of :func:`held`: ``warm`` (the layout as it was; None: the inputs' positions) with
    ``template_share`` of the template blended in, the template's shape alone at the ``restart`` vertices."""
    warm = inputs.positions if warm is None else warm
    rest = blended_rest(warm, inputs.rest_positions, template_share)
    if restart is None or inputs.rest_positions is None or not np.any(restart):
        return rest
    restart = np.asarray(restart, dtype=bool)
    rest[restart] = blended_rest(warm, inputs.rest_positions, 1.0)[restart]
    return rest


def merged(settled: np.ndarray, before: np.ndarray, region: np.ndarray) -> np.ndarray:
    """The settled positions inside ``region`` and the positions as they were (bit for bit) outside it."""
    result = np.array(before, dtype=np.float32, copy=True)
    region = np.asarray(region, dtype=bool)
    result[region] = np.asarray(settled, dtype=np.float32)[region]
    return result


class Restriction(NamedTuple):
    """A wrap restricted to part of the layout: the layout vertices it keeps (in their order, the solver's
    numbering), the part's topology, and the layout as it was (every vertex outside keeps it)."""

    kept: np.ndarray  # (K,) int64 layout vertices of the part
    region: np.ndarray  # (N,) bool the vertices re-settled (the part's others are held)
    topology: LayoutTopology  # the part's faces, edges and seams, numbered 0 .. K - 1
    positions: np.ndarray  # (N, 3) float32 local positions of the whole layout before
    state: layout_state.LayoutState  # the whole layout's state before (as resolved on the current target)


def restrict(topology: LayoutTopology, inputs: WrapInputs, region: np.ndarray, positions: np.ndarray):
    """(``Restriction``, the part's inputs): the layout's faces and edges that touch ``region`` and their vertices
    (those outside ``region`` held where they are, ``inputs`` made by :func:`held`), so that the solver works on
    the part alone; None when the inputs have what a part cannot be cut from (curve constraints, a plane)."""
    if inputs.curve_vertices is not None or inputs.plane_vertices is not None:
        return None
    region = np.asarray(region, dtype=bool)
    sizes = topology.face_sizes.astype(np.int64)
    corners = topology.face_corners.astype(np.int64)
    face_of_corner = np.repeat(np.arange(sizes.size), sizes)
    touching = np.zeros(sizes.size, dtype=bool)
    np.logical_or.at(touching, face_of_corner, region[corners])
    edges = topology.edges.astype(np.int64).reshape(-1, 2)
    edge_kept = region[edges].any(axis=1)
    member = region.copy()
    member[corners[touching[face_of_corner]]] = True
    member[edges[edge_kept].reshape(-1)] = True
    kept = np.flatnonzero(member)
    number = np.full(region.size, -1, dtype=np.int64)
    number[kept] = np.arange(kept.size)
    seams = topology.seams.astype(np.int64).reshape(-1, 2)
    seams = seams[member[seams].all(axis=1)]
    part = LayoutTopology(
        int(kept.size),
        np.ascontiguousarray(number[corners[touching[face_of_corner]]], dtype=np.uint32),
        np.ascontiguousarray(sizes[touching], dtype=np.uint32),
        np.ascontiguousarray(number[edges[edge_kept]], dtype=np.uint32).reshape(-1, 2),
        np.ascontiguousarray(number[seams], dtype=np.uint32).reshape(-1, 2),
    )
    anchor_vertices = inputs.anchor_vertices.astype(np.int64)
    anchor_kept = member[anchor_vertices]

    def rows(array):
        return None if array is None else np.ascontiguousarray(np.asarray(array)[kept])

    part_inputs = inputs._replace(
        states=rows(inputs.states),
        triangles=rows(inputs.triangles),
        barycentrics=rows(inputs.barycentrics),
        positions=rows(inputs.positions),
        rest_positions=rows(inputs.rest_positions),
        stiffness=rows(inputs.stiffness),
        free_vertices=rows(inputs.free_vertices),
        anchor_vertices=np.ascontiguousarray(number[anchor_vertices[anchor_kept]], dtype=np.uint32),
        anchor_triangles=np.ascontiguousarray(inputs.anchor_triangles[anchor_kept]),
        anchor_barycentrics=np.ascontiguousarray(inputs.anchor_barycentrics[anchor_kept]),
        anchor_positions=np.ascontiguousarray(inputs.anchor_positions[anchor_kept]),
    )
    state = layout_state.normalized_state(inputs.states, inputs.triangles, inputs.barycentrics)
    return Restriction(kept, region, part, np.asarray(positions, dtype=np.float32), state), part_inputs


def scatter(restriction: Restriction, positions: np.ndarray, state: layout_state.LayoutState):
    """The whole layout's (positions, state) from the part's: the part's vertices in ``region`` as solved, every
    other vertex as it was (its position bit for bit, its state as resolved on the current target)."""
    solved = restriction.region[restriction.kept]
    vertices = restriction.kept[solved]
    whole_positions = restriction.positions.copy()
    whole_positions[vertices] = np.asarray(positions)[solved]
    whole = restriction.state
    states, faces, barycentrics = whole.states.copy(), whole.faces.copy(), whole.barycentrics.copy()
    states[vertices] = state.states[solved]
    faces[vertices] = state.faces[solved]
    barycentrics[vertices] = state.barycentrics[solved]
    return whole_positions, layout_state.LayoutState(states, faces, barycentrics)
