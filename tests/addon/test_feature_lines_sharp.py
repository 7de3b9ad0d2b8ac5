"""Pair Feature Lines onto a target's own sharp creases, and the accuracy of a traced crest.

A target that keeps its creases sharp (a CAD model re-exported with another tessellation) has exact features: its
edges whose faces meet at more than the crease angle. The cube layout's creases pair with them and their stretches
lie on the target's edges. A crest traced from curvatures on a rounded crease is known only to within its scale: a
crease already lying on it stays free.
"""

import bpy

import bmesh
import numpy as np
from test_feature_lines import box_target, cube_layout, feature_items, mark_sharp

from bpy_helpers import distance_to_polyline, world_positions

HALF = 1.1
"""Half-size of the sharp box target (the cube layout's is 1)."""


def sharp_box_target():
    """A box of half-size :data:`HALF`, each face a 7 x 7 grid (not the layout's 6 x 6), triangulated."""
    mesh = bpy.data.meshes.new("Sharp box")
    editable = bmesh.new()
    bmesh.ops.create_cube(editable, size=2.0 * HALF)
    bmesh.ops.subdivide_edges(editable, edges=editable.edges[:], cuts=6, use_grid_fill=True)
    bmesh.ops.triangulate(editable, faces=editable.faces[:])
    editable.to_mesh(mesh)
    editable.free()
    obj = bpy.data.objects.new("Sharp box", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def on_box_edge(points) -> np.ndarray:
    """(P,) distance of each point from the nearest edge of the sharp box."""
    gaps = np.sort(np.abs(HALF - np.abs(np.asarray(points))), axis=1)
    return np.linalg.norm(gaps[:, :2], axis=1)


def test_the_cubes_creases_pair_with_the_targets_sharp_edges(capfd):
    layout = cube_layout(sharp_box_target())
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    output = capfd.readouterr().out
    items = feature_items(layout)
    assert len(items) == 12, output
    for item in items:
        assert item.confidence > 0.5
        points = np.array([tuple(point.co) for point in item.points])
        # On the target's own edge, not beside it as a crest traced from curvatures would be.
        assert on_box_edge(points).max() < 1e-5
    assert bpy.ops.springwrap.detach(only_selected=False) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=300) == {"FINISHED"}
    positions = world_positions(layout)
    for item in items:
        chain = [int(vertex) for vertex in item.layout_vertices.split()]
        assert on_box_edge(positions[chain]).mean() < 0.01


def test_the_targets_creases_follow_the_crease_angle():
    layout = cube_layout(sharp_box_target())
    # The cube's twelve edges marked sharp: feature lines whatever the crease angle.
    positions = world_positions(layout)
    on_edge = np.sum(np.isclose(np.abs(positions), 1.0, atol=1e-4), axis=1) >= 2
    mark_sharp(layout, [tuple(edge.vertices) for edge in layout.data.edges if on_edge[list(edge.vertices)].all()])
    assert bpy.ops.springwrap.feature_lines_pair(crease_angle=30.0) == {"FINISHED"}
    exact = [np.array([tuple(point.co) for point in item.points]) for item in feature_items(layout)]
    assert len(exact) == 12
    assert max(on_box_edge(points).max() for points in exact) < 1e-5
    # Beyond the box's 90-degree edges the target's edges are no creases: only crests traced from curvatures
    # remain to pair with, and they run beside the edges.
    assert bpy.ops.springwrap.feature_lines_pair(crease_angle=95.0) == {"FINISHED"}
    traced = [np.array([tuple(point.co) for point in item.points]) for item in feature_items(layout)]
    assert all(on_box_edge(points).max() > 1e-3 for points in traced)


def test_a_crease_already_on_its_traced_crest_stays_free(capfd):
    layout = cube_layout(box_target())
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    items = feature_items(layout)
    assert len(items) == 12
    crests = [np.array([tuple(point.co) for point in item.points]) for item in items]
    assert bpy.ops.springwrap.detach(only_selected=False) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=300) == {"FINISHED"}
    positions = world_positions(layout)
    for item, crest in zip(items, crests):
        chain = [int(vertex) for vertex in item.layout_vertices.split()]
        assert distance_to_polyline(positions[chain], crest).mean() < 0.02
    capfd.readouterr()
    # The wrapped creases now lie on the crests, closer than the crests are known: pairing them again adds nothing.
    assert bpy.ops.springwrap.feature_lines_pair() == {"FINISHED"}
    output = capfd.readouterr().out
    assert not feature_items(layout), output
    assert "12 it already lies within the accuracy of its feature" in output


def test_junctions_place_each_crease_between_the_targets_corners(capfd):
    """The cube's 8 corners (three creases end at each) match the larger box's; each crease between two of them
    then follows the box's edge between those corners shared out by rest length: its chain's first vertex, a
    sixth of the way along the cube's edge, goes a sixth of the way along the box's (1.1 times as far from the
    middle). With Junctions off the stretch starts where the fit has that vertex."""
    layout = cube_layout(sharp_box_target())
    positions = world_positions(layout)

    def first_points(use_junctions):
        assert bpy.ops.springwrap.feature_lines_pair(use_junctions=use_junctions) == {"FINISHED"}
        found = []
        for item in feature_items(layout):
            first = positions[int(item.layout_vertices.split()[0])]
            point = np.array(tuple(item.points[0].co))
            along = int(np.argmin(np.abs(np.abs(first) - 1.0) < 1e-4))  # the one axis the edge runs along
            found.append((first[along], point[along]))
        return np.array(found)

    matched = first_points(True)
    assert "8 corners matched, 12 pairs between two" in capfd.readouterr().out
    assert len(matched) == 12
    np.testing.assert_allclose(matched[:, 1], HALF * matched[:, 0], atol=1e-4)
    unmatched = first_points(False)
    assert "0 corners matched, 0 pairs between two" in capfd.readouterr().out
    np.testing.assert_allclose(unmatched[:, 1], unmatched[:, 0], atol=1e-4)


def test_placement_anchors_puts_each_crease_vertex_where_the_corners_map_it_as_spaced_where_the_fit_has_it():
    """The cube's rest shape stored, then its vertices slid along x unevenly (the corners stay): the creases along
    x are spaced unevenly under the fit. With Placement Anchors each of their vertices goes along the box's edge
    where the map through the 8 matched corners (a scaling by 1.1) takes its rest point; As Spaced, where the
    uneven spacing has it."""
    from springwrap.blender import attributes
    from springwrap.core import curves

    layout = cube_layout(sharp_box_target())
    rest = world_positions(layout)
    attributes.write_rest(layout, rest)
    slid = rest.copy()
    slid[:, 0] += 0.15 * (1.0 - rest[:, 0] ** 2)
    layout.data.vertices.foreach_set("co", slid.astype(np.float32).ravel())
    layout.data.update()

    def along_x(placement):
        assert bpy.ops.springwrap.feature_lines_pair(placement=placement) == {"FINISHED"}
        found = []
        for item in feature_items(layout):
            chain = np.array([int(vertex) for vertex in item.layout_vertices.split()])
            if np.ptp(rest[chain, 0]) < 1.0:
                continue  # a crease along y or z
            points = np.array([tuple(point.co) for point in item.points])
            fractions = np.array([entry.value for entry in item.fractions])
            assert fractions.size == (chain.size if placement == "MAPPED" else 0)
            pulled = curves.arc_length_points(slid[chain], points, fractions)
            found.append(np.abs(pulled[:, 0] - HALF * rest[chain, 0]).max())
        assert len(found) == 4
        return max(found)

    assert along_x("MAPPED") < 1e-3
    assert along_x("SPACED") > 0.05
