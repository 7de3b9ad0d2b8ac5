"""The layout's shape keys: read as arrays, refused on request, carried over when the basis moves, put back.

With shape keys a mesh's shape lives in its keys (Blender shows the reference key plus the mix of the
others), so an operation reads its positions from the reference key and writes the new basis into the
reference key *and* the mesh vertices, and every other key is carried over onto the new basis
(``core.shape_transfer``). Only key data (``KeyBlock.data``) is written: names, order, values, slider
ranges, vertex groups, mute, interpolation and relative keys are never touched. Object mode data;
``foreach_get`` / ``foreach_set``.
"""

import bpy

import numpy as np

from ..core import shape_transfer
from ..core.errors import LayoutError
from ..core.shape_transfer import ShapeKeys

REFUSED = (
    "Shape Keys is set to Refuse (shape_keys='REFUSE', --shape-keys REFUSE): set it to Transfer to move the basis "
    "and carry the keys over"
)
"""What the refusal says when the ``shape_keys`` option asked for it."""


def has_shape_keys(layout: bpy.types.Object) -> bool:
    """Whether the layout mesh has shape keys (at least a reference key)."""
    keys = layout.data.shape_keys
    return keys is not None and len(keys.key_blocks) > 0


def refuse(layout: bpy.types.Object, mode: str, consequence: str) -> None:
    """Raise :class:`LayoutError` when the layout has shape keys and ``mode`` is not ``'TRANSFER'``."""
    if mode != "TRANSFER" and has_shape_keys(layout):
        raise LayoutError(f"Layout '{layout.name}' has shape keys; {consequence}")


def read(layout: bpy.types.Object) -> ShapeKeys | None:
    """Every key's positions, relative keys and the reference key; None without shape keys. Raises
    :class:`LayoutError` naming a key with a NaN or infinite coordinate."""
    if not has_shape_keys(layout):
        return None
    key = layout.data.shape_keys
    blocks = list(key.key_blocks)
    count = len(layout.data.vertices)
    positions = np.empty((len(blocks), count * 3), dtype=np.float32)
    for index, block in enumerate(blocks):
        if len(block.data) != count:
            raise LayoutError(
                f"Layout '{layout.name}': shape key '{block.name}' has {len(block.data)} points for {count} vertices"
            )
        block.data.foreach_get("co", positions[index])
    reference = next((index for index, block in enumerate(blocks) if block == key.reference_key), 0)
    names = tuple(block.name for block in blocks)
    index_of = {name: index for index, name in enumerate(names)}
    relative = np.full(len(blocks), reference, dtype=np.int64)
    if key.use_relative:  # absolute keys (evaluated by time) are each carried against the reference key
        for index, block in enumerate(blocks):
            parent = block.relative_key
            relative[index] = index_of.get(parent.name, reference) if parent is not None else reference
    keys = ShapeKeys(names, positions.reshape(len(blocks), count, 3), relative, reference)
    shape_transfer.check_keys(keys, layout.name)
    return keys


def read_basis(mesh: bpy.types.Mesh) -> np.ndarray | None:
    """(N * 3,) float32 local positions of the reference key, or None without shape keys."""
    key = mesh.shape_keys
    if key is None or key.reference_key is None or len(key.reference_key.data) != len(mesh.vertices):
        return None
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    key.reference_key.data.foreach_get("co", positions)
    return positions


def write(layout: bpy.types.Object, positions: np.ndarray, reference: int) -> None:
    """Write (K, N, 3) key positions into the key blocks, and the reference key's into the mesh vertices.

    A key whose data is already equal is not written (so it stays bit for bit, and costs nothing).
    """
    mesh = layout.data
    blocks = mesh.shape_keys.key_blocks
    current = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    for index, block in enumerate(blocks):
        values = np.ascontiguousarray(positions[index], dtype=np.float32).reshape(-1)
        block.data.foreach_get("co", current)
        if current.tobytes() != values.tobytes():
            block.data.foreach_set("co", values)
    basis = np.ascontiguousarray(positions[reference], dtype=np.float32).reshape(-1)
    mesh.vertices.foreach_get("co", current)
    if current.tobytes() != basis.tobytes():
        mesh.vertices.foreach_set("co", basis)
    mesh.update()


def restore(layout: bpy.types.Object, keys: ShapeKeys | None) -> None:
    """Put every key (and the mesh vertices, as the reference key) back as :func:`read` found them."""
    if keys is not None and has_shape_keys(layout):
        write(layout, keys.positions, keys.reference)


def carried(
    layout: bpy.types.Object, new_basis: np.ndarray, topology, keys: ShapeKeys | None = None
) -> tuple[np.ndarray, int] | None:
    """(every key's new positions, the reference key's index) once the basis becomes ``new_basis`` (local (N, 3));
    None without shape keys. ``topology`` is the layout's ``subdivision.LayoutTopology`` (None: no faces or
    edges, offsets are then only moved along). ``keys``: the keys as they are now, when the caller has them (else
    read here). Computes, writes nothing."""
    if keys is None:
        keys = read(layout)
    if keys is None:
        return None
    if topology is None:
        return shape_transfer.follow_keys(keys, new_basis), keys.reference
    return (
        shape_transfer.carry_keys(keys, new_basis, topology.face_corners, topology.face_sizes, topology.edges),
        keys.reference,
    )


def follow(layout: bpy.types.Object, keys: ShapeKeys | None, new_basis: np.ndarray) -> None:
    """A live wrap's frame: the keys as they were (``keys``) moved along with the basis, offsets unchanged."""
    if keys is not None:
        write(layout, shape_transfer.follow_keys(keys, new_basis), keys.reference)


def write_mirrored(
    layout: bpy.types.Object, keys: ShapeKeys, source: np.ndarray, original_count: int, reflect_local
) -> None:
    """After the mirror added its copies: the layout's own vertices keep their keys as they were (``keys``,
    read before), each copy gets its source's key positions reflected (``reflect_local``: local (M, 3) points
    to their local mirror images), so a key on one half appears on the other half mirrored."""
    count = len(layout.data.vertices)
    positions = np.empty((len(keys.names), count, 3), dtype=np.float32)
    copies = np.arange(count) >= original_count
    for index in range(len(keys.names)):
        own = keys.positions[index]
        positions[index, ~copies] = own[np.asarray(source)[~copies]]
        positions[index, copies] = reflect_local(own[np.asarray(source)[copies]])
    write(layout, positions, keys.reference)
