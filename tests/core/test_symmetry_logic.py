"""Plain tests of symmetric anchors without Blender: vertex twins (``core/symmetry.py``) and anchor pairs
(``core/anchor_twins.py``, ``core/anchors.py``), on generated grids and kernel targets.

Twins by topology are checked on grids whose vertex and face order are shuffled and whose positions are
pushed off symmetry (so only the topology can find them); twins by position on grids whose topology is not
symmetric; the references are the grid's own (row, column) -> (row, mirrored column) map.
"""

import sys

import numpy as np
import pytest

from helpers import core_module, grid_triangles

sy = core_module("symmetry")
at = core_module("anchor_twins")
an = sys.modules[sy.__name__.rpartition(".")[0] + ".anchors"]
mi = sys.modules[sy.__name__.rpartition(".")[0] + ".mirroring"]
ls = sys.modules[sy.__name__.rpartition(".")[0] + ".layout_state"]
tg = sys.modules[sy.__name__.rpartition(".")[0] + ".target"]

X_PLANE = mi.Plane(np.zeros(3), np.array([1.0, 0.0, 0.0]))


# ---------------------------------------------------------------- generated geometry


class Grid:
    """A ``columns`` x ``rows`` quad grid in z = 0, symmetric across x = 0, optionally shuffled.

    ``twins`` is the reference: each vertex's mirror (same row, mirrored column), in the shuffled numbering.
    """

    def __init__(self, columns, rows=5, shuffle_seed=None, width=2.0):
        xs = np.linspace(-width / 2, width / 2, columns)
        positions = np.array([(x, 0.5 * row, 0.0) for row in range(rows) for x in xs])
        faces = np.array(
            [
                [
                    row * columns + column,
                    row * columns + column + 1,
                    (row + 1) * columns + column + 1,
                    (row + 1) * columns + column,
                ]
                for row in range(rows - 1)
                for column in range(columns - 1)
            ]
        )
        mirror = np.array(
            [(vertex // columns) * columns + columns - 1 - vertex % columns for vertex in range(len(positions))]
        )
        new_of_old = np.arange(len(positions))
        if shuffle_seed is not None:
            generator = np.random.default_rng(shuffle_seed)
            old_of_new = generator.permutation(len(positions))
            new_of_old = np.argsort(old_of_new)
            positions = positions[old_of_new]
            faces = new_of_old[faces][generator.permutation(len(faces))]
            faces = np.array([np.roll(face, int(generator.integers(4))) for face in faces])
            mirror = new_of_old[mirror[old_of_new]]
        self.positions, self.faces, self.twins = positions, faces, mirror
        self.columns, self.rows, self.new_of_old = columns, rows, new_of_old

    @property
    def edges(self):
        pairs = np.concatenate([np.stack([self.faces[:, k], self.faces[:, (k + 1) % 4]], axis=1) for k in range(4)])
        return np.unique(np.sort(pairs, axis=1), axis=0)

    def find(self, positions=None, faces=None, plane=X_PLANE, **options):
        faces = self.faces if faces is None else faces
        return sy.vertex_twins(
            self.positions if positions is None else positions,
            np.concatenate([np.asarray(face) for face in faces]) if len(faces) else np.zeros(0),
            np.array([len(face) for face in faces]),
            self.edges,
            plane,
            **options,
        )


def make_target(vertices, triangles):
    return tg.make_target("Target", np.asarray(vertices, dtype=np.float64), np.asarray(triangles, dtype=np.uint32))


def symmetric_target(cells=12, size=4.0, height=-1.0, x_range=(-1.0, 1.0)):
    """A bumpy sheet under the grids, symmetric across x = 0 (z depends on |x|), over ``x_range`` of its width."""
    xs = np.linspace(size / 2 * x_range[0], size / 2 * x_range[1], cells + 1)
    ys = np.linspace(-1.0, 3.0, cells + 1)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    z = height + 0.2 * np.cos(1.3 * x) + 0.1 * y
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return make_target(vertices, grid_triangles(cells))


def layout_of(grid):
    positions = np.asarray(grid.positions, dtype=np.float32)
    return ls.LayoutArrays(positions, np.eye(4), np.zeros(len(positions), dtype=bool), ls.space_state(len(positions)))


# ---------------------------------------------------------------- twins by topology


@pytest.mark.parametrize(
    "columns", [7, 8], ids=["plane through a column (edge seeds)", "plane through faces (crossing seeds)"]
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_topology_finds_every_twin_of_a_shuffled_grid(columns, seed):
    grid = Grid(columns, shuffle_seed=seed)
    twins = grid.find()
    np.testing.assert_array_equal(twins.twins, grid.twins)
    assert np.all(twins.how == sy.BY_TOPOLOGY)


def test_topology_ignores_how_far_the_vertices_moved_off_symmetry():
    """One side pushed by 0.4 of an edge and the whole grid bent: no twin is near the reflection, the map holds."""
    grid = Grid(9, shuffle_seed=3)
    positions = grid.positions.copy()
    positions[positions[:, 0] > 0.01, 1] += 0.1  # a quarter of the column spacing, along the plane
    positions[:, 2] += 0.3 * positions[:, 0] ** 2 + 0.2 * positions[:, 0]
    assert not np.array_equal(grid.find(positions, use_topology=False).twins, grid.twins)
    twins = grid.find(positions)
    np.testing.assert_array_equal(twins.twins, grid.twins)
    assert np.all(twins.how == sy.BY_TOPOLOGY)


def test_a_plane_not_through_the_layout_finds_no_topological_twins():
    grid = Grid(7, shuffle_seed=0)
    twins = grid.find(plane=mi.Plane(np.array([5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])))
    assert np.all(twins.twins == -1) and np.all(twins.how == sy.NO_TWIN)


def test_the_map_is_an_involution_and_on_plane_vertices_are_their_own_twins():
    grid = Grid(7, shuffle_seed=4)
    twins = grid.find()
    np.testing.assert_array_equal(twins.twins[twins.twins], np.arange(len(grid.positions)))
    itself = twins.twins == np.arange(len(grid.positions))
    np.testing.assert_array_equal(itself, np.isclose(grid.positions[:, 0], 0.0))
    np.testing.assert_array_equal(itself, twins.on_plane)


# ---------------------------------------------------------------- twins by position, and none


def test_asymmetric_topology_falls_back_to_position():
    """A face split in two on one side only: no topological symmetry; the twins by position are right."""
    grid = Grid(7)
    positions = np.vstack([grid.positions, [[0.8, 0.25, 0.0]]])  # inside the face at columns 5..6, row 0..1
    faces = [list(face) for face in grid.faces.tolist()]
    corner = grid.faces[5].tolist()  # row 0, columns 5..6 (x from 0.667 to 1)
    faces[5] = [corner[0], corner[1], corner[2], len(positions) - 1]
    faces.append([corner[0], len(positions) - 1, corner[2], corner[3]])
    twins = sy.vertex_twins(
        positions,
        np.concatenate([np.asarray(face) for face in faces]),
        np.array([len(face) for face in faces]),
        grid.edges,
        X_PLANE,
    )
    np.testing.assert_array_equal(twins.twins[: len(grid.positions)], grid.twins)
    assert np.all(twins.how[: len(grid.positions)] == sy.BY_POSITION)
    assert twins.twins[-1] == -1 and twins.how[-1] == sy.NO_TWIN  # the extra vertex has nothing across


def test_loose_vertices_find_twins_by_position_within_the_tolerance():
    grid = Grid(7)
    positions = grid.positions.copy()
    spacing = 1.0 / 3.0
    positions[grid.twins[8]] += [0.2 * spacing, 0.0, 0.0]  # within 0.25 of the edge length: still the twin
    positions[grid.twins[15]] += [0.0, 0.0, 0.4 * spacing]  # beyond it: no twin
    twins = grid.find(positions, faces=[])
    assert twins.twins[8] == grid.twins[8] and twins.how[8] == sy.BY_POSITION
    assert twins.twins[15] == -1 and twins.how[15] == sy.NO_TWIN
    assert twins.twins[10] == 10 and twins.on_plane[10]  # on the plane: its own twin


def test_nearest_within_matches_brute_force():
    generator = np.random.default_rng(7)
    points = generator.uniform(-1, 1, (400, 3))
    queries = generator.uniform(-1, 1, (300, 3))
    radii = generator.uniform(0.0, 0.3, 300)
    found = sy.nearest_within(points, queries, radii)
    distances = np.linalg.norm(points[None, :, :] - queries[:, None, :], axis=2)
    expected = np.where(distances.min(axis=1) <= radii, distances.argmin(axis=1), -1)
    np.testing.assert_array_equal(found, expected)
    assert (found >= 0).sum() > 50 and (found < 0).sum() > 50


def test_non_finite_positions_are_refused():
    grid = Grid(7)
    positions = grid.positions.copy()
    positions[3, 1] = np.nan
    with pytest.raises(sy.LayoutError, match="NaN or infinite"):
        grid.find(positions)


# ---------------------------------------------------------------- anchor pairs


def test_add_anchors_the_twin_at_the_closest_point_to_the_reflection():
    grid = Grid(7, shuffle_seed=5)
    target = symmetric_target()
    twins = grid.find()
    vertex = int(grid.new_of_old[2 * 7 + 1])  # row 2, column 1
    outcome, report = at.add(
        twins, X_PLANE, len(grid.positions), an.no_anchors(), target, "", vertex, [-0.6, 1.0, -0.5], True
    )
    anchors = outcome.anchors
    assert an.anchor_count(anchors) == 2 and report.paired_count == 1 and report.how == "by topology"
    own, twin = (
        np.flatnonzero(anchors.vertex_indices == vertex)[0],
        np.flatnonzero(anchors.vertex_indices != vertex)[0],
    )
    assert outcome.active_index == own
    assert anchors.vertex_indices[twin] == grid.twins[vertex]
    assert anchors.twins[own] == grid.twins[vertex] and anchors.twins[twin] == vertex
    np.testing.assert_allclose(anchors.locations[twin], anchors.locations[own] * [-1.0, 1.0, 1.0], atol=1e-5)
    np.testing.assert_array_equal(an.partner_indices(anchors), [twin, own][:: 1 if own == 0 else -1])


def test_an_anchor_on_the_plane_is_its_own_twin():
    grid = Grid(7, shuffle_seed=6)
    vertex = int(grid.new_of_old[3 * 7 + 3])  # the middle column
    outcome, report = at.add(
        grid.find(),
        X_PLANE,
        len(grid.positions),
        an.no_anchors(),
        symmetric_target(),
        "",
        vertex,
        [0.0, 1.5, -0.5],
        True,
    )
    assert an.anchor_count(outcome.anchors) == 1 and report.on_plane_count == 1 and report.twin_vertex == -1
    assert outcome.anchors.twins[0] == vertex and an.partner_indices(outcome.anchors)[0] == 0


def test_no_twin_vertex_or_no_target_near_the_reflection_leaves_one_anchor():
    grid = Grid(7)
    half_target = symmetric_target(x_range=(0.05, 1.0))  # nothing at x < 0.1
    twins = grid.find()
    outcome, report = at.add(
        twins, X_PLANE, len(grid.positions), an.no_anchors(), half_target, "", 12, [0.7, 1.0, -0.5], True
    )
    assert an.anchor_count(outcome.anchors) == 1 and report.no_target_count == 1 and report.paired_count == 0
    assert outcome.anchors.twins[0] == -1
    lone = twins._replace(twins=np.full_like(twins.twins, -1), how=np.zeros_like(twins.how))
    outcome, report = at.add(
        lone, X_PLANE, len(grid.positions), an.no_anchors(), symmetric_target(), "", 12, [0.7, 1.0, -0.5], True
    )
    assert an.anchor_count(outcome.anchors) == 1 and report.no_vertex_count == 1 and report.how == "no twin"


def test_a_space_anchors_twin_is_the_reflected_point():
    grid = Grid(7)
    outcome, _report = at.add(
        grid.find(), X_PLANE, len(grid.positions), an.no_anchors(), symmetric_target(), "", 9, [0.4, 0.7, 2.0], False
    )
    anchors = outcome.anchors
    assert list(anchors.kinds) == [an.SPACE_ANCHOR] * 2
    np.testing.assert_allclose(anchors.locations[1], [-0.4, 0.7, 2.0])


def test_removing_one_of_a_pair_removes_both_or_unpairs_the_other():
    grid = Grid(7)
    outcome, _report = at.add(
        grid.find(), X_PLANE, len(grid.positions), an.no_anchors(), symmetric_target(), "", 8, [0.0, 0.5, -1.0], True
    )
    other = an.make_anchors([30], [an.SPACE_ANCHOR], [-1], np.zeros((1, 3)), [[0, 0, 1]])
    anchors = an.concatenate(outcome.anchors, other)
    assert an.anchor_count(an.remove(anchors, 0, with_twin=True)) == 1
    alone = an.remove(anchors, 0, with_twin=False)
    assert an.anchor_count(alone) == 2 and np.all(alone.twins == -1)
    # Replacing one half by a plain anchor unpairs the other.
    replaced = an.add(len(grid.positions), outcome.anchors, symmetric_target(), "", 8, [0.0, 0.5, -1.0]).anchors
    assert np.all(replaced.twins == -1)


def test_update_keeps_pairs():
    grid = Grid(7)
    target = symmetric_target()
    outcome, _report = at.add(
        grid.find(), X_PLANE, len(grid.positions), an.no_anchors(), target, "", 8, [0.0, 0.5, -1.0], True
    )
    updated = an.update(outcome.anchors, target, target.signature).anchors
    np.testing.assert_array_equal(updated.twins, outcome.anchors.twins)


@pytest.mark.parametrize("columns", [7, 8])
def test_auto_is_exactly_symmetric_in_the_layout(columns):
    grid = Grid(columns, rows=9, shuffle_seed=8)
    target = symmetric_target()
    twins = grid.find()
    outcome, report, side = at.auto(
        twins, X_PLANE, layout_of(grid), None, an.no_anchors(), target, "", 0.45, "CLOSEST", True, 0.0
    )
    anchors = outcome.anchors
    vertices = anchors.vertex_indices.astype(np.int64)
    assert side == 1 and report.no_vertex_count == 0 and report.no_target_count == 0
    assert np.array_equal(np.sort(vertices), np.sort(grid.twins[vertices]))  # the anchored set is its own mirror
    partners = an.partner_indices(anchors)
    assert np.all(partners >= 0)
    np.testing.assert_array_equal(vertices[partners], grid.twins[vertices])
    np.testing.assert_allclose(anchors.locations[partners], anchors.locations * [-1.0, 1.0, 1.0], atol=1e-5)
    placed = grid.positions[vertices]
    assert np.all((placed[:, 0] > -1e-9) | (partners != np.arange(len(vertices))))
    first_half = vertices[: report.paired_count + report.on_plane_count]
    assert np.all(grid.positions[first_half, 0] >= -1e-9)  # spread on the + side, mirrored to the - side
    gaps = np.linalg.norm(placed[:, None] - placed[None], axis=2) + np.eye(len(placed)) * 9
    assert gaps.min() >= 0.45 - 1e-9


def test_auto_spreads_on_the_side_with_more_kept_anchors():
    grid = Grid(7, rows=9)
    target = symmetric_target()
    left = [int(v) for v in np.flatnonzero(grid.positions[:, 0] < -0.5)[:3]]
    kept = an.make_anchors(left, [an.SPACE_ANCHOR] * 3, [-1] * 3, np.zeros((3, 3)), grid.positions[left])
    outcome, _report, side = at.auto(
        grid.find(), X_PLANE, layout_of(grid), None, kept, target, "", 0.6, "CLOSEST", False, 0.0
    )
    assert side == -1
    new = outcome.anchors.vertex_indices[3:].astype(np.int64)
    assert set(new.tolist()) == set(grid.twins[new].tolist())


def test_auto_anchors_vertices_without_twins_alone():
    grid = Grid(7, rows=9)
    twins = grid.find()
    right = np.flatnonzero(grid.positions[:, 0] > 0.5)
    lone = twins._replace(
        twins=np.where(
            np.isin(np.arange(len(twins.twins)), np.concatenate([right, grid.twins[right]])), -1, twins.twins
        )
    )
    outcome, report, _side = at.auto(
        lone, X_PLANE, layout_of(grid), None, an.no_anchors(), symmetric_target(), "", 0.45, "CLOSEST", True, 0.0
    )
    assert report.no_vertex_count > 0
    partners = an.partner_indices(outcome.anchors)
    assert np.count_nonzero(partners < 0) == report.no_vertex_count
    unpaired = outcome.anchors.vertex_indices[partners < 0]
    assert np.all(lone.twins[unpaired] == -1)


@pytest.mark.parametrize("shift, found", [(0.2, True), (0.6, False)])
def test_a_midline_off_the_plane_seeds_the_match_within_a_quarter_edge(shift, found):
    """A wrapped layout's midline is only near the plane: within a quarter of an edge it still seeds the match."""
    grid = Grid(7, shuffle_seed=9)
    positions = grid.positions + [shift / 3.0, 0.0, 0.0]  # columns 1/3 apart, rows 1/2: the edges around 0.4
    twins = grid.find(positions, use_topology=True)
    assert np.array_equal(twins.twins, grid.twins) == found
    assert np.all(twins.how == sy.BY_TOPOLOGY) == found
