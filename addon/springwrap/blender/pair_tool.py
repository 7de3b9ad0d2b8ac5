"""What the pair tool reads and writes in Blender: the 3D view as the picking sees it, the layout's vertices and
surface under the mouse, the target point under the mouse (a ray cast on the evaluated target), each edit of the
anchor list (written by :func:`.anchors.write_anchors`, like every anchor operator's), and the Live re-settle
(a :class:`.wrap_session.WrapSession` started from the layout as it is after the edit).

Object mode data: the pair tool's operator holds the layout out of edit mode while it runs, as the modal wrap does.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import anchors, input_policy, pair_edits, pair_pick, transforms
from ..core.errors import LayoutError
from ..core.target import CentredMesh
from ..core.transforms import matrix_array
from ..core.wrap_inputs import WrapParameters
from ..properties import WRAP_DEFAULTS
from . import anchors as anchor_data
from . import layout as layout_data
from . import target as target_data
from .wrap_session import WrapSession

LIVE_FIRST_FRAME_SECONDS = 0.3
"""A Live re-settle's first frame solves at most this long, so the layout shows an edit's effect soon after it."""


class Picking(NamedTuple):
    """The layout as the mouse sees it: its vertices in world space and its surface (what hides a vertex)."""

    world: np.ndarray  # (N, 3) float64
    surface: CentredMesh | None  # the layout's faces (fans), None for a layout without faces
    tolerance: float  # pair_pick.occlusion_tolerance of the vertices


_picking: dict = {"key": None, "value": None}
_twins: dict = {"key": None, "value": None}


def read_view(region, region_3d) -> pair_pick.View:
    """The region of a 3D view (``WINDOW``) and its ``RegionView3D`` as a ``pair_pick.View``."""
    return pair_pick.make_view(matrix_array(region_3d.perspective_matrix), region.width, region.height)


def _layout_key(layout, arrays) -> tuple:
    """What the picking and the twins depend on: the object, its mesh, its vertices and transform."""
    positions = np.ascontiguousarray(arrays.positions)
    return (layout.as_pointer(), layout.data.as_pointer(), hash(positions.tobytes()), arrays.matrix_world.tobytes())


def layout_picking(layout: bpy.types.Object) -> Picking:
    """The layout's :class:`Picking`, cached until its vertices or transform change (a Live re-settle moves them)."""
    arrays = layout_data.read_layout(layout)
    key = _layout_key(layout, arrays)
    if _picking["key"] != key:
        world = transforms.world_positions(arrays)
        topology = layout_data.read_layout_topology(layout)
        triangles = pair_pick.fan_triangles(topology.face_corners, topology.face_sizes)
        finite = np.all(np.isfinite(world))
        surface = CentredMesh(world, triangles) if triangles.shape[0] and finite else None
        _picking.update(key=key, value=Picking(world, surface, pair_pick.occlusion_tolerance(world)))
    return _picking["value"]


def forget() -> None:
    """Drop the cached picking and twins (the tool ended, a file was loaded)."""
    _picking.update(key=None, value=None)
    _twins.update(key=None, value=None)


def vertex_under_mouse(layout: bpy.types.Object, view: pair_pick.View, mouse) -> int:
    """The layout vertex a click at ``mouse`` (region pixels) takes, -1 for none (``pair_pick.pick_vertex``)."""
    picking = layout_picking(layout)
    return pair_pick.pick_vertex(view, picking.world, mouse, occluder=picking.surface, tolerance=picking.tolerance)


def check_target_shown(layout: bpy.types.Object) -> None:
    """Raise :class:`LayoutError` when the layout's target cannot be clicked: none, not a mesh, or hidden."""
    target = target_data.check_target(layout)
    if not target.visible_get():
        raise LayoutError(f"Target '{target.name}' is hidden: show it to pick points on it")


def target_under_mouse(context, layout: bpy.types.Object, view: pair_pick.View, mouse) -> np.ndarray | None:
    """(3,) float64 world point of the evaluated target's surface under ``mouse``, None when the ray misses it.
    Raises :class:`LayoutError` for a target that cannot be clicked (none, hidden, no faces)."""
    check_target_shown(layout)
    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    origin, direction = pair_pick.mouse_ray(view, mouse)
    hits = target.mesh.ray_cast(origin[None], direction[None])
    if int(np.asarray(hits.triangles)[0]) < 0:
        return None
    return np.asarray(hits.positions, dtype=np.float64).reshape(-1, 3)[0]


def anchor_ends(layout: bpy.types.Object) -> tuple[anchors.Anchors, np.ndarray]:
    """The layout's anchors and (K, 3) world positions of their layout vertices (NaN for a missing vertex)."""
    anchor_list = anchor_data.read_anchors(layout)
    return anchor_list, layout_data.read_world_vertex_positions(layout, anchor_list.vertex_indices)


def _symmetry(layout: bpy.types.Object, extent):
    """``(Twins, Plane)`` of the layout's symmetric-anchor settings, None when Symmetric is off; cached while the
    layout's vertices and the plane stay."""
    settings = layout.springwrap
    if not settings.anchor_symmetric:
        return None
    owner = settings.anchor_symmetry_object
    name = owner.name if owner is not None else ""
    plane_matrix = matrix_array((owner or layout).matrix_world).tobytes()
    key = (_layout_key(layout, layout_data.read_layout(layout)), settings.anchor_symmetry_axis, name, plane_matrix)
    if _twins["key"] != key:
        twins, plane, _owner = anchor_data.read_vertex_twins(layout, settings.anchor_symmetry_axis, name, extent)
        _twins.update(key=key, value=(twins, plane))
    return _twins["value"]


def place_pair(context, layout: bpy.types.Object, vertex: int, location, on_surface: bool = True):
    """Anchor layout ``vertex`` to the target point at ``location`` (world), replacing its pair in place, its twin
    too when the layout's Symmetric setting is on; written. Returns the ``AnchorOutcome``."""
    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    location = input_policy.check_location(tuple(location), "The pair's target point", target.extent)
    existing = anchor_data.read_anchors(layout)
    vertex_count = len(layout.data.vertices)
    symmetry = _symmetry(layout, target.extent)
    outcome, _report = pair_edits.place(
        vertex_count, existing, target, layout.springwrap.anchors_signature, vertex, location, on_surface, symmetry
    )
    anchor_data.write_anchors(layout, outcome.anchors, outcome.active_index, target.signature)
    return outcome


def repick_pair(context, layout: bpy.types.Object, index: int, vertex: int):
    """Move the layout end of the pair at ``index`` onto ``vertex`` (its twin's too, Symmetric on); written."""
    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    existing = anchor_data.read_anchors(layout)
    anchors.check_anchor_locations(existing)
    symmetry = _symmetry(layout, target.extent)
    outcome, _report = pair_edits.repick(
        len(layout.data.vertices), existing, target, layout.springwrap.anchors_signature, index, vertex, symmetry
    )
    anchor_data.write_anchors(layout, outcome.anchors, outcome.active_index, target.signature)
    return outcome


def remove_pair(layout: bpy.types.Object, index: int):
    """Remove the pair at ``index`` (and its twin, Symmetric on); written. Needs no target (the way out of a
    broken pair)."""
    outcome = pair_edits.remove(anchor_data.read_anchors(layout), index, layout.springwrap.anchor_symmetric)
    anchor_data.write_anchors(layout, outcome.anchors, outcome.active_index)
    return outcome


def start_settle(context, layout: bpy.types.Object, display_seconds: float | None = None) -> WrapSession:
    """A Live re-settle: a wrap with the wrap's default settings started from the layout as it is now (its
    positions and face-points: a warm start), with the anchors as just edited. Nothing is written yet.
    ``display_seconds``: what a redraw is known to cost (the frames are paced from it, as the modal wrap's)."""
    parameters = WrapParameters(settings=WRAP_DEFAULTS)
    return WrapSession(context, layout, parameters, display_seconds=display_seconds)


def advance_settle(session: WrapSession) -> None:
    """One frame of a Live re-settle, written. The first solves here, at most :data:`LIVE_FIRST_FRAME_SECONDS`, so
    the layout shows an edit's effect soon after it; the rest solves in the session's worker thread
    (``WrapSession.start_worker``) and each later frame writes the newest positions it solved. The next edit
    finishes the re-settle (``WrapSession.finish`` stops the worker between two iterations) before it changes the
    anchors, and starts another from the layout as it then is."""
    if session.worker is None and session.frames == 0:
        session.advance(max_seconds=LIVE_FIRST_FRAME_SECONDS)
        session.start_worker()
    else:
        session.advance()
