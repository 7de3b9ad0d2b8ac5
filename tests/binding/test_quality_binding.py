"""The quality read-out in the kernel (``springwrap_kernel.vertex_stretch``, ``face_normals``, ``flipped_faces``,
``TargetMesh.surface_distances``) against a numpy reference of the same definitions: per-vertex SVDs (Kabsch with
the reflection removed) over each face's neighbourhood, written here as plainly as possible, on grids bent,
folded, crumpled and turned, with triangles and n-gons among the quads, far from the origin and near it."""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import grid


def reference_stretch(points, rest, edges):
    now = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    before = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    usable = np.isfinite(now) & np.isfinite(before)
    ends = edges[usable].reshape(-1).astype(np.int64)
    now_sum = np.bincount(ends, np.repeat(now[usable], 2), minlength=len(points))
    rest_sum = np.bincount(ends, np.repeat(before[usable], 2), minlength=len(points))
    stretch = np.ones(len(points))
    measured = rest_sum > 0.0
    stretch[measured] = now_sum[measured] / rest_sum[measured]
    return stretch


def reference_faces(corners, sizes):
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    return [corners[start : start + size] for start, size in zip(starts, sizes, strict=True)]


def reference_normal(points, face):
    relative = points[face] - points[face].mean(axis=0)
    normal = np.cross(relative, np.roll(relative, -1, axis=0)).sum(axis=0)
    return np.where(np.isfinite(normal), normal, 0.0)


def reference_flipped(points, rest, corners, sizes, edges):
    """Each face against its rest normal turned by the Kabsch rotation of its corners and their edge neighbours
    (a vertex once per way it is reached)."""
    neighbours = [[] for _ in range(len(points))]
    for a, b in edges:
        neighbours[a].append(b)
        neighbours[b].append(a)
    flipped = []
    for face in reference_faces(corners, sizes):
        normal, rest_normal = reference_normal(points, face), reference_normal(rest, face)
        group = list(face) + [other for corner in face for other in neighbours[corner]]
        group = [v for v in group if np.isfinite(points[v]).all() and np.isfinite(rest[v]).all()]
        before = rest[group] - rest[group].mean(axis=0)
        now = points[group] - points[group].mean(axis=0)
        left, _, right = np.linalg.svd(before.T @ now)
        sign = np.sign(np.linalg.det(right.T @ left.T)) or 1.0
        turn = right.T @ np.diag([1.0, 1.0, sign]) @ left.T
        facing = (turn @ rest_normal) @ normal
        judged = normal.any() and rest_normal.any() and np.isfinite(facing)
        flipped.append(bool(judged and facing < 0.0))
    return np.array(flipped)


def layout(n=8, offset=0.0):
    """An n x n quad grid (unit cells, z = 0) with its last row of quads cut into triangles and one pentagon:
    points, corners, sizes, edges."""
    side = n + 1
    points = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="xy"), -1).reshape(-1, 2)
    points = np.column_stack([points, np.zeros(len(points))]).astype(np.float64) + offset
    faces = []
    for row in range(n):
        for column in range(n):
            a = row * side + column
            quad = [a, a + 1, a + side + 1, a + side]
            if row == n - 1:
                faces += [quad[:3], [quad[0], quad[2], quad[3]]]
            else:
                faces.append(quad)
    faces[0] = faces[0] + [len(points)]  # a pentagon: one more vertex below the first quad
    points = np.vstack([points, points[0] + [0.5, -0.5, 0.0]])
    edges = {tuple(sorted((face[k], face[(k + 1) % len(face)]))) for face in faces for k in range(len(face))}
    corners = np.concatenate(faces).astype(np.uint32)
    sizes = np.array([len(face) for face in faces], dtype=np.uint32)
    return points, corners, sizes, np.array(sorted(edges), dtype=np.uint32)


def deformations(points, seed):
    """Shapes of the layout to judge: bent by 120 degrees, turned over whole, folded, crumpled at random."""
    rng = np.random.default_rng(seed)
    centre = points.mean(axis=0)
    bent = points.copy()
    beyond = points[:, 0] > centre[0]
    theta = np.radians(120.0)
    dx, dz = bent[beyond, 0] - centre[0], bent[beyond, 2] - centre[2]
    bent[beyond, 0] = centre[0] + dx * np.cos(theta) - dz * np.sin(theta)
    bent[beyond, 2] = centre[2] + dx * np.sin(theta) + dz * np.cos(theta)
    turned = (points - centre) * [1.0, -1.0, -1.0] + centre
    folded = points.copy()
    folded[12] = points[40] + [0.3, 0.2, 0.05]
    crumpled = points + rng.normal(scale=0.6, size=points.shape)
    return {"bent": bent, "turned": turned, "folded": folded, "crumpled": crumpled}


@pytest.mark.parametrize("offset", [0.0, 2.5e5])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_kernel_readout_agrees_with_the_numpy_reference(offset, seed):
    points, corners, sizes, edges = layout(offset=offset)
    judged = 0
    for name, shape in deformations(points, seed).items():
        flipped = sk.flipped_faces(shape, points, corners, sizes, edges)
        expected = reference_flipped(shape, points, corners, sizes, edges)
        assert np.array_equal(flipped, expected), name
        assert np.allclose(sk.vertex_stretch(shape, points, edges), reference_stretch(shape, points, edges))
        normals = sk.face_normals(shape, corners, sizes)
        reference = np.array([reference_normal(shape, face) for face in reference_faces(corners, sizes)])
        assert np.allclose(normals, reference, atol=1e-9 * max(1.0, offset))
        judged += int(expected.sum())
        stretch, together, diagonal = sk.layout_readout(shape, points, corners, sizes, edges)
        assert np.array_equal(together, expected), name  # the read-out's one call judges as the reference
        assert np.allclose(stretch, reference_stretch(shape, points, edges))
        assert diagonal == pytest.approx(float(np.linalg.norm(shape.max(axis=0) - shape.min(axis=0))))
    assert judged > 0  # the fold and the crumpling turned faces over: the comparison judged both answers
    stretch, flipped, _ = sk.layout_readout(points, None, corners, sizes, edges)
    assert (stretch == 1.0).all() and not flipped.any()  # no rest shape: nothing measured against it


def test_non_finite_and_degenerate_inputs_read_as_the_reference_does():
    points, corners, sizes, edges = layout(n=4)
    broken = points.copy()
    broken[3] = np.nan
    broken[corners[4:8]] = broken[corners[4]]  # a quad collapsed to a point
    flipped = sk.flipped_faces(broken, points, corners, sizes, edges)
    assert np.array_equal(flipped, reference_flipped(broken, points, corners, sizes, edges))
    stretch = sk.vertex_stretch(broken, points, edges)
    assert np.allclose(stretch, reference_stretch(broken, points, edges)) and np.isfinite(stretch).all()


def test_surface_distances_are_the_closest_points_distances_with_or_without_a_start():
    vertices, triangles = grid(6)
    mesh = sk.TargetMesh(vertices, triangles)
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-1, 7, 200), rng.uniform(-1, 7, 200), rng.uniform(-1, 1, 200)])
    hits = mesh.closest_points(points.astype(np.float32))
    expected = np.linalg.norm(points - hits.positions.astype(np.float64), axis=1)
    plain = mesh.surface_distances(points)
    started = mesh.surface_distances(points, near=rng.integers(0, len(triangles), 200).astype(np.uint32))
    assert np.allclose(plain, expected, atol=1e-6) and np.array_equal(plain, started)
    points[0] = np.inf
    assert mesh.surface_distances(points)[0] == np.inf
    on = hits.positions.astype(np.float64)[1:]  # on their triangles: read from them, as the search finds
    near = hits.triangles[1:].astype(np.uint32)
    assert np.allclose(mesh.surface_distances(on, near=near, on_surface=1e-6), mesh.surface_distances(on), atol=1e-6)
    with pytest.raises(sk.InvalidArgumentError, match="on_surface"):
        mesh.surface_distances(on, on_surface=float("nan"))


def test_bad_layout_arrays_raise_naming_the_problem():
    points, corners, sizes, edges = layout(n=2)
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.flipped_faces(points, points, corners, sizes, np.array([[0, 999]], np.uint32))
    with pytest.raises(sk.SpringwrapError, match="face"):
        sk.face_normals(points, corners, sizes + 1)
    with pytest.raises(sk.ArrayError, match="float64"):
        sk.vertex_stretch(points.astype(np.float32), points, edges)


def placed(points, matrix):
    """(N, 3) float64 world points of float32 local ``points`` under ``matrix`` (numpy, the reference)."""
    return points.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize(
    "linear",
    [np.eye(3), np.diag([2.0, 0.25, 1.5]), np.diag([-1.0, 0.5, 3.0]) @ np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]])],
)
def test_placed_readout_is_the_readout_and_distances_of_the_world_positions(linear):
    points, corners, sizes, edges = layout(n=6)
    vertices, triangles = grid(8)
    origin = np.array([100.0, -50.0, 7.0])
    mesh = sk.TargetMesh((vertices - [1.0, 1.0, 0.5]).astype(np.float32), triangles)
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = linear, origin + [0.5, 0.5, 0.0]
    for name, shape in deformations(points, 5).items():
        local, rest = shape.astype(np.float32), points.astype(np.float32)
        world, world_rest = placed(local, matrix), placed(rest, matrix)
        near = np.arange(len(local), dtype=np.uint32) % len(triangles)
        distances, stretch, flipped, diagonal = sk.placed_readout(
            mesh, local, rest, matrix, corners, sizes, edges, origin=origin, near=near, on_surface=1e-6
        )
        expected_stretch, expected_flipped, expected_diagonal = sk.layout_readout(
            world, world_rest, corners, sizes, edges
        )
        assert np.array_equal(flipped, expected_flipped), name
        assert np.allclose(stretch, expected_stretch, rtol=1e-12, atol=0.0), name
        assert diagonal == pytest.approx(expected_diagonal, rel=1e-12)
        expected = mesh.surface_distances(world - origin, near=near, on_surface=1e-6)
        assert np.allclose(distances, expected, rtol=1e-9, atol=1e-9), name
    unmeasured = sk.placed_readout(mesh, local, None, matrix, corners, sizes, edges)
    assert (unmeasured[1] == 1.0).all() and not unmeasured[2].any()
    stray = rest.copy()
    stray[2] = np.inf  # a rest shape not finite: not used, as none
    assert all(
        np.array_equal(a, b)
        for a, b in zip(sk.placed_readout(mesh, local, stray, matrix, corners, sizes, edges), unmeasured, strict=True)
    )


def test_placed_readout_refuses_bad_arrays_naming_the_problem():
    points, corners, sizes, edges = layout(n=2)
    vertices, triangles = grid(4)
    mesh = sk.TargetMesh(vertices, triangles)
    local = points.astype(np.float32)
    arguments = (local, local, np.eye(4), corners, sizes, edges)
    with pytest.raises(sk.ArrayError, match="positions.*float32"):
        sk.placed_readout(mesh, points, local, np.eye(4), corners, sizes, edges)
    with pytest.raises(sk.SpringwrapError, match="rest"):
        sk.placed_readout(mesh, local, local[1:], np.eye(4), corners, sizes, edges)
    with pytest.raises(sk.InvalidArgumentError, match="matrix.*last row"):
        sk.placed_readout(mesh, local, local, np.ones((4, 4)), corners, sizes, edges)
    with pytest.raises(sk.ArrayError, match="matrix"):
        sk.placed_readout(mesh, local, local, np.eye(3), corners, sizes, edges)
    with pytest.raises(sk.ArrayError, match="origin"):
        sk.placed_readout(mesh, *arguments, origin=np.zeros(2))
    with pytest.raises(sk.SpringwrapError, match="near"):
        sk.placed_readout(mesh, *arguments, near=np.zeros(3, np.uint32))
    with pytest.raises(sk.InvalidArgumentError, match="on_surface"):
        sk.placed_readout(mesh, *arguments, on_surface=-1.0)
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.placed_readout(mesh, local, local, np.eye(4), corners, sizes, np.array([[0, 999]], np.uint32))
    with pytest.raises(sk.ArgumentTypeError, match="TargetMesh"):
        sk.placed_readout("mesh", *arguments)
    far = local.copy()
    far[0] = 1e30
    with pytest.raises(sk.CoordinateRangeError):
        sk.placed_readout(mesh, far, local, np.eye(4), corners, sizes, edges)
