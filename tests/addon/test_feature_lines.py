"""Pair Feature Lines under Blender (PyPI ``bpy``): a cube layout's creases and marked edges paired with a rounded
box's ridges as curve constraints, what stays free, and bad inputs that change nothing.

The target is the rounded box of ``test_features`` (half-size 1, edges rounded by 0.25): its twelve blend
centre-lines are ridges. The layout is a cube of the same size, each face a 6 x 6 quad grid: its twelve edges
are 90-degree convex creases, each about 0.1 from the ridge it should follow.
"""

import bpy

import bmesh
import numpy as np
import pytest

from bpy_helpers import distance_to_polyline, world_positions
from helpers import rounded_box


def cube_layout(target, name="Cube"):
    """A quad cube of half-size 1 (6 x 6 quads a face), whose target is ``target``, active and selected."""
    mesh = bpy.data.meshes.new(name)
    editable = bmesh.new()
    bmesh.ops.create_cube(editable, size=2.0)
    bmesh.ops.subdivide_edges(editable, edges=editable.edges[:], cuts=5, use_grid_fill=True)
    editable.to_mesh(mesh)
    editable.free()
    return active_layout(mesh, target)


def active_layout(mesh, target):
    """An object of ``mesh`` in the scene, whose target is ``target``, the only one selected and active."""
    layout = bpy.data.objects.new(mesh.name, mesh)
    bpy.context.scene.collection.objects.link(layout)
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    return layout


def box_target():
    vertices, triangles = rounded_box(1.0, 0.25, 24)
    mesh = bpy.data.meshes.new("Box")
    mesh.from_pydata(vertices.tolist(), [], triangles.tolist())
    mesh.update()
    obj = bpy.data.objects.new("Box", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


@pytest.fixture
def cube():
    return cube_layout(box_target())


def feature_items(layout):
    return [item for item in layout.springwrap.curve_constraints if item.source_kind == "FEATURE_LINE"]


def mark_sharp(layout, pairs):
    """Mark the edges joining the given vertex pairs sharp (and only those)."""
    wanted = {tuple(sorted(pair)) for pair in pairs}
    mesh = layout.data
    flags = [tuple(sorted(edge.vertices)) in wanted for edge in mesh.edges]
    if bpy.app.version >= (4, 0, 0):
        attribute = mesh.attributes.get("sharp_edge") or mesh.attributes.new("sharp_edge", "BOOLEAN", "EDGE")
        attribute.data.foreach_set("value", flags)
    else:  # Blender 3.x keeps sharpness as an edge flag
        mesh.edges.foreach_set("use_edge_sharp", flags)
    mesh.update()
    assert sum(flags) == len(wanted)


def ring_at_height(layout, height=0.0):
    """The vertex pairs of the edges of the layout's horizontal loop at ``height`` (round the four sides)."""
    positions = world_positions(layout)
    pairs = []
    for edge in layout.data.edges:
        a, b = edge.vertices
        if abs(positions[a][2] - height) < 1e-4 and abs(positions[b][2] - height) < 1e-4:
            pairs.append((a, b))
    return pairs


def test_the_cubes_creases_pair_with_the_boxs_ridges(cube, capfd):
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    output = capfd.readouterr().out
    items = feature_items(cube)
    assert len(items) == 12, output
    assert "Paired 12 of 12 feature lines" in output
    positions = world_positions(cube)
    for item in items:
        assert 0.3 <= item.confidence <= 1.0
        chain = [int(vertex) for vertex in item.layout_vertices.split()]
        assert len(chain) == 5  # an edge of the cube (6 quads) but its two corners, which three creases share
        points = np.array([tuple(point.co) for point in item.points])
        # The target stretch runs beside the crease (the ridge of the blend, about 0.1 in), end to end.
        distances = distance_to_polyline(positions[chain], points)
        assert distances.max() < 0.25
        assert np.linalg.norm(points[0] - positions[chain[0]]) < np.linalg.norm(points[-1] - positions[chain[0]])
    # Drawn in the viewport apart from the hand-made curve constraints (violet, like proposed point pairs): a
    # dashed line from each chain vertex to its target, and each stretch of target feature as a solid line.
    from springwrap.ui.overlays import CURVE_DASH_COUNT, curve_segments, feature_stretches

    starts, _ends = curve_segments(cube, feature=True)
    assert starts.shape[0] == CURVE_DASH_COUNT * sum(len(item.layout_vertices.split()) for item in items)
    assert curve_segments(cube)[0].shape == (0, 3)  # no hand-made constraint among them
    starts, ends = feature_stretches(cube)
    assert starts.shape == ends.shape == (sum(len(item.points) - 1 for item in items), 3)
    first = np.array([tuple(point.co) for point in items[0].points])
    np.testing.assert_allclose(starts[0], first[0], atol=1e-5)
    np.testing.assert_allclose(ends[len(first) - 2], first[-1], atol=1e-5)
    # A second run replaces the pairs instead of adding more.
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    assert len(feature_items(cube)) == 12
    # Removable one by one like any curve constraint.
    assert bpy.ops.springwrap.curve_constraint_remove(index=0) == {"FINISHED"}
    assert len(feature_items(cube)) == 11


def test_the_wrap_puts_the_paired_creases_on_the_ridges(cube):
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    assert bpy.ops.springwrap.detach(only_selected=False) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=300) == {"FINISHED"}
    positions = world_positions(cube)
    for item in feature_items(cube):
        chain = [int(vertex) for vertex in item.layout_vertices.split()]
        points = np.array([tuple(point.co) for point in item.points])
        assert distance_to_polyline(positions[chain], points).mean() < 0.02


def test_each_setting_changes_the_pairs(cube):
    counts = {}
    for name, value in [
        ("default", None),
        ("crease_angle", 120.0),
        ("min_confidence", 0.999),
        ("max_distance", 0.01),
        ("max_angle", 0.0),
        ("feature_scale", 1.5),
    ]:
        arguments = {} if value is None else {name: value}
        assert bpy.ops.springwrap.feature_lines_pair(**arguments) == {"FINISHED"}
        counts[name] = len(feature_items(cube))
    assert counts["default"] == 12
    assert all(counts[name] < 12 for name in counts if name != "default"), counts


def test_a_marked_loop_across_a_face_stays_free_and_is_listed(cube, capfd):
    mark_sharp(cube, ring_at_height(cube, 0.0))
    before = len(cube.springwrap.curve_constraints)
    assert bpy.ops.springwrap.feature_lines_pair(crease_angle=0.0, use_borders=False) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "Paired 0 of 1 feature line" in output
    assert "marked line (any) loop at" in output and "1 free" in output
    assert len(cube.springwrap.curve_constraints) == before


def test_a_marked_line_that_crosses_itself_is_refused_and_nothing_changes(cube):
    # A figure eight on the front face (y = 1): two squares of quads touching at its centre, one line going
    # straight through the centre twice.
    positions = world_positions(cube)
    third = 1.0 / 3.0

    def at(x, z):
        return int(np.argmin(np.linalg.norm(positions - [x, 1.0, z], axis=1)))

    eight = [(0, 0), (third, 0), (third, third), (0, third), (0, 0), (-third, 0), (-third, -third), (0, -third), (0, 0)]
    vertices = [at(x, z) for x, z in eight]
    mark_sharp(cube, list(zip(vertices[:-1], vertices[1:])))
    before = [item.layout_vertices for item in cube.springwrap.curve_constraints]
    with pytest.raises(RuntimeError, match="crosses itself"):
        bpy.ops.springwrap.feature_lines_pair(crease_angle=0.0, use_borders=False)
    assert [item.layout_vertices for item in cube.springwrap.curve_constraints] == before


def test_an_empty_or_missing_group_and_a_missing_attribute_are_refused(cube):
    cube.vertex_groups.new(name="Empty")
    before = len(cube.springwrap.curve_constraints)
    with pytest.raises(RuntimeError, match="'Empty' holds no edge"):
        bpy.ops.springwrap.feature_lines_pair(vertex_group="Empty")
    with pytest.raises(RuntimeError, match="no vertex group 'Nothing'"):
        bpy.ops.springwrap.feature_lines_pair(vertex_group="Nothing")
    with pytest.raises(RuntimeError, match="no boolean edge attribute 'lips'"):
        bpy.ops.springwrap.feature_lines_pair(edge_attribute="lips")
    assert len(cube.springwrap.curve_constraints) == before


def test_a_vertex_group_marks_a_line(cube, capfd):
    group = cube.vertex_groups.new(name="Lips")
    members = sorted({vertex for pair in ring_at_height(cube, 0.0) for vertex in pair})
    group.add(members, 1.0, "REPLACE")
    assert bpy.ops.springwrap.feature_lines_pair(vertex_group="Lips", crease_angle=0.0, use_borders=False) == {
        "FINISHED"
    }
    assert "of 1 feature line" in capfd.readouterr().out


def mouth_layout(target):
    """A quad 'face' round a closed mouth, facing +z: rings of 24 vertices from an outer border inwards, the
    fourth a slit (lips that meet, 1.0 wide), the last two going back into a pocket behind it; active, selected."""
    shapes = [(1.0, 0.8, 0.0), (0.8, 0.5, 0.0), (0.6, 0.2, 0.0), (0.5, 0.002, 0.0), (0.45, 0.002, -0.1)]
    shapes.append((0.4, 0.002, -0.2))
    angle = np.arange(24) * 2.0 * np.pi / 24
    rings = [np.stack([a * np.cos(angle), b * np.sin(angle), np.full(24, z)], -1) for a, b, z in shapes]
    faces = [
        (r * 24 + i, r * 24 + (i + 1) % 24, (r + 1) * 24 + (i + 1) % 24, (r + 1) * 24 + i)
        for r in range(len(shapes) - 1)
        for i in range(24)
    ]
    mesh = bpy.data.meshes.new("Mouth")
    mesh.from_pydata(np.concatenate(rings).tolist(), [], faces)
    mesh.update()
    return active_layout(mesh, target)


def pit_target(n=100):
    """A height field over [-1.2, 1.2]^2, domed below z = 0, with a pit 1.2 x 0.6 and 1 deep: a mouth open
    on the target."""
    steps = np.linspace(-1.2, 1.2, n + 1)
    x, y = np.meshgrid(steps, steps, indexing="ij")
    z = np.where((np.abs(x) < 0.6) & (np.abs(y) < 0.3), -1.0, -0.3 * (x**2 + y**2))
    index = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4)
    mesh = bpy.data.meshes.new("Pit")
    mesh.from_pydata(np.stack([x, y, z], -1).reshape(-1, 3).tolist(), [], quads.tolist())
    mesh.update()
    obj = bpy.data.objects.new("Pit", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_closed_lips_are_paired_with_the_rim_of_an_open_mouth_and_openings_off_pairs_none(capfd):
    layout = mouth_layout(pit_target())
    assert bpy.ops.springwrap.feature_lines_pair(
        use_sharp=False, crease_angle=0.0, use_borders=False, feature_scale=0.3
    ) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "paired 1 opening (2 slit halves onto its rim" in output, output
    items = feature_items(layout)
    assert len(items) == 2
    positions = world_positions(layout)
    for item in items:
        chain = [int(vertex) for vertex in item.layout_vertices.split()]
        assert all(72 <= vertex < 96 for vertex in chain)  # the slit's ring
        points = np.array([tuple(point.co) for point in item.points])
        side = np.sign(positions[chain, 1].sum())
        inner = points[np.abs(points[:, 0]) < 0.35]
        assert np.allclose(inner[:, 1], side * 0.3, atol=0.03)
    assert bpy.ops.springwrap.feature_lines_pair(
        use_sharp=False, crease_angle=0.0, use_borders=False, use_openings=False, feature_scale=0.3
    ) == {"FINISHED"}
    assert not feature_items(layout)
