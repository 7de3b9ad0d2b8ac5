"""The kernel's Python binding: the array contract, the exceptions, and results against numpy.

No bpy here: these tests check `springwrap_kernel` as any Python pipeline would use it.
"""

import threading

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import grid


def sphere(subdivisions: int = 24, radius: float = 1.0):
    """A closed UV sphere (poles fanned), as float32 / uint32 arrays."""
    rings, segments = subdivisions, 2 * subdivisions
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2 * np.pi * np.arange(segments) / segments
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    body = np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], -1).reshape(-1, 3)
    vertices = np.concatenate([[[0, 0, 1]], body, [[0, 0, -1]]]) * radius
    south = len(vertices) - 1
    ring = lambda r: 1 + r * segments  # noqa: E731
    s = np.arange(segments)
    n = (s + 1) % segments
    triangles = [np.stack([np.zeros(segments, int), ring(0) + s, ring(0) + n], 1)]
    triangles.append(np.stack([np.full(segments, south), ring(rings - 2) + n, ring(rings - 2) + s], 1))
    for r in range(rings - 2):
        a0, b0, c0, d0 = ring(r) + s, ring(r) + n, ring(r + 1) + s, ring(r + 1) + n
        triangles += [np.stack([a0, c0, d0], 1), np.stack([a0, d0, b0], 1)]
    return vertices.astype(np.float32), np.concatenate(triangles).astype(np.uint32)


def brute_force_closest(vertices, triangles, points):
    """Closest distances by testing every triangle, in float64 (Ericson's method, vectorised)."""
    a, b, c = (vertices[triangles[:, k]].astype(np.float64)[None] for k in range(3))
    p = points.astype(np.float64)[:, None]
    ab, ac, ap = b - a, c - a, p - a
    # Inside the triangle the answer is the distance to its plane; otherwise the nearest edge.
    normal = np.cross(ab, ac)
    n2 = (normal * normal).sum(-1)
    t = (ap * normal).sum(-1) / n2
    q = p - t[..., None] * normal
    in_triangle = (
        ((np.cross(b - a, q - a) * normal).sum(-1) >= 0)
        & ((np.cross(c - b, q - b) * normal).sum(-1) >= 0)
        & ((np.cross(a - c, q - c) * normal).sum(-1) >= 0)
    )
    best = np.where(in_triangle, np.abs(t) * np.sqrt(n2), np.inf)
    for start, end in ((a, b), (b, c), (c, a)):
        direction = end - start
        s = np.clip(((p - start) * direction).sum(-1) / (direction * direction).sum(-1), 0, 1)
        closest = start + s[..., None] * direction
        best = np.minimum(best, np.linalg.norm(p - closest, axis=-1))
    return best.min(axis=1)


@pytest.fixture(scope="module")
def sphere_mesh():
    vertices, triangles = sphere()
    return sk.TargetMesh(vertices, triangles)


def test_closest_points_match_brute_force_and_face_points_rebuild_them(sphere_mesh):
    rng = np.random.default_rng(0)
    points = (rng.normal(size=(5000, 3)) * 1.2).astype(np.float32)
    hits = sphere_mesh.closest_points(points)
    vertices, triangles = sphere()
    expected = brute_force_closest(vertices, triangles, points[:500])
    np.testing.assert_allclose(hits.distances[:500], expected, rtol=1e-5, atol=1e-5)
    assert (hits.triangles >= 0).all()
    rebuilt = sphere_mesh.face_point_positions(hits.triangles.astype(np.uint32), hits.barycentrics)
    np.testing.assert_allclose(rebuilt, hits.positions, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(points - hits.positions, axis=1), hits.distances, rtol=1e-4, atol=1e-5)


def test_batch_order_does_not_change_answers(sphere_mesh):
    """Large batches are answered in spatial order internally; answers come back in input order."""
    rng = np.random.default_rng(1)
    points = rng.normal(size=(20000, 3)).astype(np.float32)
    hits = sphere_mesh.closest_points(points)
    permutation = rng.permutation(len(points))
    shuffled = sphere_mesh.closest_points(np.ascontiguousarray(points[permutation]))
    np.testing.assert_array_equal(shuffled.distances, hits.distances[permutation])
    one_by_one = [sphere_mesh.closest_points(points[i : i + 1]).distances[0] for i in range(0, 20000, 997)]
    np.testing.assert_array_equal(one_by_one, hits.distances[::997])


def test_max_distance_marks_misses_with_minus_one(sphere_mesh):
    points = np.array([[0, 0, 3], [0, 0, 1.05]], np.float32)
    hits = sphere_mesh.closest_points(points, max_distance=0.5)
    assert hits.triangles.tolist()[0] == -1 and hits.triangles[1] >= 0
    assert np.isnan(hits.distances[0])
    vertex_hits = sphere_mesh.nearest_vertices(points, max_distance=0.5)
    assert vertex_hits.vertices[0] == -1 and vertex_hits.vertices[1] >= 0


def test_nearest_vertices_land_on_vertices(sphere_mesh):
    rng = np.random.default_rng(2)
    points = rng.normal(size=(3000, 3)).astype(np.float32)
    hits = sphere_mesh.nearest_vertices(points)
    vertices = sphere_mesh.vertices()
    np.testing.assert_array_equal(hits.positions, vertices[hits.vertices])
    distances = np.linalg.norm(points[:, None] - vertices[None], axis=-1).min(axis=1)
    np.testing.assert_allclose(hits.distances, distances, rtol=1e-6)
    corner_of = sphere_mesh.triangles()[hits.triangles]
    assert (corner_of[np.arange(len(points)), hits.barycentrics.argmax(axis=1)] == hits.vertices).all()


def test_ray_cast_axes_both_directions_and_misses():
    vertices, triangles = grid(4)
    mesh = sk.TargetMesh(vertices, triangles)
    origins = np.array([[1.5, 2.5, 2.0], [1.5, 2.5, -1.0], [9.0, 9.0, 1.0]], np.float32)
    down = np.tile(np.array([[0, 0, -1]], np.float32), (3, 1))
    hits = mesh.ray_cast(origins, down)
    assert hits.triangles[0] >= 0 and hits.triangles[1] == -1 and hits.triangles[2] == -1
    np.testing.assert_allclose(hits.positions[0], [1.5, 2.5, 0.0], atol=1e-6)
    assert hits.distances[0] == pytest.approx(2.0)
    both = mesh.ray_cast(origins, down, both_directions=True)
    assert both.triangles[1] >= 0 and both.distances[1] == pytest.approx(-1.0)
    limited = mesh.ray_cast(origins, down, max_distance=1.0, both_directions=True)
    assert limited.triangles[0] == -1 and limited.triangles[1] >= 0


def test_topology_and_normals_of_a_grid():
    vertices, triangles = grid(3)
    mesh = sk.TargetMesh(vertices, triangles)
    assert mesh.boundary_edge_count == 12 and mesh.boundary_edges().shape == (12, 2)
    neighbors = mesh.triangle_neighbors()
    assert neighbors.dtype == np.int32 and neighbors.shape == (18, 3)
    assert ((neighbors == -1).sum()) == 12
    np.testing.assert_array_equal(mesh.face_normals(), np.tile([0, 0, 1], (18, 1)))
    np.testing.assert_array_equal(mesh.vertex_normals(), np.tile([0, 0, 1], (16, 1)))
    assert mesh.bounding_box() == ((0, 0, 0), (3, 3, 0))
    assert "18 triangles" in repr(mesh)


@pytest.mark.parametrize(
    ("make_arguments", "error", "words"),
    [
        (lambda v, t: (v.astype(np.float64), t), sk.ArrayError, "dtype float64"),
        (lambda v, t: (v[:, :2].copy(), t), sk.ArrayError, "shape"),
        (lambda v, t: (np.asfortranarray(v), t), sk.ArrayError, "non-contiguous"),
        (lambda v, t: (v[::2], t), sk.ArrayError, "non-contiguous"),
        (lambda v, t: (v.tolist(), t), sk.ArrayError, "got a list"),
        (lambda v, t: (v, t.astype(np.int64)), sk.ArrayError, "triangles must be"),
        (lambda v, t: (v[:0], t[:0]), sk.EmptyMeshError, "empty mesh"),
        (lambda v, t: (v, t[:0]), sk.EmptyMeshError, "0 triangles"),
        (
            lambda v, t: (np.where(np.arange(len(v))[:, None] == 3, np.nan, v).astype(np.float32), t),
            sk.NonFiniteError,
            "vertex 3",
        ),
        (lambda v, t: (v, np.where(t == 5, 99, t).astype(np.uint32)), sk.IndexOutOfRangeError, "vertex 99"),
        (lambda v, t: (np.zeros_like(v), t), sk.DegenerateMeshError, "degenerate"),
    ],
)
def test_bad_meshes_raise_named_errors(make_arguments, error, words):
    vertices, triangles = grid(2)
    with pytest.raises(error, match=words):
        sk.TargetMesh(*make_arguments(vertices, triangles))


def test_degenerate_triangles_are_kept_unless_rejected():
    vertices, triangles = grid(2)
    vertices = np.concatenate([vertices, [[5, 5, 0], [6, 5, 0], [7, 5, 0]]]).astype(np.float32)
    triangles = np.concatenate([triangles, [[9, 10, 11]]]).astype(np.uint32)
    mesh = sk.TargetMesh(vertices, triangles)
    assert mesh.degenerate_triangle_count == 1 and mesh.triangle_count == 9
    with pytest.raises(sk.DegenerateTriangleError, match="triangle 8"):
        sk.TargetMesh(vertices, triangles, reject_degenerate=True)


def test_bad_queries_raise_named_errors(sphere_mesh):
    good = np.zeros((2, 3), np.float32)
    with pytest.raises(sk.NonFiniteError, match="point 1"):
        sphere_mesh.closest_points(np.array([[0, 0, 0], [np.inf, 0, 0]], np.float32))
    with pytest.raises(sk.InvalidArgumentError, match="max_distance"):
        sphere_mesh.closest_points(good, max_distance=-1.0)
    with pytest.raises(sk.InvalidArgumentError, match="zero-length direction"):
        sphere_mesh.ray_cast(good, good)
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        sphere_mesh.ray_cast(good, np.ones((3, 3), np.float32))
    with pytest.raises(sk.IndexOutOfRangeError, match="triangle 123456"):
        sphere_mesh.face_point_positions(np.array([123456], np.uint32), np.array([[1, 0, 0]], np.float32))
    with pytest.raises(sk.ArrayError, match="triangles must be"):
        sphere_mesh.face_point_positions(np.array([0], np.int64), np.array([[1, 0, 0]], np.float32))


def test_every_error_is_a_springwrap_error_and_a_value_error():
    for name in (
        "ArrayError",
        "EmptyMeshError",
        "NonFiniteError",
        "IndexOutOfRangeError",
        "DegenerateMeshError",
        "DegenerateTriangleError",
        "InvalidArgumentError",
        "DivergedError",
        "InternalError",
    ):
        error = getattr(sk, name)
        assert issubclass(error, sk.SpringwrapError) and issubclass(error, ValueError)


def test_queries_release_the_gil(sphere_mesh):
    """Two threads querying at once both finish with the right answers (the GIL is released)."""
    rng = np.random.default_rng(3)
    points = rng.normal(size=(200000, 3)).astype(np.float32)
    expected = sphere_mesh.closest_points(points).distances
    results = [None, None]

    def work(slot):
        results[slot] = sphere_mesh.closest_points(points).distances

    threads = [threading.Thread(target=work, args=(slot,)) for slot in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for result in results:
        np.testing.assert_array_equal(result, expected)


def test_empty_query_batches_give_empty_results(sphere_mesh):
    hits = sphere_mesh.closest_points(np.zeros((0, 3), np.float32))
    assert hits.triangles.shape == (0,) and hits.positions.shape == (0, 3)


def test_type_stubs_match_the_module():
    """The hand-kept __init__.pyi names exactly what the module exports, methods included."""
    import ast
    from pathlib import Path

    stub = Path(sk.__file__).with_name("__init__.pyi")
    tree = ast.parse(stub.read_text())
    top_level = {node.name for node in tree.body if isinstance(node, (ast.ClassDef, ast.FunctionDef))}
    top_level |= {node.target.id for node in tree.body if isinstance(node, ast.AnnAssign)}
    assert top_level == set(sk.__all__)
    stub_class = next(node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "TargetMesh")
    stub_methods = {node.name for node in stub_class.body if isinstance(node, ast.FunctionDef)} - {"__init__"}
    runtime_methods = {name for name in dir(sk.TargetMesh) if not name.startswith("_")}
    assert stub_methods == runtime_methods
    assert (stub.parent / "py.typed").exists()


def test_the_stubs_wrap_settings_defaults_are_the_kernels():
    """The stub's ``WrapSettings(...)`` defaults (all a reader or an IDE sees) are the kernel's ``WrapSettings()``."""
    import ast
    from pathlib import Path

    tree = ast.parse(Path(sk.__file__).with_name("__init__.pyi").read_text())
    stub_class = next(node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "WrapSettings")
    init = next(node for node in stub_class.body if isinstance(node, ast.FunctionDef) and node.name == "__init__")
    stub_defaults = {
        argument.arg: ast.literal_eval(default)
        for argument, default in zip(init.args.kwonlyargs, init.args.kw_defaults)
    }
    kernel = sk.WrapSettings().to_dict()
    assert list(stub_defaults) == list(kernel)
    for name, value in kernel.items():
        stub_value = stub_defaults[name]
        if isinstance(value, str):
            assert stub_value == value, name
        else:  # float32 inside the kernel: the stub's number must give the same float32
            assert np.float32(stub_value) == np.float32(value), name
    stub_properties = {node.name for node in stub_class.body if isinstance(node, ast.FunctionDef)} - {"__init__"}
    assert stub_properties == {name for name in dir(sk.WrapSettings) if not name.startswith("_")}
    solver_class = next(node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "WrapSolver")
    solver_init = next(
        node for node in solver_class.body if isinstance(node, ast.FunctionDef) and node.name == "__init__"
    )
    assert not set(kernel) & {argument.arg for argument in solver_init.args.kwonlyargs}, "settings go in WrapSettings"
