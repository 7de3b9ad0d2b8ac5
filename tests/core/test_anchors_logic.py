"""Plain tests of the add-on's bpy-free anchor logic (``addon/springwrap/core/anchors.py``), no Blender.

The spacing choice is checked against a brute-force greedy reference; resolution, add and auto
run on small generated targets built with the kernel (``springwrap_kernel``, importable without
Blender).
"""

import sys

import numpy as np
import pytest

from helpers import CORE, core_module, grid_triangles

an = core_module("anchors")
ls = sys.modules[an.__name__.rpartition(".")[0] + ".layout_state"]
tf = sys.modules[an.__name__.rpartition(".")[0] + ".transforms"]
tg = sys.modules[an.__name__.rpartition(".")[0] + ".target"]


# ---------------------------------------------------------------- generated geometry


def grid_target(size=4.0, cells=8, height=0.0):
    """A flat square grid in the plane z = ``height``, centred on the origin, as a kernel target."""
    coordinates = np.linspace(-size / 2, size / 2, cells + 1)
    x, y = np.meshgrid(coordinates, coordinates, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.full(x.size, height)], axis=1).astype(np.float32)
    return make_target(vertices, grid_triangles(cells))


def make_target(vertices, triangles):
    """A ``core.target.Target`` over a kernel mesh, as ``blender.target.read_target`` builds it."""
    return tg.make_target("Target", np.asarray(vertices, dtype=np.float64), triangles)


def layout_arrays(positions, matrix_world=None):
    """``LayoutArrays`` of a layout with the given local positions (all space-points)."""
    positions = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
    matrix = np.eye(4) if matrix_world is None else np.asarray(matrix_world, dtype=np.float64)
    return ls.LayoutArrays(positions, matrix, np.zeros(len(positions), dtype=bool), ls.space_state(len(positions)))


def layout_grid(count=15, size=3.0, height=1.0):
    """A flat grid of ``count`` x ``count`` layout points above the target, at z = ``height``."""
    coordinates = np.linspace(-size / 2, size / 2, count)
    x, y = np.meshgrid(coordinates, coordinates, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, height)], axis=1)


def greedy_reference(points, spacing, candidates=None, seeds=()):
    """The O(N^2) greedy Poisson-disk choice, in index order: what spaced_indices must return."""
    chosen_points = [np.asarray(seed, dtype=np.float64) for seed in seeds]
    chosen = []
    for index, point in enumerate(np.asarray(points, dtype=np.float64)):
        if candidates is not None and not candidates[index]:
            continue
        if all(np.sum((point - other) ** 2) >= spacing * spacing for other in chosen_points):
            chosen_points.append(point)
            chosen.append(index)
    return np.array(chosen, dtype=np.int64)


def pairwise_min_distance(points):
    differences = points[:, None, :] - points[None, :, :]
    distances = np.sqrt(np.sum(differences**2, axis=2))
    distances[np.diag_indices(len(points))] = np.inf
    return distances.min()


# ---------------------------------------------------------------- module and list basics


def test_module_does_not_import_bpy():
    source = (CORE / "anchors.py").read_text()
    assert "import bpy" not in source and "mathutils" not in source and "bmesh" not in source


def test_kinds_are_the_point_states():
    assert an.FACE_ANCHOR == ls.FACE_POINT and an.SPACE_ANCHOR == ls.SPACE_POINT


def test_make_anchors_writes_space_anchors_canonically():
    anchors = an.make_anchors([4, 5, 6], [1, 0, 7], [3, 9, 9], np.ones((3, 3)), np.arange(9).reshape(3, 3))
    assert anchors.vertex_indices.dtype == np.int32 and anchors.kinds.dtype == np.int32
    assert anchors.barycentrics.dtype == np.float32 and anchors.locations.dtype == np.float64
    assert anchors.kinds.tolist() == [1, 0, 0]
    assert anchors.triangles.tolist() == [3, -1, -1]
    assert anchors.barycentrics[0].tolist() == [1, 1, 1] and not anchors.barycentrics[1:].any()
    assert anchors.locations[2].tolist() == [6, 7, 8]  # a space anchor keeps its point
    assert an.kind_counts(anchors) == (1, 2)


def test_empty_list_take_concatenate_and_remove():
    empty = an.no_anchors()
    assert an.anchor_count(empty) == 0 and empty.locations.shape == (0, 3)
    one = an.make_anchors([2], [0], [-1], np.zeros((1, 3)), [[1, 2, 3]])
    two = an.make_anchors([7], [0], [-1], np.zeros((1, 3)), [[4, 5, 6]])
    both = an.concatenate(an.concatenate(empty, one), two)
    assert both.vertex_indices.tolist() == [2, 7]
    assert an.take(both, [1]).vertex_indices.tolist() == [7]
    assert an.remove(both, 0).vertex_indices.tolist() == [7]
    with pytest.raises(ls.LayoutError, match="no anchor 2"):
        an.remove(both, 2)
    with pytest.raises(ls.LayoutError, match="no anchor -1"):
        an.remove(both, -1)


def test_anchored_and_valid_masks_ignore_indices_out_of_range():
    anchors = an.make_anchors([1, 3, 9], [0, 0, 0], [-1] * 3, np.zeros((3, 3)), np.zeros((3, 3)))
    assert an.anchored_mask(anchors, 5).tolist() == [False, True, False, True, False]
    assert an.valid_vertex_mask(anchors, 5).tolist() == [True, True, False]


def test_clamp_active_index():
    assert an.clamp_active_index(5, 3) == 2
    assert an.clamp_active_index(-4, 3) == 0
    assert an.clamp_active_index(1, 3) == 1
    assert an.clamp_active_index(0, 0) == -1


# ---------------------------------------------------------------- validation


def test_check_vertex_index():
    assert an.check_vertex_index(np.int64(4), 5) == 4
    for bad in (5, -1, -7, 1000):
        with pytest.raises(ls.LayoutError, match=f"Vertex index {bad} is out of range: the layout has 5 vertices"):
            an.check_vertex_index(bad, 5)


def test_check_location():
    assert an.check_location((1, 2, 3)).tolist() == [1.0, 2.0, 3.0]
    for bad in ((np.nan, 0, 0), (0, np.inf, 0), (0, 0)):
        with pytest.raises(ls.LayoutError, match="NaN or infinite"):
            an.check_location(bad, "The 3D cursor")


def test_check_anchor_locations_names_the_first_bad_anchor_in_the_mask():
    locations = np.zeros((3, 3))
    locations[1, 0] = np.nan
    locations[2, 2] = np.inf
    anchors = an.make_anchors([10, 11, 12], [1, 1, 1], [0, 0, 0], np.ones((3, 3)) / 3, locations)
    with pytest.raises(ls.LayoutError, match=r"Anchor 1 \(vertex 11\) has a NaN .* \(2 such anchors\)"):
        an.check_anchor_locations(anchors)
    with pytest.raises(ls.LayoutError, match=r"Anchor 2 \(vertex 12\)"):
        an.check_anchor_locations(anchors, np.array([True, False, True]))
    an.check_anchor_locations(anchors, np.array([True, False, False]))


def test_pick_vertex_prefers_the_active_selected_vertex():
    selection = np.array([False, True, False, True])
    assert an.pick_vertex(selection, 3) == 3
    assert an.pick_vertex(selection, 1) == 1
    assert an.pick_vertex(np.array([False, False, True]), -1) == 2  # the only selected one
    assert an.pick_vertex(np.array([False, False, True]), 0) == 2  # an unselected active vertex does not count
    with pytest.raises(ls.LayoutError, match="No selected vertex"):
        an.pick_vertex(np.zeros(4, dtype=bool), -1)
    with pytest.raises(ls.LayoutError, match="2 vertices are selected and none is active"):
        an.pick_vertex(selection, -1)


# ---------------------------------------------------------------- spacing


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_spaced_indices_match_the_greedy_reference(seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-1.0, 1.0, size=(400, 3)) * [2.0, 1.0, 0.3]
    spacing = 0.35
    chosen = an.spaced_indices(points, spacing)
    assert np.array_equal(chosen, greedy_reference(points, spacing))
    assert np.array_equal(an.spaced_indices(points, spacing), chosen)  # deterministic
    assert pairwise_min_distance(points[chosen]) >= spacing
    # Maximal: every point is within the spacing of a chosen one.
    nearest = np.sqrt(((points[:, None, :] - points[None, chosen, :]) ** 2).sum(axis=2)).min(axis=1)
    assert nearest.max() < spacing


def test_spaced_indices_respect_candidates_and_seeds():
    rng = np.random.default_rng(7)
    points = rng.uniform(-1.0, 1.0, size=(300, 3))
    candidates = rng.uniform(size=300) < 0.7
    seeds = points[~candidates][:5]
    spacing = 0.4
    chosen = an.spaced_indices(points, spacing, candidates, seeds)
    assert np.array_equal(chosen, greedy_reference(points, spacing, candidates, seeds))
    assert np.all(candidates[chosen])
    distances_to_seeds = np.sqrt(((points[chosen][:, None, :] - seeds[None, :, :]) ** 2).sum(axis=2))
    assert distances_to_seeds.min() >= spacing


def test_spaced_indices_on_a_regular_grid_take_every_other_point():
    points = layout_grid(count=9, size=8.0)  # unit steps
    chosen = an.spaced_indices(points, 2.0)
    assert len(chosen) == 25
    assert pairwise_min_distance(points[chosen]) == pytest.approx(2.0)


def test_spaced_indices_edge_cases():
    points = np.zeros((5, 3))
    assert an.spaced_indices(points, 1.0).tolist() == [0]  # coincident points: one anchor
    assert an.spaced_indices(points, 1.0, np.zeros(5, dtype=bool)).size == 0
    assert an.spaced_indices(np.eye(3), 1e-9).tolist() == [0, 1, 2]
    assert an.spaced_indices(np.eye(3) * 1e6, 1e3).tolist() == [0, 1, 2]
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ls.LayoutError, match="positive distance"):
            an.spaced_indices(points, bad)
    with pytest.raises(ls.LayoutError, match="too small"):
        an.spaced_indices(np.eye(3) * 1e6, 1e-9)
    nan_points = np.eye(3)
    nan_points[1, 1] = np.nan
    with pytest.raises(ls.LayoutError, match="NaN"):
        an.spaced_indices(nan_points, 0.5)
    assert an.spaced_indices(nan_points, 0.5, np.array([True, False, True])).tolist() == [0, 2]


def test_spaced_indices_scale_to_many_points():
    rng = np.random.default_rng(3)
    points = rng.uniform(0.0, 1.0, size=(60_000, 3)) * [10.0, 10.0, 0.1]
    chosen = an.spaced_indices(points, 0.5)
    assert 200 < len(chosen) < 800
    assert pairwise_min_distance(points[chosen]) >= 0.5


def test_default_spacing_is_a_tenth_of_the_diagonal():
    points = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [np.nan, 0.0, 0.0]])
    assert an.default_spacing(points) == pytest.approx(0.5)
    assert an.default_spacing(np.zeros((3, 3))) == 1.0
    assert an.default_spacing(np.zeros((0, 3))) == 1.0


# ---------------------------------------------------------------- targets: resolve, refresh, add, auto


def test_refresh_locations_follows_the_target():
    target = grid_target()
    anchors = an.make_anchors([0, 1], [1, 0], [5, -1], [[0.2, 0.3, 0.5], [0, 0, 0]], [[9, 9, 9], [1, 2, 3]])
    refreshed = an.refresh_locations(anchors, target)
    expected = target.mesh.face_point_positions(
        np.array([5], dtype=np.uint32), np.array([[0.2, 0.3, 0.5]], dtype=np.float32)
    )
    np.testing.assert_allclose(refreshed.locations[0], expected[0], atol=1e-6)
    assert refreshed.locations[1].tolist() == [1, 2, 3]  # a space anchor is its own point
    assert anchors.locations[0].tolist() == [9, 9, 9]  # input untouched


def test_resolve_after_deleting_triangles():
    target = grid_target(cells=4)
    old_triangles = target.mesh.triangles()
    vertices = target.mesh.vertices()
    # Two face anchors: one on triangle 3, one on triangle 20.
    anchors = an.make_anchors([0, 1], [1, 1], [3, 20], [[0.2, 0.3, 0.5]] * 2, np.zeros((2, 3)))
    anchors = an.refresh_locations(anchors, target)
    # Delete triangles 0..9: triangle 3 is gone, triangle 20 becomes triangle 10.
    changed = make_target(vertices, old_triangles[10:])
    resolved, resolution = an.resolve(anchors, changed, target.signature)
    assert (resolution.detached_count, resolution.reattached_count) == (1, 1)
    assert resolved.kinds.tolist() == [an.SPACE_ANCHOR, an.FACE_ANCHOR]
    assert resolved.triangles.tolist() == [-1, 10]
    np.testing.assert_allclose(resolved.locations, anchors.locations, atol=1e-6)  # the space anchor stays put
    rebuilt = changed.mesh.face_point_positions(np.array([10], dtype=np.uint32), resolved.barycentrics[1:])
    np.testing.assert_allclose(rebuilt[0], anchors.locations[1], atol=1e-6)


def test_resolve_leaves_anchors_alone_when_the_topology_is_unchanged():
    target = grid_target(cells=4)
    anchors = an.make_anchors([0], [1], [3], [[0.2, 0.3, 0.5]], [[np.nan, 0, 0]])
    resolved, resolution = an.resolve(anchors, target, target.signature)
    assert (resolution.detached_count, resolution.reattached_count) == (0, 0)
    assert resolved.triangles.tolist() == [3]
    assert np.all(np.isfinite(resolved.locations))  # refreshed from the triangle


def test_resolve_refuses_a_nan_location_it_needs():
    target = grid_target(cells=4)
    anchors = an.make_anchors([0], [1], [3], [[0.2, 0.3, 0.5]], [[np.nan, 0, 0]])
    with pytest.raises(ls.LayoutError, match="Anchor 0"):
        an.resolve(anchors, target, "another signature")


def test_add_anchors_to_the_closest_point_and_replaces_the_vertex_anchor():
    target = grid_target()
    outcome = an.add(10, an.no_anchors(), target, "", 4, (0.3, 0.7, 2.0))
    assert outcome.anchors.vertex_indices.tolist() == [4]
    assert outcome.anchors.kinds.tolist() == [an.FACE_ANCHOR]
    np.testing.assert_allclose(outcome.anchors.locations[0], [0.3, 0.7, 0.0], atol=1e-6)
    assert (outcome.added_count, outcome.replaced_count, outcome.active_index) == (1, 0, 0)

    outcome = an.add(10, outcome.anchors, target, target.signature, 7, (5.0, 0.0, 1.0))  # beyond the edge
    np.testing.assert_allclose(outcome.anchors.locations[1], [2.0, 0.0, 0.0], atol=1e-6)
    outcome = an.add(10, outcome.anchors, target, target.signature, 4, (-1.0, -1.0, 0.5), on_surface=False)
    assert outcome.anchors.vertex_indices.tolist() == [7, 4]
    assert outcome.replaced_count == 1 and outcome.active_index == 1
    assert outcome.anchors.kinds.tolist() == [an.FACE_ANCHOR, an.SPACE_ANCHOR]
    assert outcome.anchors.locations[1].tolist() == [-1.0, -1.0, 0.5]


def test_add_refuses_bad_input():
    target = grid_target()
    with pytest.raises(ls.LayoutError, match="out of range"):
        an.add(10, an.no_anchors(), target, "", 10, (0, 0, 0))
    with pytest.raises(ls.LayoutError, match="NaN"):
        an.add(10, an.no_anchors(), target, "", 1, (0, np.nan, 0))


def test_auto_closest_spacing_coverage_and_targets():
    target = grid_target(size=4.0, cells=8)
    matrix = np.diag([2.0, 1.0, 1.0, 1.0])  # a non-uniform world transform
    matrix[:3, 3] = (0.1, 0.2, 0.5)
    layout = layout_arrays(layout_grid(count=21, size=1.8, height=0.5), matrix)
    world = tf.world_positions(layout)
    outcome = an.auto(layout, None, an.no_anchors(), target, "", 0.5, "CLOSEST", True)
    chosen = outcome.anchors.vertex_indices
    assert outcome.spacing == 0.5 and outcome.added_count == len(chosen) > 10
    assert outcome.missed_count == 0 and outcome.skipped_count == 0
    assert pairwise_min_distance(world[chosen]) >= 0.5
    coverage = np.sqrt(((world[:, None, :] - world[None, chosen, :]) ** 2).sum(axis=2)).min(axis=1)
    assert coverage.max() < 0.5
    expected = world[chosen].copy()
    expected[:, 2] = 0.0  # the closest point of the plane below (the layout lies within the target)
    np.testing.assert_allclose(outcome.anchors.locations, expected, atol=1e-5)
    assert np.all(outcome.anchors.kinds == an.FACE_ANCHOR)


def test_auto_default_spacing_and_keeping_existing_anchors():
    target = grid_target()
    layout = layout_arrays(layout_grid(count=11, size=2.0))
    world = tf.world_positions(layout)
    existing = an.add(len(world), an.no_anchors(), target, "", 60, world[60]).anchors
    outcome = an.auto(layout, None, existing, target, target.signature, 0.0, "CLOSEST", False)
    assert outcome.spacing == pytest.approx(0.1 * np.sqrt(8.0))
    assert outcome.anchors.vertex_indices[0] == 60
    assert np.count_nonzero(outcome.anchors.vertex_indices == 60) == 1
    assert pairwise_min_distance(world[outcome.anchors.vertex_indices]) >= outcome.spacing
    replaced = an.auto(layout, None, existing, target, target.signature, 0.0, "CLOSEST", True)
    assert replaced.replaced_count == 1 and 0 in replaced.anchors.vertex_indices


def test_auto_project_skips_vertices_without_normals_and_counts_misses():
    target = grid_target(size=2.2, cells=4)
    layout = layout_arrays(layout_grid(count=7, size=3.0, height=1.0))  # wider than the target
    world = tf.world_positions(layout)
    normals = np.tile([0.0, 0.0, 1.0], (len(world), 1))  # pointing away: both directions must hit
    normals[0] = 0.0  # a vertex on no face
    outcome = an.auto(layout, normals, an.no_anchors(), target, "", 0.4, "PROJECT", True)
    chosen = an.spaced_indices(world, 0.4)
    inside = np.all(np.abs(world[chosen, :2]) <= 1.0 + 1e-6, axis=1)
    assert outcome.skipped_count == 1
    assert outcome.added_count == np.count_nonzero(inside[1:])
    assert outcome.missed_count == np.count_nonzero(~inside[1:])
    assert outcome.missed_count > 0
    expected = world[outcome.anchors.vertex_indices].copy()
    expected[:, 2] = 0.0  # straight down
    np.testing.assert_allclose(outcome.anchors.locations, expected, atol=1e-5)


def test_auto_max_distance():
    target = grid_target()
    points = layout_grid(count=5, size=2.0, height=1.0)
    points[::2, 2] = 3.0  # every other vertex high above the plane
    layout = layout_arrays(points)
    outcome = an.auto(layout, None, an.no_anchors(), target, "", 0.1, "CLOSEST", True, max_distance=2.0)
    assert np.all(points[outcome.anchors.vertex_indices, 2] == 1.0)
    assert outcome.missed_count == np.count_nonzero(points[:, 2] == 3.0)


def test_auto_refuses_bad_input():
    target = grid_target()
    points = layout_grid(count=5)
    points[3, 1] = np.nan
    with pytest.raises(ls.LayoutError, match="Layout vertex 3 has a NaN"):
        an.auto(layout_arrays(points), None, an.no_anchors(), target, "", 0.5, "CLOSEST", True)
    with pytest.raises(ls.LayoutError, match="would create"):
        an.auto(layout_arrays(layout_grid(count=120)), None, an.no_anchors(), target, "", 1e-4, "CLOSEST", True)
    with pytest.raises(ValueError, match="unknown anchor method"):
        an.auto(layout_arrays(layout_grid(count=5)), None, an.no_anchors(), target, "", 0.5, "NEAREST", True)


def test_update_resolves_and_refreshes():
    target = grid_target()
    anchors = an.make_anchors([0], [1], [5], [[0.2, 0.3, 0.5]], [[0, 0, 0]])
    outcome = an.update(anchors, target, target.signature)
    assert outcome.added_count == 0 and outcome.topology_detached_count == 0
    assert outcome.anchors.locations[0].tolist() != [0, 0, 0]


def test_segments_leave_out_missing_vertices():
    anchors = an.make_anchors([0, 1, 2], [0, 0, 0], [-1] * 3, np.zeros((3, 3)), [[1, 1, 1], [2, 2, 2], [3, 3, 3]])
    starts, ends = an.segments(anchors, [[0, 0, 0], [np.nan] * 3, [5, 5, 5]])
    assert starts.dtype == np.float32 and ends.dtype == np.float32
    assert starts.tolist() == [[0, 0, 0], [5, 5, 5]]
    assert ends.tolist() == [[1, 1, 1], [3, 3, 3]]
