"""The layout's anchors (``Object.springwrap.anchors``) as ``core.anchors.Anchors`` arrays, and back."""

import bpy

import numpy as np

from ..core import anchors, input_policy, mirroring, symmetry, transforms
from ..core.errors import LayoutError
from ..core.transforms import matrix_array
from . import anchor_view, compat
from . import layout as layout_data

_ANCHOR_FIELDS = (
    # AnchorItem property, numpy dtype, components (the order of anchors.make_anchors' arguments)
    ("vertex_index", np.int32, 1),
    ("target_kind", np.int32, 1),  # enum: its item numbers are the anchor kinds
    ("triangle", np.int32, 1),
    ("barycentric", np.float32, 3),
    ("location", np.float64, 3),
    ("twin_vertex", np.int32, 1),  # -1 (no pair) in files saved before symmetric anchors
    ("proposed", bool, 1),  # off (a hand pair) in files saved before proposals
    ("confidence", np.float32, 1),
)


def read_anchors(layout: bpy.types.Object) -> anchors.Anchors:
    """The layout's anchors (``Object.springwrap.anchors``) as arrays, in list order."""
    items = layout.springwrap.anchors
    count = len(items)
    arrays = []
    for name, dtype, components in _ANCHOR_FIELDS:
        values = np.empty(count * components, dtype=dtype)
        if count:
            compat.foreach_get(items, name, values)
        arrays.append(values)
    return anchors.make_anchors(*arrays)


def face_anchor_count(layout: bpy.types.Object) -> int:
    """How many of the layout's anchors are on the target surface (the kinds read at once: the list may be long)."""
    items = layout.springwrap.anchors
    kinds = np.empty(len(items), dtype=np.int32)
    if len(items):
        compat.foreach_get(items, "target_kind", kinds)
    return int(np.count_nonzero(kinds == anchors.FACE_ANCHOR))


def write_anchors(
    layout: bpy.types.Object, anchor_list: anchors.Anchors, active_index: int = -1, signature: str | None = None
) -> None:
    """Replace the layout's anchor list; make ``active_index`` active (-1 keeps the current one, clamped).

    ``signature`` (the target's topology signature the face anchors refer to) is stored when given.
    """
    settings = layout.springwrap
    items = settings.anchors
    anchor_list = anchors.unpair_broken(anchor_list)  # a pair whose other half is gone is no pair
    count = anchors.anchor_count(anchor_list)
    if len(items) != count:
        items.clear()
        for _ in range(count):
            items.add()
    if count:
        for (name, dtype, _components), array in zip(_ANCHOR_FIELDS, anchor_list):
            compat.foreach_set(items, name, np.ascontiguousarray(array, dtype=dtype).reshape(-1))
    chosen = active_index if active_index >= 0 else settings.active_anchor_index
    with anchor_view.quietly():  # an operation's new active anchor: no selection change, no framing
        settings.active_anchor_index = max(anchors.clamp_active_index(chosen, count), 0)
    if signature is not None:
        settings.anchors_signature = signature


def read_symmetry_plane(
    layout: bpy.types.Object, axis: str, object_name: str = "", extent: input_policy.Extent | None = None
) -> tuple[mirroring.Plane, str]:
    """The symmetry plane of symmetric anchors in world space, and the name of the object it belongs to.

    The plane through the origin of the layout, or of the Empty ``object_name``, perpendicular to that
    object's local ``axis`` (its local plane ``axis = 0``, as the mirror's). Raises :class:`LayoutError` when
    the object is missing or not an Empty, or its transform gives no plane (NaN, zero scale, out of range).
    """
    owner = layout
    if object_name:
        owner = bpy.data.objects.get(object_name)
        if owner is None:
            raise LayoutError(
                f"There is no object named '{object_name}' for the symmetry plane (deleted?): pick an Empty or none"
            )
        if owner.type != "EMPTY":
            raise LayoutError(
                f"The symmetry object '{object_name}' is a {owner.type.lower()}, not an Empty: its plane is the "
                "Empty's local plane (pick an Empty, or none for the layout's own)"
            )
    matrix = matrix_array(owner.matrix_world)
    if not np.all(np.isfinite(matrix)):
        raise LayoutError(f"'{owner.name}' has a NaN or infinite transform: the symmetry plane is undefined")
    plane = mirroring.plane_from_matrix(matrix, axis)
    input_policy.check_plane(plane.point, plane.normal, owner.name, extent)
    return plane, owner.name


def read_vertex_twins(
    layout: bpy.types.Object, axis: str, object_name: str = "", extent: input_policy.Extent | None = None
) -> tuple[symmetry.Twins, mirroring.Plane, str]:
    """The layout's vertex twins across the symmetry plane (:func:`read_symmetry_plane`), the plane and the name
    of the object it belongs to (object mode data)."""
    arrays = layout_data.read_layout(layout)
    topology = layout_data.read_layout_topology(layout)
    plane, owner = read_symmetry_plane(layout, axis, object_name, extent)
    world = transforms.world_positions(arrays)
    twins = symmetry.vertex_twins(world, topology.face_corners, topology.face_sizes, topology.edges, plane)
    return twins, plane, owner
