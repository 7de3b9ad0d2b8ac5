"""Symmetric anchors under Blender: ``anchor_add(symmetric=True)``, ``anchors_auto(symmetric=True)``, pairs removed
together, kept by update, save and undo, shown as pairs in the panel's list.

The scene: an exactly symmetric head (``symmetric_target_arrays``) and a whole sphere layout around it whose
vertices are numbered in a shuffled order, both placed by the same rotation and offset (``PLACEMENT``), so the
layout's local X plane is the target's plane of symmetry in world space. References: the layout's known
mirror map, the plane from ``PLACEMENT``, and ``mathutils`` BVHTree closest points.
"""

import bpy

import bmesh
import numpy as np
import pytest
from mathutils import Matrix

from bpy_helpers import (
    PLACEMENT,
    PanelRecorder,
    Reference,
    activate,
    symmetric_head_scene,
    world_plane,
    world_positions,
)

TOLERANCE = 1e-4  # world units, on a head about 2.5 across: float32 storage of placed vertices and anchors


def reflect(points):
    point, normal = world_plane()
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points - 2.0 * np.outer((points - point) @ normal, normal)


def anchors_of(layout):
    """(vertices, twins, locations, kinds) of the anchor list."""
    items = layout.springwrap.anchors
    vertices = np.array([item.vertex_index for item in items], dtype=np.int64)
    twins = np.array([item.twin_vertex for item in items], dtype=np.int64)
    locations = np.array([tuple(item.location) for item in items], dtype=np.float64).reshape(-1, 3)
    return vertices, twins, locations, [item.target_kind for item in items]


def off_plane_vertices(twins, count=4):
    return [int(vertex) for vertex in np.flatnonzero(twins != np.arange(len(twins)))[::37][:count]]


def test_add_symmetric_anchors_the_twin_at_the_reflection(capfd):
    target, layout, twins = symmetric_head_scene()
    reference = Reference(target)
    world = world_positions(layout)
    for vertex in off_plane_vertices(twins):
        location = world[vertex] + [0.05, -0.02, 0.03]
        result = bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=tuple(location), use_location=True, symmetric=True
        )
        assert result == {"FINISHED"}
        assert f"its twin: vertex {twins[vertex]} (by topology)" in capfd.readouterr().out
    vertices, pairs, locations, kinds = anchors_of(layout)
    assert len(vertices) == 8 and kinds == ["FACE"] * 8
    np.testing.assert_array_equal(pairs, twins[vertices])
    np.testing.assert_allclose(world[twins[vertices]], reflect(world[vertices]), atol=1e-5)  # layout twins
    partner = {int(vertex): index for index, vertex in enumerate(vertices)}
    mirrored = locations[[partner[int(twin)] for twin in pairs]]
    assert np.abs(mirrored - reflect(locations)).max() < TOLERANCE  # target twins: reflections
    for own, twin in zip(locations[::2], locations[1::2]):
        expected, _index, _distance = reference.nearest(reflect(own)[0])
        np.testing.assert_allclose(twin, expected, atol=TOLERANCE)  # the closest point to the reflection
    assert layout.springwrap.active_anchor_index == len(vertices) - 2  # the anchor asked for, not its twin


def test_an_anchor_on_the_plane_is_its_own_twin():
    _target, layout, twins = symmetric_head_scene()
    vertex = int(np.flatnonzero(twins == np.arange(len(twins)))[5])
    location = tuple(world_positions(layout)[vertex])
    assert bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=location, use_location=True, symmetric=True) == {
        "FINISHED"
    }
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert vertices.tolist() == [vertex] and pairs.tolist() == [vertex]


def test_no_target_near_the_reflection_adds_one_anchor_and_warns(capfd):
    target, layout, twins = symmetric_head_scene()
    # The target's x < 0 half deleted: nothing near the reflection of a point 0.3 on the x > 0 side (the reach is
    # 5 % of the half head's diagonal, about 0.12).
    editable = bmesh.new()
    editable.from_mesh(target.data)
    bmesh.ops.delete(editable, geom=[vertex for vertex in editable.verts if vertex.co.x < -1e-6], context="VERTS")
    editable.to_mesh(target.data)
    editable.free()
    target.data.update()
    world = world_positions(layout)
    point, normal = world_plane()
    vertex = next(v for v in off_plane_vertices(twins, 20) if (world[v] - point) @ normal > 0.3)
    assert bpy.ops.springwrap.anchor_add(
        vertex_index=vertex, location=tuple(world[vertex]), use_location=True, symmetric=True
    ) == {"FINISHED"}
    assert "1 with no target point near the reflection" in capfd.readouterr().out
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert vertices.tolist() == [vertex] and pairs.tolist() == [-1]


def test_remove_takes_the_twin_too_unless_told_not_to():
    _target, layout, twins = symmetric_head_scene()
    world = world_positions(layout)
    first, second = off_plane_vertices(twins, 2)
    for vertex in (first, second):
        bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=tuple(world[vertex]), use_location=True, symmetric=True
        )
    assert bpy.ops.springwrap.anchor_remove(index=0) == {"FINISHED"}
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert sorted(vertices.tolist()) == sorted([second, int(twins[second])])
    assert bpy.ops.springwrap.anchor_remove(index=0, with_twin=False) == {"FINISHED"}
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert len(vertices) == 1 and pairs.tolist() == [-1]  # the other half stays, unpaired
    assert bpy.ops.springwrap.anchors_clear() == {"FINISHED"}
    assert len(layout.springwrap.anchors) == 0


@pytest.mark.parametrize("spacing", [0.3, 0.6])
def test_auto_symmetric_is_exactly_symmetric(spacing, capfd):
    target, layout, twins = symmetric_head_scene()
    assert bpy.ops.springwrap.anchors_auto(spacing=spacing, symmetric=True) == {"FINISHED"}
    assert "spread on the + side" in capfd.readouterr().out
    vertices, pairs, locations, kinds = anchors_of(layout)
    assert len(vertices) > 10 and kinds == ["FACE"] * len(vertices)
    np.testing.assert_array_equal(pairs, twins[vertices])  # every anchor paired with its vertex's mirror
    assert set(vertices.tolist()) == set(twins[vertices].tolist())
    index_of = {int(vertex): index for index, vertex in enumerate(vertices)}
    mirrored = locations[[index_of[int(twin)] for twin in pairs]]
    paired = pairs != vertices  # an anchor on the plane is its own twin, at its own closest point
    assert paired.sum() > 10 and (~paired).sum() > 0
    assert np.abs(mirrored - reflect(locations))[paired].max() < TOLERANCE
    world = world_positions(layout)[vertices]
    gaps = np.linalg.norm(world[:, None] - world[None], axis=2) + np.eye(len(world)) * 1e9
    assert gaps.min() >= spacing * (1 - 1e-5)
    # update keeps the pairs, and so do saving and loading
    assert bpy.ops.springwrap.anchors_update() == {"FINISHED"}
    np.testing.assert_array_equal(anchors_of(layout)[1], pairs)


def test_a_symmetry_empty_gives_the_same_pairs():
    _target, layout, twins = symmetric_head_scene()
    empty = bpy.data.objects.new("Plane Empty", None)
    bpy.context.scene.collection.objects.link(empty)
    empty.matrix_world = PLACEMENT @ Matrix.Rotation(np.pi / 2, 4, "Z")  # its local Y is the layout's X
    activate(layout)
    bpy.context.view_layer.update()
    vertex = off_plane_vertices(twins, 1)[0]
    location = tuple(world_positions(layout)[vertex])
    assert bpy.ops.springwrap.anchor_add(
        vertex_index=vertex,
        location=location,
        use_location=True,
        symmetric=True,
        symmetry_axis="Y",
        symmetry_object="Plane Empty",
    ) == {"FINISHED"}
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert sorted(vertices.tolist()) == sorted([vertex, int(twins[vertex])])


def test_pairs_survive_save_reload_and_undo(tmp_path):
    _target, layout, twins = symmetric_head_scene()
    vertex = off_plane_vertices(twins, 1)[0]
    location = tuple(world_positions(layout)[vertex])
    bpy.ops.ed.undo_push(message="before")
    bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=location, use_location=True, symmetric=True)
    bpy.ops.ed.undo_push(message="symmetric anchor")
    path = str(tmp_path / "pairs.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    layout = bpy.data.objects["Layout"]
    vertices, pairs, _locations, _kinds = anchors_of(layout)
    assert sorted(zip(vertices.tolist(), pairs.tolist())) == sorted(
        [(vertex, int(twins[vertex])), (int(twins[vertex]), vertex)]
    )
    activate(layout)
    bpy.ops.ed.undo_push(message="loaded")
    bpy.ops.springwrap.anchor_remove(index=0)
    bpy.ops.ed.undo_push(message="removed")
    assert len(bpy.data.objects["Layout"].springwrap.anchors) == 0
    bpy.ops.ed.undo()
    assert len(bpy.data.objects["Layout"].springwrap.anchors) == 2


def test_anchors_without_a_pairing_field_load_as_unpaired():
    """Files saved before symmetric anchors have no ``twin_vertex``: the property's default, -1, means no pair."""
    _target, layout, _twins = symmetric_head_scene()
    item = layout.springwrap.anchors.add()
    item.vertex_index = 3
    item.location = tuple(world_positions(layout)[3])
    assert item.twin_vertex == -1
    assert bpy.ops.springwrap.anchors_update() == {"FINISHED"}
    assert bpy.ops.springwrap.anchor_remove(index=0) == {"FINISHED"}


def test_the_panel_offers_symmetric_anchors_and_the_list_shows_pairs():
    from springwrap.ui.lists import SPRINGWRAP_UL_anchors
    from springwrap.ui.panels import SPRINGWRAP_PT_anchors

    _target, layout, twins = symmetric_head_scene()
    settings = layout.springwrap
    settings.anchor_symmetric = True
    settings.anchor_symmetry_axis = "Z"
    recorder = PanelRecorder()
    panel = type("Panel", (), {"layout": recorder})()
    SPRINGWRAP_PT_anchors.draw(panel, bpy.context)
    assert {"anchor_symmetric", "anchor_symmetry_axis", "anchor_symmetry_object"} <= set(recorder.props)
    buttons = dict(recorder.operators)
    for name in ("springwrap.anchor_add", "springwrap.anchors_auto"):
        assert buttons[name].symmetric is True and buttons[name].symmetry_axis == "Z"
        assert buttons[name].symmetry_object == ""

    settings.anchor_symmetry_axis = "X"
    world = world_positions(layout)
    vertex = off_plane_vertices(twins, 1)[0]
    middle = int(np.flatnonzero(twins == np.arange(len(twins)))[3])
    for chosen in (vertex, middle):
        bpy.ops.springwrap.anchor_add(
            vertex_index=chosen, location=tuple(world[chosen]), use_location=True, symmetric=True
        )
    labels, numbers = {}, {}
    for index, item in enumerate(settings.anchors):
        row = PanelRecorder()
        SPRINGWRAP_UL_anchors.draw_item(None, bpy.context, row, settings, item, 0, None, "", index)
        labels[item.vertex_index], numbers[item.vertex_index] = row.labels, str(index + 1)
    twin = int(twins[vertex])
    # The pair number, the vertex, the twin anchor's pair number (as the viewport numbers them).
    assert labels[vertex][:3] == [numbers[vertex], f"v{vertex}", f"\u2194{numbers[twin]}"]
    assert labels[twin][:3] == [numbers[twin], f"v{twin}", f"\u2194{numbers[vertex]}"]
    assert labels[middle][:3] == [numbers[middle], f"v{middle}", "\u2194mid"]
