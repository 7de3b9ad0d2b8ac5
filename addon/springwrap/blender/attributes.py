"""The one reader and writer of mesh attributes, and the layout's attributes built on them.

The layout keeps its face-point state in three attributes and its rest shape in a fourth
(``core.layout_state`` names them); the feature detection writes a colour attribute; the mirror
carries a temporary index through bmesh; the quality read-out writes two POINT attributes and a FACE one
(``core.quality`` names them). All of them move through :func:`read_attribute` / :func:`write_attribute`
(``foreach_get`` / ``foreach_set``, no per-vertex loop). Object mode data only.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import layout_state, parts, quality
from ..core.layout_state import LayoutState

_FOREACH = {
    # data type: (foreach property, numpy dtype, components)
    "INT": ("value", np.int32, 1),
    "FLOAT": ("value", np.float32, 1),
    "BOOLEAN": ("value", bool, 1),
    "FLOAT_VECTOR": ("vector", np.float32, 3),
    "FLOAT_COLOR": ("color", np.float32, 4),
    "FLOAT4X4": ("value", np.float32, 16),
    "INT16_2D": ("value", np.int32, 2),
}

STATE_ATTRIBUTES = (
    (layout_state.STATE_ATTRIBUTE, "INT"),
    (layout_state.FACE_ATTRIBUTE, "INT"),
    (layout_state.BARYCENTRIC_ATTRIBUTE, "FLOAT_VECTOR"),
)
"""The face-point state's attributes, in the order of :class:`~..core.layout_state.LayoutState`'s fields."""


def domain_size(mesh: bpy.types.Mesh, domain: str) -> int:
    """How many elements the mesh has in ``domain`` (``POINT``, ``EDGE``, ``FACE`` or ``CORNER``)."""
    return len({"POINT": mesh.vertices, "EDGE": mesh.edges, "FACE": mesh.polygons, "CORNER": mesh.loops}[domain])


def find_attribute(mesh: bpy.types.Mesh, name: str, data_type: str, domain: str = "POINT"):
    """The named attribute when it exists with the given type and domain, else None."""
    attribute = mesh.attributes.get(name)
    if attribute is None or attribute.domain != domain or attribute.data_type != data_type:
        return None
    return attribute


def point_attribute(mesh: bpy.types.Mesh, name: str, data_type: str):
    """The named POINT attribute when it exists with the given type, else None."""
    return find_attribute(mesh, name, data_type)


def read_attribute(mesh: bpy.types.Mesh, name: str, data_type: str, domain: str = "POINT") -> np.ndarray | None:
    """The flat values of the named attribute of that type and domain (its own length), or None when there is none."""
    attribute = find_attribute(mesh, name, data_type, domain)
    if attribute is None:
        return None
    prop, dtype, components = _FOREACH[data_type]
    values = np.empty(len(attribute.data) * components, dtype=dtype)
    attribute.data.foreach_get(prop, values)
    return values


def read_point_attribute(mesh: bpy.types.Mesh, name: str, data_type: str) -> np.ndarray | None:
    """The flat values of the named POINT attribute of that type (its own length), or None when there is none."""
    return read_attribute(mesh, name, data_type)


def write_attribute(mesh: bpy.types.Mesh, name: str, data_type: str, domain: str, values, replace: bool = True) -> bool:
    """Write ``values`` into the named attribute of ``domain``, creating it when missing; whether it was written.

    An attribute of that name with another type or domain is replaced (``replace``), or left alone
    and nothing is written. The attribute is looked up again after a creation, which may move the
    mesh's other attributes in memory.
    """
    existing = mesh.attributes.get(name)
    if existing is not None and find_attribute(mesh, name, data_type, domain) is None:
        if not replace:
            return False
        mesh.attributes.remove(existing)
        existing = None
    if existing is None:
        mesh.attributes.new(name, data_type, domain)
    prop, dtype, _components = _FOREACH[data_type]
    mesh.attributes[name].data.foreach_set(prop, np.ascontiguousarray(values, dtype=dtype).reshape(-1))
    return True


def write_point_attribute(mesh: bpy.types.Mesh, name: str, data_type: str, values, replace: bool = True) -> bool:
    """Write ``values`` into the named POINT attribute (see :func:`write_attribute`)."""
    return write_attribute(mesh, name, data_type, "POINT", values, replace)


def lift_attributes(mesh: bpy.types.Mesh, data_types) -> list:
    """Remove the mesh's attributes of the given types; what :func:`put_back_attributes` needs to restore them
    (name, domain, type, (count, components) values, in the mesh's order)."""
    lifted = []
    for attribute in list(mesh.attributes):
        if attribute.data_type in data_types:
            name, domain, data_type = attribute.name, attribute.domain, attribute.data_type
            components = _FOREACH[data_type][2]
            values = read_attribute(mesh, name, data_type, domain).reshape(-1, components)
            lifted.append((name, domain, data_type, values))
    for name, *_rest in lifted:
        remove_attribute(mesh, name)
    return lifted


def put_back_attributes(mesh: bpy.types.Mesh, lifted: list, sources: dict) -> None:
    """Recreate attributes lifted by :func:`lift_attributes`, each element taking the values of its source
    (``sources``: domain -> (count,) index of each element's original, as the mesh is now)."""
    for name, domain, data_type, values in lifted:
        write_attribute(mesh, name, data_type, domain, values[np.asarray(sources[domain], dtype=np.int64)])


def remove_attribute(mesh: bpy.types.Mesh, name: str) -> None:
    """Remove the attribute called ``name`` (any type or domain) when the mesh has one."""
    existing = mesh.attributes.get(name)
    if existing is not None:
        mesh.attributes.remove(existing)


# ---------------------------------------------------------------- the layout's positions and state


def read_positions(mesh: bpy.types.Mesh) -> np.ndarray:
    """(N * 3,) float32 local vertex coordinates, as stored."""
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    return positions


def read_state(mesh: bpy.types.Mesh) -> LayoutState:
    """The per-vertex state from the mesh attributes; missing (or wrongly typed) ones mean space-points."""
    vertex_count = len(mesh.vertices)
    arrays = []
    for name, data_type in STATE_ATTRIBUTES:
        values = read_point_attribute(mesh, name, data_type)
        if values is None or values.size != vertex_count * _FOREACH[data_type][2]:
            return layout_state.space_state(vertex_count)
        arrays.append(values)
    return layout_state.normalized_state(*arrays)


def write_state(mesh: bpy.types.Mesh, state: LayoutState, replace: bool = True) -> None:
    """Write the per-vertex state into its attributes (see :func:`write_point_attribute` for ``replace``)."""
    values = (state.states, state.faces, state.barycentrics)
    for (name, data_type), array in zip(STATE_ATTRIBUTES, values):
        write_point_attribute(mesh, name, data_type, array, replace=replace)


def read_rest(layout: bpy.types.Object) -> np.ndarray | None:
    """The layout's stored rest shape (local (N, 3) float32), or None when it has none (object mode)."""
    values = read_point_attribute(layout.data, layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR")
    return None if values is None else values.reshape(-1, 3)


def write_rest(layout: bpy.types.Object, positions: np.ndarray) -> None:
    """Store ``positions`` (local (N, 3)) as the layout's rest shape, replacing any (object mode)."""
    write_point_attribute(layout.data, layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR", positions)


# ---------------------------------------------------------------- a wrap in progress

_ABSENT = "absent"
_FOREIGN = "foreign"


SNAPSHOT_ATTRIBUTES = STATE_ATTRIBUTES + ((layout_state.REST_ATTRIBUTE, "FLOAT_VECTOR"), (parts.PART_ATTRIBUTE, "INT"))
"""What a wrap may write besides positions: the state attributes, the rest shape (written by the final
write when the layout has none yet) and which vertices followed the surface as parts."""

READOUT_ATTRIBUTES = (
    (quality.DISTANCE_ATTRIBUTE, "FLOAT", "POINT"),
    (quality.STRETCH_ATTRIBUTE, "FLOAT", "POINT"),
    (quality.FLIPPED_ATTRIBUTE, "BOOLEAN", "FACE"),
)
"""The quality read-out a wrap's final write adds (``blender.quality``): in the snapshot too."""


class LayoutSnapshot(NamedTuple):
    """The layout's positions, state attributes, rest shape and quality read-out as they were, to put back bit
    for bit (a cancelled or failed wrap)."""

    positions: np.ndarray  # (N * 3,) float32, as read
    # attribute name -> its raw values; _ABSENT when it did not exist; _FOREIGN when an attribute of
    # that name has another type or domain (wrap frames leave it alone, see write_wrap_frame)
    attributes: dict


def take_snapshot(layout: bpy.types.Object) -> LayoutSnapshot:
    """Copy what a wrap writes: positions, the state attributes, the rest shape and the read-out (object mode)."""
    mesh = layout.data
    attributes = {}
    for name, data_type, domain in _snapshot_entries():
        values = read_attribute(mesh, name, data_type, domain)
        if values is None:
            values = _ABSENT if mesh.attributes.get(name) is None else _FOREIGN
        attributes[name] = values
    return LayoutSnapshot(read_positions(mesh), attributes)


def _snapshot_entries():
    """(name, data type, domain) of everything a snapshot keeps besides positions."""
    return tuple((name, data_type, "POINT") for name, data_type in SNAPSHOT_ATTRIBUTES) + READOUT_ATTRIBUTES


def restore_snapshot(layout: bpy.types.Object, snapshot: LayoutSnapshot) -> None:
    """Put back what :func:`take_snapshot` copied: positions, state attributes, rest shape and read-out, bit for
    bit.

    An attribute that did not exist is removed again; one that existed gets its values back.
    """
    mesh = layout.data
    mesh.vertices.foreach_set("co", snapshot.positions)
    for name, data_type, domain in _snapshot_entries():
        saved = snapshot.attributes[name]
        if isinstance(saved, str):
            if saved == _ABSENT:
                remove_attribute(mesh, name)
            continue
        write_attribute(mesh, name, data_type, domain, saved)
    mesh.update()


def write_wrap_frame(layout: bpy.types.Object, positions: np.ndarray, state: LayoutState) -> None:
    """An intermediate frame of a wrap: local positions and the state, without replacing attributes.

    The state attributes are created when missing, but an attribute of the same name with
    another type is left alone (only the final write replaces it, so that a cancel can restore
    everything). Creates no undo step.
    """
    mesh = layout.data
    mesh.vertices.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).reshape(-1))
    write_state(mesh, state, replace=False)
    mesh.update()
