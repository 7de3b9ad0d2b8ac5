"""Parts in a wrap, on the Blender side: the layout's Find Parts setting and its Follow, Follow Soft and Surface
groups read (``core.parts`` plans from them), the parts left out of the target's pull (the solver's free
vertices, also at the fine stage of a spring resolution above 1), and the part attribute written with the wrap's
result and read back by the read-out."""

import bpy

import numpy as np

from ..core import layout_state, parts, transforms
from ..core.errors import LayoutError
from . import attributes
from . import layout as layout_data

_GROUPS = (("follow_group", "Follow"), ("follow_soft_group", "Follow Soft"), ("surface_group", "Surface"))
"""The layout settings naming the parts' vertex groups, and their labels."""


def read_part_groups(layout: bpy.types.Object) -> parts.PartGroups:
    """The layout's Follow, Follow Soft and Surface groups as (N,) bool (weight above 0), None where not set.

    Raises :class:`LayoutError` for a group the layout does not have, or one without a vertex of weight above 0."""
    settings = layout.springwrap
    found = []
    for attribute, label in _GROUPS:
        name = getattr(settings, attribute)
        if not name:
            found.append(None)
            continue
        weights, member = layout_data.read_layout_group(layout, name)
        flags = member & (weights > 0.0)
        if not flags.any():
            raise LayoutError(
                f"The {label} group '{name}' of layout '{layout.name}' has no vertex (of weight above 0): assign the "
                f"pieces' vertices to it, or clear {label}"
            )
        found.append(flags)
    return parts.PartGroups(*found)


def plan_wrap_parts(layout, arrays, topology, target, anchor_list, curve_constraints):
    """The wrap's :class:`core.parts.PartPlan` and, when there are parts, the kernel's ``SurfaceFollower`` bound to
    the layout as it is now (world space); else None. An anchored or curve-constrained vertex is never a part.
    Raises :class:`LayoutError` for a bad group or every vertex a part."""
    settings = layout.springwrap
    groups = read_part_groups(layout)
    count = int(topology.vertex_count)
    pinned = np.zeros(count, dtype=bool)
    pinned[np.asarray(anchor_list.vertex_indices, dtype=np.int64).reshape(-1)] = True
    for constraint in curve_constraints:
        pinned[np.asarray(constraint.layout_vertices, dtype=np.int64)] = True
    world = transforms.world_positions(arrays)
    plan = parts.plan_parts(layout.name, world, topology, groups, bool(settings.find_parts), target.mesh, pinned)
    if not plan.any:
        return plan, None
    return plan, parts.make_follower(plan, world)


def free_parts(inputs, plan: parts.PartPlan):
    """``inputs`` (``core.wrap_inputs.WrapInputs``) with the parts, and the surface the target does not show
    (``plan.unseen``), among the free vertices (no pull to the target)."""
    if not plan.any:
        return inputs
    free = plan.parts if plan.unseen is None else plan.parts | plan.unseen
    if inputs.free_vertices is not None:
        free = free | np.asarray(inputs.free_vertices, dtype=bool)
    return inputs._replace(free_vertices=np.ascontiguousarray(free))


def refine_free(inputs, fine, vertex_count: int):
    """The fine stage's ``inputs`` with free flags for every fine point (free when all the layout vertices it
    blends are), when the coarse stage had free vertices."""
    free = inputs.free_vertices
    if free is None or np.asarray(free).shape[0] != vertex_count:
        return inputs
    fine_free = np.ones(fine.sources.shape[0], dtype=bool)
    for column in range(fine.sources.shape[1]):
        used = fine.weights[:, column] > 0.0
        fine_free[used] &= np.asarray(free, dtype=bool)[fine.sources[used, column]]
    return inputs._replace(free_vertices=np.ascontiguousarray(fine_free))


def write_parts(layout: bpy.types.Object, plan: parts.PartPlan) -> None:
    """Write :data:`core.parts.PART_ATTRIBUTE` (2 rigid part, 1 soft part, 0 surface); without parts, an older one
    is removed."""
    mesh = layout.data
    if plan.any:
        attributes.write_point_attribute(mesh, parts.PART_ATTRIBUTE, "INT", parts.part_codes(plan))
    else:
        attributes.remove_attribute(mesh, parts.PART_ATTRIBUTE)


def read_parts(layout: bpy.types.Object) -> np.ndarray | None:
    """(N,) bool: the vertices the last wrap moved as parts, or None when it had none (or the mesh changed)."""
    mesh = layout.data
    codes = attributes.read_point_attribute(mesh, parts.PART_ATTRIBUTE, "INT")
    if codes is None or codes.size != len(mesh.vertices):
        return None
    return np.asarray(codes).reshape(-1) > 0


def follow_surface(
    follower, plan: parts.PartPlan, world: np.ndarray, state, inputs, final: bool, target=None, placed=None
):
    """The layout's world positions ``world`` with its parts moved by the surface (``core.parts.follow``) and held
    on the mirror plane (:func:`hold_on_plane`). ``final`` (the wrap's result): they follow only the surface
    vertices that ``state`` (``core.layout_state.LayoutState``) holds on the target (:func:`surface_held`), and the rigid
    pieces that skin covers are placed by its registration onto ``target`` (the target's ``CentredMesh``, when
    given; the pieces so placed appended to ``placed``, an optional list)."""
    held = surface_held(state, inputs) if final else None
    moved = parts.follow(follower, plan, world, held, target if final else None, placed)
    return hold_on_plane(moved, plan, inputs)


def surface_held(state, inputs) -> np.ndarray:
    """(N,) bool: the vertices the target's surface holds, the parts' skin in the wrap's result: the face points of
    ``state`` but those a curve constraint holds (``inputs.curve_vertices``). A curve puts its vertices along the
    target's feature (a lip paired with the rim of an open mouth, stretched along it), not where the surface carried
    them: skin moving as a curve pulls it would drag a part that follows it, or place one by a patch the target's
    surface does not hold (the tongue behind paired lips: ``benchmarks/parts.py``)."""
    held = np.array(state.states == layout_state.FACE_POINT, dtype=bool)
    curves = getattr(inputs, "curve_vertices", None)
    if curves is not None:
        curves = np.asarray(curves, dtype=np.int64).reshape(-1)
        held[curves[curves < held.size]] = False
    return held


def hold_on_plane(world: np.ndarray, plan: parts.PartPlan, inputs) -> np.ndarray:
    """``world`` ((N, 3) float64) with the part vertices the mirror holds on its plane (``inputs.plane_vertices``)
    put back onto it: a part cut by the mirror plane keeps its seam there, as the surface's does."""
    held = getattr(inputs, "plane_vertices", None)
    if held is None or not plan.any:
        return world
    held = np.asarray(held, dtype=np.int64)
    held = held[(held < plan.parts.size) & plan.parts[np.minimum(held, plan.parts.size - 1)]]
    if held.size == 0:
        return world
    normal = np.asarray(inputs.plane_normal, dtype=np.float64)
    normal = normal / np.linalg.norm(normal)
    point = np.asarray(inputs.plane_point, dtype=np.float64) + np.asarray(inputs.origin, dtype=np.float64)
    world = np.array(world, dtype=np.float64)
    world[held] -= np.outer((world[held] - point) @ normal, normal)
    return world


def readout_summary(layout: bpy.types.Object, readout) -> dict:
    """The read-out's numbers for a report (``core.quality.summary``) of the layout's surface alone when its last wrap
    moved parts, with ``part_vertices``, how many vertices followed the surface (0 without parts)."""
    from ..core import quality

    followed = read_parts(layout)
    summary = quality.summary(parts.surface_readout(readout, followed))
    return summary | {"part_vertices": 0 if followed is None else int(followed.sum())}


def read_followed_plan(layout: bpy.types.Object, topology) -> parts.PartPlan | None:
    """The parts the layout's last wrap moved (:data:`core.parts.PART_ATTRIBUTE`: rigid and soft) as a
    :class:`core.parts.PartPlan`, or None when it had none (or the mesh changed since)."""
    codes = attributes.read_point_attribute(layout.data, parts.PART_ATTRIBUTE, "INT")
    if codes is None or codes.size != int(topology.vertex_count):
        return None
    codes = np.asarray(codes).reshape(-1)
    if not (codes > 0).any() or (codes > 0).all():
        return None
    return parts.PartPlan(codes > 0, codes == 1, parts.layout_pieces(topology), ())
