"""Plain tests of the creases of a re-tessellated part (``addon/springwrap/core/rounded_creases.py``), no
Blender: a box whose edges a re-tessellation rounded (a grid on each face, each quad cut along a random diagonal,
its vertices pushed onto a box with rounded edges), its sharp twin, and bad inputs."""

import numpy as np

from helpers import core_module

rc = core_module("rounded_creases")
fl = core_module("feature_lines")

HALF = 1.0  # the box spans -HALF..HALF on each axis


def box(cells=24, radius=0.1, seed=3):
    """(positions, triangles) of a box of side 2 whose edges are rounded with ``radius`` (0: sharp), each face a
    ``cells`` x ``cells`` grid of quads each split along a random diagonal (the tessellation ignores the
    creases, as a voxel remesh's does)."""
    rng = np.random.default_rng(seed)
    steps = np.linspace(-HALF, HALF, cells + 1)
    points, triangles = [], []
    for axis in range(3):
        for side in (-HALF, HALF):
            u, v = np.meshgrid(steps, steps, indexing="ij")
            face = np.zeros((cells + 1, cells + 1, 3))
            others = [a for a in range(3) if a != axis]
            face[..., axis], face[..., others[0]], face[..., others[1]] = side, u, v
            index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1) + sum(len(p) for p in points)
            a, b, c, d = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
            flip = rng.random(a.shape) < 0.5
            first = np.where(flip[..., None], np.stack([a, b, c], -1), np.stack([a, b, d], -1))
            second = np.where(flip[..., None], np.stack([a, c, d], -1), np.stack([b, c, d], -1))
            found = np.concatenate([first.reshape(-1, 3), second.reshape(-1, 3)])
            outward = (side > 0) == (axis != 1)  # the winding that makes this face's normals point out
            triangles.append(found if outward else found[:, ::-1])
            points.append(face.reshape(-1, 3))
    points, triangles = np.concatenate(points), np.concatenate(triangles)
    merged, inverse = np.unique(np.round(points, 9), axis=0, return_inverse=True)
    triangles = inverse.reshape(-1)[triangles]
    if radius > 0.0:
        inner = HALF - radius
        core = np.clip(merged, -inner, inner)
        offset = merged - core
        merged = core + radius * offset / np.linalg.norm(offset, axis=1, keepdims=True)
    return merged, triangles


def crest(points, radius=0.1):
    """Each point's distance from the nearest crest of the rounded box: the surface point nearest the sharp box's
    edge it rounds (the middle of the quarter cylinder), on the edge's straight stretch."""
    inner = HALF - radius
    corner_offset = radius / np.sqrt(2.0)
    found = np.full(points.shape[0], np.inf)
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        for signs in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            target = np.array(signs) * (inner + corner_offset)
            lateral = np.linalg.norm(points[:, others] - target, axis=1)
            along = np.maximum(np.abs(points[:, axis]) - inner, 0.0)
            found = np.minimum(found, np.hypot(lateral, along))
    return found


def test_a_rounded_box_has_its_twelve_edges_as_ridges_on_their_crests_meeting_at_its_eight_corners():
    positions, triangles = box()
    found = rc.rounded_creases(positions, triangles, 30.0)
    assert len(found.curves) == 12
    assert {kind for kind, _points, _closed in found.curves} == {"RIDGE"}
    edge = 2.0 / 24
    for _kind, points, closed in found.curves:
        assert not closed
        length = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
        assert length > 2.0 * (HALF - 0.1)  # the whole edge, its rounding's ends and the corners
        middle = points[np.abs(points).min(axis=1) < HALF - 0.3]  # the straight stretch
        assert middle.shape[0] >= 10
        assert crest(middle.astype(np.float64)).max() < 0.05 * edge
    assert found.junctions.shape == (8, 3)
    expected = (HALF - 0.1) + 0.1 / np.sqrt(3.0)  # the rounded corner's point nearest the sharp corner
    assert np.allclose(np.abs(found.junctions), expected, atol=0.3 * edge)


def test_each_rounded_crease_runs_from_corner_to_corner_ending_on_the_junctions():
    positions, triangles = box()
    found = rc.rounded_creases(positions, triangles, 30.0)
    ends = np.concatenate([points[[0, -1]] for _kind, points, _closed in found.curves]).astype(np.float64)
    nearest = np.linalg.norm(ends[:, None, :] - found.junctions[None, :, :], axis=2).min(axis=1)
    assert nearest.max() < 1e-5


def test_inside_out_the_box_has_valleys():
    positions, triangles = box()
    found = rc.rounded_creases(positions, triangles[:, ::-1], 30.0)
    assert len(found.curves) == 12
    assert {kind for kind, _points, _closed in found.curves} == {"VALLEY"}


def test_a_sharp_box_gives_its_edges_exactly():
    positions, triangles = box(radius=0.0)
    found = rc.rounded_creases(positions, triangles, 30.0)
    assert len(found.curves) == 12
    for _kind, points, _closed in found.curves:
        on_edge = np.sort(np.abs(points.astype(np.float64)), axis=1)[:, 1:]  # the two coordinates at the edge
        assert np.allclose(on_edge, HALF, atol=1e-5)


def test_the_crease_angle_decides_which_bends_are_creases():
    positions, triangles = box()
    assert rc.rounded_creases(positions, triangles, 100.0).curves == []  # a box's edges bend 90 degrees
    assert rc.rounded_creases(positions, triangles, 0.0).curves == []  # 0: no creases


def test_the_target_features_take_the_rounded_creases_and_their_corners():
    positions, triangles = box()
    curves, junctions = fl.target_features([], positions.astype(np.float32), triangles, 30.0, 0.1)
    creases = [curve for curve in curves if curve[0] == "RIDGE"]
    assert len(creases) == 12
    assert all(accuracy < 0.01 for _kind, _points, _closed, accuracy in creases)
    assert junctions.shape == (8, 3)


def test_bad_inputs_give_no_creases_and_no_error():
    positions, triangles = box()
    empty = rc.rounded_creases(positions, np.zeros((0, 3), dtype=np.int64), 30.0)
    assert empty.curves == [] and empty.junctions.shape == (0, 3)
    flat = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64)
    assert rc.rounded_creases(flat, np.array([[0, 1, 2], [0, 2, 3]]), 30.0).curves == []
    collapsed = np.zeros_like(positions)  # every triangle degenerate
    assert rc.rounded_creases(collapsed, triangles, 30.0).curves == []
    # Degenerate triangles in the middle of a face change nothing.
    centre = int(np.argmin(np.linalg.norm(positions - [0.0, 0.0, HALF], axis=1)))
    spoiled = np.concatenate([triangles, [[centre, centre, centre], [centre, centre, centre + 1]]])
    assert len(rc.rounded_creases(positions, spoiled, 30.0).curves) == 12


def test_a_mostly_curved_mesh_has_no_rounded_creases():
    """A box whose faces are rough all over (most triangles bend from their neighbours: an organic shape's
    tessellation, not a machined part's flat faces) is not searched, and a sphere has no crease anywhere."""
    positions, triangles = box()
    rough = positions + np.random.default_rng(5).normal(scale=0.01, size=positions.shape)
    assert rc.rounded_creases(rough, triangles, 30.0).curves == []
    sphere = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    found = rc.rounded_creases(sphere, triangles, 30.0)
    assert found.curves == [] and found.junctions.shape == (0, 3)


def test_the_corners_where_the_flanks_meet_are_the_box_s_sharp_corners():
    """The rounded corners' junctions lie on the surface; the points where their flanks' planes meet are the sharp
    corners the rounding cut off (what a layout's own sharp corner maps to)."""
    positions, triangles = box()
    found = rc.rounded_creases(positions, triangles, 30.0)
    assert found.corners.shape == found.junctions.shape == (8, 3)
    assert np.allclose(np.abs(found.corners), HALF, atol=0.1 * (2.0 / 24))  # the surface point is 0.5 edges off
    assert np.all(np.linalg.norm(found.corners - found.junctions, axis=1) > 0.02)  # off the surface


def quad_cube(cells=4):
    """(positions, face corners (flat), face sizes) of a cube -1..1 whose faces are ``cells`` x ``cells`` quads."""
    points, faces, index = [], [], {}

    def vertex(p):
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(points)
            points.append(p)
        return index[key]

    steps = np.linspace(-1.0, 1.0, cells + 1)
    for axis in range(3):
        for side in (-1.0, 1.0):
            u, v = [a for a in range(3) if a != axis]
            for i in range(cells):
                for j in range(cells):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3)
                        p[axis], p[u], p[v] = side, steps[i + di], steps[j + dj]
                        quad.append(vertex(p))
                    faces.append(quad if side > 0 else quad[::-1])
    return np.array(points), np.array(faces).ravel(), np.full(len(faces), 4)


def test_a_corner_vertex_beside_its_corner_is_taken_to_where_its_flanks_meet():
    """A retopology put the cube's corner vertex 0.3 edges inside the corner: its corner is where the planes of its
    three flanks meet; a vertex at its corner and a vertex in the middle of a face (no three flanks) stay."""
    positions, corners, sizes = quad_cube()
    corner = int(np.argmin(np.linalg.norm(positions - [1.0, 1.0, 1.0], axis=1)))
    middle = int(np.argmin(np.linalg.norm(positions - [1.0, 0.0, 0.0], axis=1)))
    other = int(np.argmin(np.linalg.norm(positions - [-1.0, -1.0, -1.0], axis=1)))
    moved = positions.copy()
    moved[corner] -= 0.3 * 0.5 / np.sqrt(3.0)  # 0.3 of an edge (0.5) toward the centre
    found = rc.sharp_corners(moved, corners, sizes, [corner, other, middle], 30.0)
    np.testing.assert_allclose(found[0], [1.0, 1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(found[1:], moved[[other, middle]])
    assert rc.sharp_corners(moved, corners, sizes, [corner], 0.0).tolist() == [moved[corner].tolist()]
    assert rc.sharp_corners(moved, corners, sizes, [], 30.0).shape == (0, 3)
    lost = moved.copy()
    lost[corner - 1 if corner else corner + 1] = np.nan  # a vertex beside it lost (a diverged wrap's)
    assert np.isfinite(rc.sharp_corners(lost, corners, sizes, [corner, other], 30.0)[1]).all()


def test_a_corner_whose_third_flank_is_bent_near_it_is_found_one_ring_farther():
    """The cube's corner vertex a third of an edge along the x crease, the top face bent beside the corner (a vertex
    raised, its triangles not flat): its two rings show two flanks, the ring beyond shows the top's flat triangles,
    and the vertex is taken to where the three planes meet. Bent farther (the third ring too), it stays."""
    positions, corners, sizes = quad_cube(8)
    edge = 0.25
    corner = int(np.argmin(np.linalg.norm(positions - [1.0, 1.0, 1.0], axis=1)))
    for bent, expected in ((1, [1.0, 1.0, 1.0]), (2, None)):
        moved = positions.copy()
        inner = np.all(moved[:, :2] < 1.0 - 1e-9, axis=1) & np.all(moved[:, :2] > 1.0 - (bent + 0.5) * edge, axis=1)
        top = inner & (np.abs(moved[:, 2] - 1.0) < 1e-9)
        parity = np.round((moved[:, 0] + moved[:, 1]) / edge).astype(int) % 2 * 2 - 1
        moved[top, 2] += 0.1 * edge * parity[top]
        moved[corner, 0] -= 0.33 * edge
        found = rc.sharp_corners(moved, corners, sizes, [corner], 30.0)[0]
        np.testing.assert_allclose(found, moved[corner] if expected is None else expected, atol=1e-6)
