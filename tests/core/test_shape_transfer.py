"""Shape keys carried over a change of shape (``addon/springwrap/core/shape_transfer.py``), no Blender.

Generated geometry: a quad sphere (a cube's grid pushed onto the unit sphere), moved rigidly, scaled, or
stretched into an ellipsoid, with keys whose offsets are known.
"""

import numpy as np
import pytest

from helpers import core_module, cube_sphere_cage

shape_transfer = core_module("shape_transfer")
errors = core_module("errors")


def quad_sphere(cuts=8):
    """(float64 positions, corners, sizes, unique edges) of the unit quad sphere."""
    positions, corners, sizes = cube_sphere_cage(cuts)
    faces = corners.astype(np.int64).reshape(-1, 4)  # quads only
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    edges = np.unique(np.sort(pairs, axis=1), axis=0)
    return positions.astype(np.float64), corners, sizes, edges


def cap_offsets(positions, axis=(1.0, 0.0, 0.0), amount=0.1, angle=35.0):
    """A key pushing the cap within ``angle`` degrees of ``axis`` out along the sphere's normal by ``amount``."""
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    cap = normals @ np.asarray(axis) > np.cos(np.radians(angle))
    offsets = np.where(cap[:, None], amount * normals, 0.0)
    return offsets, cap


def keys_of(basis, *offsets, relative=None):
    positions = np.stack([basis] + [basis + offset for offset in offsets]).astype(np.float32)
    count = positions.shape[0]
    return shape_transfer.ShapeKeys(
        names=tuple(f"Key {index}" for index in range(count)),
        positions=positions,
        relative=np.zeros(count, dtype=np.int64) if relative is None else np.asarray(relative),
        reference=0,
    )


def rotation(axis, degrees):
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    angle = np.radians(degrees)
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def test_a_similarity_turns_and_scales_every_offset_exactly():
    positions, corners, sizes, edges = quad_sphere()
    turn = rotation([1.0, 2.0, 0.5], 70.0)
    moved = 2.5 * positions @ turn.T + [3.0, -1.0, 0.5]
    maps = shape_transfer.transfer_maps(positions, moved, corners, sizes, edges)
    assert not maps.fallback.any() and maps.moved.all()
    np.testing.assert_allclose(maps.matrices, np.broadcast_to(2.5 * turn, maps.matrices.shape), atol=1e-9)
    offsets = np.random.default_rng(3).normal(size=positions.shape)
    offsets[::2, 2] = 0.0  # a zero component is not a zero offset: it turns into the others
    offsets[::3] = 0.0
    np.testing.assert_allclose(shape_transfer.transfer_offsets(maps, offsets), 2.5 * offsets @ turn.T, atol=1e-9)


def test_the_in_plane_turn_does_not_depend_on_the_starting_tangent():
    """Turning the sphere about the normal of a vertex turns a tangential offset there by the same angle."""
    positions, corners, sizes, edges = quad_sphere()
    turn = rotation([0.0, 0.0, 1.0], 33.0)
    maps = shape_transfer.transfer_maps(positions, positions @ turn.T, corners, sizes, edges)
    top = int(np.argmax(positions[:, 2]))
    tangential = np.array([0.05, 0.0, 0.0])
    np.testing.assert_allclose(maps.matrices[top] @ tangential, turn @ tangential, atol=1e-9)


@pytest.mark.parametrize("axis_index", [0, 1, 2])
def test_a_cap_pushed_out_on_the_sphere_is_pushed_out_along_the_ellipsoid_normal(axis_index):
    """The acceptance test's numbers on an exact map: the unit sphere stretched to semi-axes (2.2, 2.0, 1.8). At a
    pole the push grows by the root of the two tangential stretches (the local area ratio) and stays
    along the ellipsoid's normal."""
    semi_axes = np.array([2.2, 2.0, 1.8])
    positions, corners, sizes, edges = quad_sphere(cuts=12)
    axis = np.eye(3)[axis_index]
    offsets, cap = cap_offsets(positions, axis)
    ellipsoid = positions * semi_axes
    keys = keys_of(positions, offsets)
    carried = shape_transfer.carry_keys(keys, ellipsoid, corners, sizes, edges)
    new_offsets = carried[1].astype(np.float64) - ellipsoid
    normals = ellipsoid / semi_axes**2
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    along = np.einsum("ij,ij->i", new_offsets, normals)
    pole = int(np.argmax(positions @ axis))
    expected = 0.1 * np.sqrt(np.prod(np.delete(semi_axes, axis_index)))
    assert along[pole] == pytest.approx(expected, rel=5e-3)  # the discrete one-ring areas
    across = np.linalg.norm(new_offsets - along[:, None] * normals, axis=1)
    assert np.all(across[cap] < 0.05 * np.abs(along[cap]))  # along the normal over the whole cap
    assert np.all(along[cap] > 0.18) and np.all(along[cap] < 0.22)  # 0.2 within 10 % on this exact stretch


def test_zero_offsets_stay_exactly_zero_and_unmoved_vertices_keep_their_offsets():
    positions, corners, sizes, edges = quad_sphere()
    offsets, cap = cap_offsets(positions)
    # Only the +z half moves: the -z half's keys (and its cap-free vertices) must not drift by a bit.
    moved = positions.copy()
    moved[positions[:, 2] > 0.3] *= 1.3
    keys = keys_of(positions, offsets, np.where(positions[:, 2:] < -0.6, [[0.0, 0.01, 0.0]], 0.0))
    carried = shape_transfer.carry_keys(keys, moved, corners, sizes, edges)
    basis = moved.astype(np.float32)
    untouched = ~cap
    assert carried[1][untouched].tobytes() == basis[untouched].tobytes()
    maps = shape_transfer.transfer_maps(positions, moved, corners, sizes, edges)
    still = ~maps.moved
    assert still.sum() > 100
    assert carried[2][still].tobytes() == keys.positions[2][still].tobytes()


def test_keys_relative_to_another_key_carry_their_offset_from_that_key():
    positions, corners, sizes, edges = quad_sphere()
    first, _ = cap_offsets(positions)
    second = first + np.where(first != 0.0, 0.02, 0.0)  # relative to the first: 0.02 more where it moved
    keys = keys_of(positions, first, second, relative=[0, 0, 1])
    moved = 2.0 * positions
    carried = shape_transfer.carry_keys(keys, moved, corners, sizes, edges).astype(np.float64)
    np.testing.assert_allclose(carried[2] - carried[1], 2.0 * (second - first), atol=1e-5)
    np.testing.assert_allclose(carried[1] - carried[0], 2.0 * first, atol=1e-5)
    # Where the second key equals the first, it stays exactly on the first's new position.
    same = np.all(second == first, axis=1)
    assert carried[2][same].tobytes() == carried[1][same].tobytes()


def test_relative_keys_in_a_cycle_or_to_themselves_are_taken_against_the_basis():
    keys = shape_transfer.ShapeKeys(("B", "A", "C", "D"), np.zeros((4, 1, 3), np.float32), np.array([0, 2, 1, 3]), 0)
    order = shape_transfer.key_order(keys)
    assert sorted(key for key, _ in order) == [1, 2, 3]
    parents = dict(order)
    assert parents[3] == 0
    placed = {0}
    for key, parent in order:
        assert parent in placed  # each key after the key it needs
        placed.add(key)


def test_degenerate_faces_loose_vertices_and_boundaries_never_give_nan():
    positions, corners, sizes, edges = quad_sphere(cuts=4)
    collapsed = positions.copy()
    collapsed[corners[:4]] = positions[corners[0]]  # one face collapsed to a point
    collapsed[:, 2] = np.where(positions[:, 2] > 0.9, 0.9, positions[:, 2])  # a flattened region
    # Loose chain vertices (no face), a lone vertex, and a border: half the sphere's faces only.
    half = np.flatnonzero(np.repeat(positions[corners[::4], 2] > 0.0, 1))
    face_corners = corners.reshape(-1, 4)[half].ravel()
    face_sizes = sizes[half]
    extra = np.array([[5.0, 0.0, 0.0], [5.5, 0.0, 0.0], [6.0, 0.1, 0.0], [9.0, 9.0, 9.0]])
    rest = np.concatenate([positions, extra])
    deformed = np.concatenate([collapsed, extra @ rotation([0, 0, 1], 90).T * 2.0])
    count = len(positions)
    chain = np.array([[count, count + 1], [count + 1, count + 2]])
    all_edges = np.concatenate([edges, chain])
    maps = shape_transfer.transfer_maps(rest, deformed, face_corners, face_sizes, all_edges)
    assert np.all(np.isfinite(maps.matrices))
    offsets = np.random.default_rng(5).normal(size=rest.shape)
    assert np.all(np.isfinite(shape_transfer.transfer_offsets(maps, offsets)))
    assert maps.fallback[count : count + 4].all()
    # The chain turned by 90 degrees about z and doubled: its offsets too.
    np.testing.assert_allclose(
        maps.matrices[count] @ [0.1, 0.0, 0.0], 2.0 * rotation([0, 0, 1], 90) @ [0.1, 0.0, 0.0], atol=1e-9
    )
    assert np.allclose(maps.matrices[count + 3], np.eye(3))  # the lone vertex: offsets kept


def test_a_nan_key_is_refused_naming_the_key_and_the_vertex():
    positions, *_ = quad_sphere(cuts=2)
    offsets = np.zeros_like(positions)
    keys = keys_of(positions, offsets, offsets)
    keys.positions[2, 7, 1] = np.nan
    with pytest.raises(errors.LayoutError, match="shape key 'Key 2' has a NaN or infinite coordinate at vertex 7"):
        shape_transfer.check_keys(keys, "Layout")


def test_live_frames_move_the_keys_along_with_the_basis():
    positions, *_ = quad_sphere(cuts=2)
    offsets, _ = cap_offsets(positions)
    keys = keys_of(positions, offsets)
    followed = shape_transfer.follow_keys(keys, positions + 1.0)
    np.testing.assert_allclose(followed[1] - followed[0], offsets, atol=1e-6)
    assert followed[0].tobytes() == (positions + 1.0).astype(np.float32).tobytes()
