"""Plain numpy tests of the add-on's bpy-free state and transform helpers (``core.layout_state``,
``core.transforms``; no Blender needed)."""

import numpy as np
import pytest

from helpers import CORE, core_module

ls = core_module("layout_state")
tf = core_module("transforms")


def face_state(faces, barycentrics=None):
    """A state where faces >= 0 are face-points."""
    faces = np.asarray(faces, dtype=np.int32)
    if barycentrics is None:
        barycentrics = np.tile(np.array([0.2, 0.3, 0.5], dtype=np.float32), (faces.size, 1))
    states = np.where(faces >= 0, ls.FACE_POINT, ls.SPACE_POINT)
    return ls.normalized_state(states, faces, barycentrics)


def test_module_does_not_import_bpy():
    source = (CORE / "layout_state.py").read_text()
    assert "import bpy" not in source and "mathutils" not in source


def test_space_state_is_all_space_points():
    state = ls.space_state(4)
    assert state.states.dtype == np.int32 and state.faces.dtype == np.int32
    assert state.barycentrics.dtype == np.float32 and state.barycentrics.shape == (4, 3)
    assert np.all(state.states == ls.SPACE_POINT)
    assert np.all(state.faces == ls.NO_FACE)
    assert not state.barycentrics.any()


def test_normalized_state_makes_anything_but_face_a_clean_space_point():
    state = ls.normalized_state([1, 0, 7, -3], [5, 6, 7, 8], np.ones((4, 3)))
    assert state.states.tolist() == [1, 0, 0, 0]
    assert state.faces.tolist() == [5, -1, -1, -1]
    assert state.barycentrics[0].tolist() == [1.0, 1.0, 1.0]
    assert not state.barycentrics[1:].any()


def test_point_counts():
    assert ls.point_counts(np.array([1, 0, 1, 1, 0], dtype=np.int32)) == (3, 2)
    assert ls.point_counts(np.zeros(0, dtype=np.int32)) == (0, 0)


def test_signature_depends_on_topology_only():
    triangles = np.array([[0, 1, 2], [2, 1, 3]], dtype=np.uint32)
    signature = ls.target_signature(triangles, 4)
    assert isinstance(signature, str) and len(signature) == 32
    int(signature, 16)  # hex
    assert ls.target_signature(triangles.copy(), 4) == signature
    assert ls.target_signature(triangles.astype(np.int64), 4) == signature  # same indices, other dtype
    assert ls.target_signature(triangles[:1], 4) != signature  # a face deleted
    assert ls.target_signature(triangles[:, [1, 2, 0]], 4) != signature  # re-triangulated / rotated
    assert ls.target_signature(triangles, 5) != signature  # a vertex added


def test_content_hash_is_blake2b_of_shapes_dtypes_and_bytes():
    """Hashed in place, the key is the one the ``tobytes()`` copies gave (cached targets keep their keys)."""
    import hashlib

    vertices = np.arange(12, dtype=np.float64).reshape(4, 3) * 0.1
    triangles = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    digest = hashlib.blake2b(digest_size=16)
    for array in (vertices, triangles):
        digest.update(np.array(array.shape, dtype=np.int64).tobytes())
        digest.update(str(array.dtype).encode())
        digest.update(array.tobytes())
    assert ls.content_hash(vertices, triangles) == digest.hexdigest()
    assert ls.content_hash(np.asfortranarray(vertices), triangles) == digest.hexdigest()


def test_content_hash_changes_with_vertex_positions():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32)
    triangles = np.array([[0, 1, 2]], dtype=np.uint32)
    base = ls.content_hash(vertices, triangles)
    assert ls.content_hash(vertices.copy(), triangles.copy()) == base
    moved = vertices.copy()
    moved[2, 2] = 1e-6
    assert ls.content_hash(moved, triangles) != base
    assert ls.content_hash(vertices, triangles[:, ::-1]) != base


def test_face_points_to_resolve_only_when_signature_changed_or_face_invalid():
    state = face_state([0, -1, 2, 9])  # 9 is out of range for 5 triangles
    unchanged = ls.face_points_to_resolve(state, 5, "abc", "abc")
    assert unchanged.tolist() == [False, False, False, True]
    changed = ls.face_points_to_resolve(state, 5, "abc", "def")
    assert changed.tolist() == [True, False, True, True]
    never_written = ls.face_points_to_resolve(state, 5, "", "def")
    assert never_written.tolist() == [False, False, False, True]


def test_reattach_tolerance_is_relative_to_the_diagonal():
    assert ls.reattach_tolerance((0, 0, 0), (3, 4, 12)) == pytest.approx(13 * ls.REATTACH_TOLERANCE)
    assert ls.reattach_tolerance((1, 1, 1), (1, 1, 1)) == 0.0


def test_resolve_face_points_reattaches_close_points_and_detaches_far_ones():
    state = face_state([4, 5, -1, 6, 7])
    mask = np.array([True, True, False, True, True])
    hit_triangles = np.array([2, 3, 1, -1])
    hit_barycentrics = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]], dtype=np.float32)
    hit_distances = np.array([0.0, 1e-6, 1e-3, np.nan])
    result = ls.resolve_face_points(state, mask, hit_triangles, hit_barycentrics, hit_distances, 1e-5)
    assert result.reattached_count == 2 and result.detached_count == 2
    assert result.state.states.tolist() == [1, 1, 0, 0, 0]
    assert result.state.faces.tolist() == [2, 3, -1, -1, -1]
    assert result.state.barycentrics[:2].tolist() == [[1, 0, 0], [0, 1, 0]]
    assert not result.state.barycentrics[2:].any()
    assert state.faces.tolist() == [4, 5, -1, 6, 7]  # input untouched


def test_detach_points():
    state = face_state([1, 2, 3])
    result = ls.detach_points(state, np.array([False, True, False]))
    assert result.states.tolist() == [1, 0, 1]
    assert result.faces.tolist() == [1, -1, 3]
    assert not result.barycentrics[1].any() and result.barycentrics[0].any()
    assert state.states.tolist() == [1, 1, 1]


def test_attach_points_merges_hits_for_the_mask_only():
    state = face_state([-1, 8, -1, -1])
    mask = np.array([True, True, False, True])
    hit_triangles = np.array([3, -1, 5])
    hit_barycentrics = np.array([[0.5, 0.5, 0], [0, 0, 0], [0, 0, 1]], dtype=np.float32)
    result = ls.attach_points(state, mask, hit_triangles, hit_barycentrics)
    assert result.states.tolist() == [1, 1, 0, 1]
    assert result.faces.tolist() == [3, 8, -1, 5]  # vertex 1 missed: keeps its old face-point
    assert result.barycentrics[0].tolist() == [0.5, 0.5, 0]
    assert result.barycentrics[3].tolist() == [0, 0, 1]
    assert ls.hit_mask(mask, hit_triangles).tolist() == [True, False, False, True]


def test_merge_positions_keeps_untouched_rows_bit_identical():
    positions = np.array([[0.1, 0.2, 0.3], [1, 2, 3], [4, 5, 6]], dtype=np.float32)
    mask = np.array([True, False, True])
    result = ls.merge_positions(positions, mask, np.array([-1, 2]), np.array([[9, 9, 9], [7, 7, 7]]))
    assert result.dtype == np.float32
    assert result[0].tobytes() == positions[0].tobytes()
    assert result[1].tobytes() == positions[1].tobytes()
    assert result[2].tolist() == [7, 7, 7]
    assert positions[2].tolist() == [4, 5, 6]


def random_affine(seed):
    rng = np.random.default_rng(seed)
    matrix = np.eye(4)
    matrix[:3, :3] = rng.normal(size=(3, 3)) + 3 * np.eye(3)
    matrix[:3, 3] = rng.normal(size=3) * 5
    return matrix


def test_transform_points_matches_homogeneous_product_and_inverts():
    matrix = random_affine(1)
    points = np.random.default_rng(2).normal(size=(10, 3)).astype(np.float32)
    homogeneous = np.c_[points.astype(np.float64), np.ones(10)] @ matrix.T
    world = tf.transform_points(matrix, points)
    np.testing.assert_allclose(world, homogeneous[:, :3], rtol=0, atol=1e-12)
    back = tf.transform_points(tf.inverse_matrix(matrix), world)
    np.testing.assert_allclose(back, points, rtol=0, atol=1e-6)


def test_transform_points_and_add_offset_are_numpys_broadcast_sums_bit_for_bit():
    matrix = random_affine(3)
    matrix[:3, 3] = (1e6, -3.3e5, 0.1)
    points = np.random.default_rng(4).normal(size=(1000, 3)) * 100.0
    np.testing.assert_array_equal(tf.transform_points(matrix, points), points @ matrix[:3, :3].T + matrix[:3, 3])
    offset = np.array([-1e6, 2.5, 7e-3])
    moved = tf.add_offset(points.astype(np.float32), offset)
    np.testing.assert_array_equal(moved, points.astype(np.float32).astype(np.float64) + offset)
    assert moved.dtype == np.float64 and moved.flags.c_contiguous
    unchanged = points.copy()
    tf.add_offset(points, offset)  # a copy: the caller's array is left as it was
    np.testing.assert_array_equal(points, unchanged)


def test_transform_directions_ignores_translation():
    matrix = np.eye(4)
    matrix[:3, 3] = (5, 6, 7)
    matrix[0, 0] = 2.0
    result = tf.transform_directions(matrix, np.array([1.0, 1.0, 0.0]))
    assert result.tolist() == [[2.0, 1.0, 0.0]]


def test_transform_normals_stays_perpendicular_under_non_uniform_scale():
    matrix = np.diag([4.0, 1.0, 1.0, 1.0])
    # The plane x = y has normal (1, -1, 0); after scaling x by 4 the plane is x = 4y.
    normal = tf.transform_normals(matrix, np.array([[1.0, -1.0, 0.0], [0.0, 0.0, 0.0]]))
    tangent = tf.transform_directions(matrix, np.array([1.0, 1.0, 0.0]))[0]
    assert abs(normal[0] @ tangent) < 1e-12
    assert np.linalg.norm(normal[0]) == pytest.approx(1.0)
    assert normal[1].tolist() == [0.0, 0.0, 0.0]


def test_normalize_or_zero():
    result = tf.normalize_or_zero(np.array([[3.0, 0, 4], [0, 0, 0], [np.nan, 0, 0]]))
    np.testing.assert_allclose(result[0], [0.6, 0, 0.8])
    assert not result[1:].any()


def test_is_invertible():
    assert tf.is_invertible(random_affine(3))
    assert tf.is_invertible(np.diag([1e-4, 1e-4, 1e-4, 1.0]))  # small but not zero scale
    assert not tf.is_invertible(np.diag([1.0, 0.0, 1.0, 1.0]))
    nan = np.eye(4)
    nan[0, 3] = np.nan
    assert not tf.is_invertible(nan)


def test_axis_direction():
    assert tf.axis_direction("X").tolist() == [1, 0, 0]
    assert tf.axis_direction("-Z").tolist() == [0, 0, -1]
    with pytest.raises(ValueError):
        tf.axis_direction("W")
    with pytest.raises(ValueError):
        tf.axis_direction("--X")


def test_as_float32_points_is_c_contiguous_float32():
    fortran = np.asfortranarray(np.arange(12, dtype=np.float64).reshape(4, 3))
    result = tf.as_float32_points(fortran)
    assert result.dtype == np.float32 and result.flags.c_contiguous and result.shape == (4, 3)
    assert result.tolist() == fortran.tolist()
