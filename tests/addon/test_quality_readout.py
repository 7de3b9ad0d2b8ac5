"""The quality read-out: the attributes every operator that
moves the layout onto the target writes, their distances against ``mathutils``' BVH on the evaluated target,
Select Problems, the heat-map's toggle in background mode and the Check panel."""

import bpy

import bmesh
import numpy as np
import pytest
from mathutils import Vector
from mathutils.bvhtree import BVHTree

from bpy_helpers import (
    PanelRecorder,
    head_scene,
    local_positions,
    plane_scene,
    set_selection,
    snapshot,
    world_positions,
    wrap_session,
)

NAMES = ("springwrap_distance", "springwrap_stretch", "springwrap_flipped")


def readout(layout):
    """(distances, stretch, flipped) as stored, or None when an attribute is missing."""
    mesh = layout.data
    if any(mesh.attributes.get(name) is None for name in NAMES):
        return None
    distance, stretch, flipped = (mesh.attributes[name] for name in NAMES)
    assert (distance.domain, distance.data_type) == ("POINT", "FLOAT")
    assert (stretch.domain, stretch.data_type) == ("POINT", "FLOAT")
    assert (flipped.domain, flipped.data_type) == ("FACE", "BOOLEAN")
    values = []
    for attribute, dtype in ((distance, np.float32), (stretch, np.float32), (flipped, bool)):
        array = np.empty(len(attribute.data), dtype=dtype)
        attribute.data.foreach_get("value", array)
        values.append(array)
    return tuple(values)


def bvh_distances(layout, target):
    """Distances of the layout's vertices (world) to the evaluated target in world space, by ``mathutils``:
    ``BVHTree.FromObject`` (the evaluated mesh's own triangles, in the target's space), queried at the points
    taken into that space, the nearest point taken back to world space."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    tree = BVHTree.FromObject(target, depsgraph)
    matrix = target.evaluated_get(depsgraph).matrix_world
    inverse = matrix.inverted()
    distances = []
    for point in world_positions(layout):
        location = tree.find_nearest(inverse @ Vector(point))[0]
        distances.append((matrix @ location - Vector(point)).length)
    return np.array(distances)


def fold(layout, vertex=84, cells=3.0):
    """Set the rest shape, then drag an inner vertex of the plane scene's 13 x 13 grid ``cells`` cells along its
    local x, over its neighbours: the faces around it turn over. The faces now facing against the grid's normal."""
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    layout.data.vertices[vertex].co.x += cells * 2.0 / 12.0
    layout.data.update()
    corners = np.array([tuple(polygon.vertices) for polygon in layout.data.polygons])
    points = np.array([tuple(v.co) for v in layout.data.vertices])[corners]
    normals = np.cross(points[:, 2] - points[:, 0], points[:, 3] - points[:, 1])
    return np.flatnonzero(normals[:, 2] < 0.0)


def body_like_scene():
    """The head-like target (nose, ears, flattened top) with a Subdivision Surface and a Displace modifier (the
    read-out must use the evaluated target) placed by a rotation and an offset, and a sphere layout around it."""
    target, layout = head_scene(scale=1.25)
    target.modifiers.new("Subdivision", "SUBSURF").levels = 1
    displace = target.modifiers.new("Displace", "DISPLACE")
    displace.strength = 0.03
    displace.texture = bpy.data.textures.new("Clouds", "CLOUDS")
    bpy.context.view_layer.update()
    return target, layout


@pytest.mark.parametrize("operation", ["snap", "project", "wrap", "mirror", "mirror without wrap"])
def test_each_operation_onto_the_target_writes_the_readout(operation):
    if operation.startswith("mirror"):
        target, layout = head_scene(on_target=True)
        assert bpy.ops.springwrap.snap() == {"FINISHED"}
        for name in NAMES:
            layout.data.attributes.remove(layout.data.attributes[name])
        assert readout(layout) is None
        arguments = {"axis": "X", "max_iterations": 200, "wrap": operation == "mirror"}
        assert bpy.ops.springwrap.mirror(**arguments) == {"FINISHED"}
    else:
        target, layout, _normal = plane_scene()
        if operation == "wrap":
            assert bpy.ops.springwrap.anchors_auto(spacing=0.5) == {"FINISHED"}
            assert bpy.ops.springwrap.wrap(max_iterations=300) == {"FINISHED"}
        else:
            arguments = {"direction": "-Z", "orientation": "LOCAL"} if operation == "project" else {}
            assert getattr(bpy.ops.springwrap, operation)(**arguments) == {"FINISHED"}
    distances, stretch, flipped = readout(layout)
    assert distances.size == stretch.size == len(layout.data.vertices)
    assert flipped.size == len(layout.data.polygons)
    assert np.allclose(distances, bvh_distances(layout, target), atol=1e-6)
    assert np.isfinite(stretch).all() and (stretch > 0).all()
    if operation != "mirror without wrap":  # a layout on the target, facing as it does
        assert distances.max() < 1e-5 and flipped.sum() <= 0.01 * flipped.size


def test_detach_does_not_write_the_readout():
    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.detach() == {"FINISHED"}
    assert readout(layout) is None


def test_distances_agree_with_mathutils_bvh_on_the_evaluated_body_like_target():
    target, layout = body_like_scene()
    set_selection(layout, np.arange(len(layout.data.vertices)) % 3 == 0)
    # Project a third of the vertices: the rest stay up to 0.35 off, so the distances are not all zero.
    assert bpy.ops.springwrap.project(direction="NORMAL", only_selected=True, max_distance=0.5) == {"FINISHED"}
    distances, _stretch, _flipped = readout(layout)
    reference = bvh_distances(layout, target)
    assert reference.max() > 0.1 and (reference < 1e-5).sum() > 10
    assert np.abs(distances - reference).max() < 1e-6
    assert bpy.ops.springwrap.anchors_auto(spacing=0.3) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=40) == {"FINISHED"}  # may stop before the end: still measured
    distances, _stretch, _flipped = readout(layout)
    assert np.abs(distances - bvh_distances(layout, target)).max() < 1e-6


def test_stretch_is_the_edge_length_against_the_rest_shape():
    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    positions = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", positions)
    layout.data.vertices.foreach_set("co", positions * np.tile([1.4, 1.4, 1.0], positions.size // 3))
    layout.data.update()  # 1.4 times as large in the plane (the grid is flat in its local z), still over the target
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    _distances, stretch, flipped = readout(layout)
    assert np.allclose(stretch, 1.4, atol=1e-5) and not flipped.any()


def test_select_problems_selects_the_flipped_faces_in_edit_mode():
    _target, layout, _normal = plane_scene()
    turned = fold(layout).tolist()
    assert turned
    assert bpy.ops.springwrap.snap() == {"FINISHED"}  # onto the plane: the folded faces stay folded
    _distances, _stretch, flipped = readout(layout)
    assert np.flatnonzero(flipped).tolist() == turned
    assert bpy.ops.springwrap.select_problems(kind="FLIPPED") == {"FINISHED"}
    assert layout.mode == "EDIT"
    assert tuple(bpy.context.tool_settings.mesh_select_mode) == (False, False, True)
    editable = bmesh.from_edit_mesh(layout.data)
    editable.faces.ensure_lookup_table()
    assert [face.index for face in editable.faces if face.select] == turned
    corners = {vertex.index for index in turned for vertex in editable.faces[index].verts}
    assert {vertex.index for vertex in editable.verts if vertex.select} == corners


@pytest.mark.parametrize("kind, threshold", [("OFF_SURFACE", 0.1), ("OFF_SURFACE", 0.0), ("STRETCHED", 1.1)])
def test_select_problems_selects_the_vertices_past_the_threshold_and_deselects_the_rest(kind, threshold):
    target, layout = body_like_scene()
    set_selection(layout, np.arange(len(layout.data.vertices)) % 2 == 0)
    assert bpy.ops.springwrap.project(direction="NORMAL", only_selected=True, max_distance=0.5) == {"FINISHED"}
    distances, stretch, _flipped = readout(layout)
    if kind == "OFF_SURFACE":
        size = np.linalg.norm(np.ptp(world_positions(layout), axis=0))
        expected = bvh_distances(layout, target) > (threshold or 0.001 * size)
    else:
        expected = (stretch > threshold) | (stretch < 1.0 / threshold)
    assert 0 < expected.sum() < expected.size
    bpy.ops.object.mode_set(mode="EDIT")  # from edit mode too: the selection is replaced
    bpy.ops.mesh.select_all(action="SELECT")
    assert bpy.ops.springwrap.select_problems(kind=kind, threshold=threshold) == {"FINISHED"}
    assert layout.mode == "EDIT"
    editable = bmesh.from_edit_mesh(layout.data)
    selected = np.array([vertex.select for vertex in editable.verts])
    assert np.array_equal(selected, expected)
    for face in editable.faces:  # vertex select mode's rule: a face is selected when all its corners are
        assert face.select == all(vertex.select for vertex in face.verts)


def test_select_problems_leaves_hidden_vertices_unselected():
    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    layout.data.vertices.foreach_set("co", local_positions(layout).reshape(-1) * 1.3)  # all stretched by 1.3
    hide = np.arange(len(layout.data.vertices)) < 13  # the first row hidden
    layout.data.vertices.foreach_set("hide", hide)
    layout.data.update()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.select_problems(kind="STRETCHED", threshold=1.2) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    selected = np.empty(len(layout.data.vertices), dtype=bool)
    layout.data.vertices.foreach_get("select", selected)
    assert np.array_equal(selected, ~hide)


def test_select_problems_selects_and_reports_the_vertices_without_a_number_and_refuses_when_none_has_one(capfd):
    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    stretch = np.ones(len(layout.data.vertices), dtype=np.float32)
    stretch[[3, 7]] = np.nan  # edited by hand
    layout.data.attributes["springwrap_stretch"].data.foreach_set("value", stretch)
    capfd.readouterr()
    assert bpy.ops.springwrap.select_problems(kind="STRETCHED") == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    selected = np.empty(len(layout.data.vertices), dtype=bool)
    layout.data.vertices.foreach_get("select", selected)
    assert np.flatnonzero(selected).tolist() == [3, 7]
    assert "2 vertices of 'Layout' have no stretch in the read-out (not a number" in capfd.readouterr().out
    layout.data.attributes["springwrap_stretch"].data.foreach_set("value", np.full_like(stretch, np.nan))
    with pytest.raises(RuntimeError, match="The read-out's stretch of 'Layout' is not a number anywhere"):
        bpy.ops.springwrap.select_problems(kind="STRETCHED")


def test_select_problems_frames_what_it_selected_in_the_3d_view(capfd):
    _target, layout, _normal = plane_scene()
    views = [area.spaces.active.region_3d for area in bpy.context.screen.areas if area.type == "VIEW_3D"]
    if not views:
        pytest.skip("this Blender has no 3D view in background mode")
    assert bpy.ops.springwrap.rest_set() == {"FINISHED"}
    positions = local_positions(layout).astype(np.float64)
    corner = np.flatnonzero((positions[:, 0] > 0.5) & (positions[:, 1] > 0.5))  # one corner stretched
    positions[corner] *= 1.4
    layout.data.vertices.foreach_set("co", positions.astype(np.float32).reshape(-1))
    layout.data.update()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    views[0].view_location = (50.0, 50.0, 50.0)
    capfd.readouterr()
    assert bpy.ops.springwrap.select_problems(kind="STRETCHED", threshold=1.2) == {"FINISHED"}
    assert "framed in the 3D view" in capfd.readouterr().out
    bpy.ops.object.mode_set(mode="OBJECT")
    selected = np.empty(len(layout.data.vertices), dtype=bool)
    layout.data.vertices.foreach_get("select", selected)
    centre = world_positions(layout)[selected].mean(axis=0)
    assert np.linalg.norm(np.array(views[0].view_location) - centre) < 0.5  # the view moved to the selection


def test_a_layout_of_points_alone_is_snapped_and_select_problems_says_why_it_has_no_readout():
    target, layout, normal = plane_scene()
    mesh = bpy.data.meshes.new("Points")
    mesh.from_pydata([(0.1, 0.2, 0.5), (-0.3, 0.1, 0.8), (0.2, -0.2, -0.4)], [], [])
    points = bpy.data.objects.new("Points", mesh)
    bpy.context.scene.collection.objects.link(points)
    points.matrix_world = layout.matrix_world
    points.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == points)
    bpy.context.view_layer.objects.active = points
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    on_plane = world_positions(target)[0]
    assert np.abs((world_positions(points) - on_plane) @ np.asarray(normal)).max() < 1e-5
    with pytest.raises(RuntimeError, match="'Points' has no faces and no edges: wrapping"):
        bpy.ops.springwrap.select_problems(kind="STRETCHED")
    with pytest.raises(RuntimeError, match="Snap, Project and Detach move points alone"):
        bpy.ops.springwrap.wrap()


def test_select_problems_refuses_without_a_readout_and_says_which_operators_write_it():
    _target, layout, _normal = plane_scene()
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="no quality read-out: Snap, Project, Wrap or Mirror"):
        bpy.ops.springwrap.select_problems(kind="STRETCHED")
    assert layout.mode == "OBJECT" and snapshot(layout) == before


def test_the_readout_is_undone_with_the_operation():
    _target, layout, _normal = plane_scene()
    bpy.ops.ed.undo_push(message="before")
    assert bpy.ops.springwrap.snap("EXEC_DEFAULT", True) == {"FINISHED"}
    assert readout(bpy.data.objects["Layout"]) is not None
    bpy.ops.ed.undo()
    assert readout(bpy.data.objects["Layout"]) is None


def test_the_live_wrap_writes_the_readout_when_it_finishes_and_not_when_cancelled():
    from springwrap.core.wrap_run import WrapLoop

    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.anchors_auto(spacing=0.5) == {"FINISHED"}
    session = wrap_session(layout)
    session.advance()  # a frame written into the layout: no read-out yet
    assert readout(layout) is None
    session.cancel()
    assert readout(layout) is None
    loop = WrapLoop(wrap_session(layout))
    while loop.handle("TIMER") == "RUNNING_MODAL":
        pass
    assert loop.state == "FINISHED" and loop.result.readout is not None
    distances, _stretch, _flipped = readout(layout)
    assert np.array_equal(distances, loop.result.readout.distances.astype(np.float32))


@pytest.mark.parametrize("before", ["none", "a snap's"])
def test_a_wrap_that_fails_after_writing_the_readout_puts_the_old_one_back(before, monkeypatch):
    from springwrap.blender import quality as quality_data
    from springwrap.blender import wrap_session as session_module

    _target, layout, _normal = plane_scene()
    if before != "none":
        set_selection(layout, np.arange(len(layout.data.vertices)) % 2 == 0)
        assert bpy.ops.springwrap.snap(only_selected=True) == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.5) == {"FINISHED"}
    stored, state = readout(layout), snapshot(layout)
    real_write = quality_data.write_readout

    def write_then_fail(layout_object, values):
        real_write(layout_object, values)
        raise RuntimeError("injected failure after the read-out")

    monkeypatch.setattr(session_module.quality_data, "write_readout", write_then_fail)
    with pytest.raises(RuntimeError, match="injected failure after the read-out"):
        bpy.ops.springwrap.wrap(max_iterations=50)
    assert snapshot(layout) == state
    if stored is None:
        assert readout(layout) is None
    else:
        assert all(np.array_equal(now, then) for now, then in zip(readout(layout), stored))


def test_the_heatmap_in_background_mode_is_never_installed_and_toggling_it_does_nothing():
    from springwrap.ui import heatmap

    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.app.background and not heatmap.is_installed()
    for kind in ("DISTANCE", "STRETCH", "FLIPPED"):
        layout.springwrap.heatmap_kind = kind
        layout.springwrap.show_heatmap = True
        heatmap.install()  # what register() calls: still nothing in background mode
        heatmap.draw_heatmap()
        heatmap.draw_legend()
        assert not heatmap.is_installed()
    layout.springwrap.show_heatmap = False


def test_the_heatmap_colours_read_from_the_readout():
    from springwrap.blender import quality as quality_data
    from springwrap.core import quality

    _target, layout, _normal = plane_scene()
    turned = fold(layout)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    stored = quality_data.read_readout(layout)
    scale = quality.heat_scale("FLIPPED", stored)
    assert scale.per_face and np.array_equal(np.flatnonzero(scale.values), turned)
    corners, corner_vertices, corner_faces = quality_data.read_triangles(layout)
    assert corners.shape == (len(layout.data.polygons) * 2 * 3, 3)  # quads: two triangles each
    assert np.allclose(corners, world_positions(layout)[corner_vertices], atol=1e-6)
    colours = quality.ramp_colours(scale.values)[corner_faces]
    red = np.isin(corner_faces, turned)
    assert np.allclose(colours[red, :3], quality.RAMP[-1]) and np.allclose(colours[~red, :3], quality.RAMP[0])
    distance = quality.heat_scale("DISTANCE", stored)  # all on the plane: blue, against a scale of 0.1 % of the size
    assert not distance.per_face and distance.values.max() < 0.01
    stretch = quality.heat_scale("STRETCH", stored)  # unchanged (1) is the ramp's middle, green
    assert abs(np.median(stretch.values) - 0.5) < 1e-3


def test_in_edit_mode_the_heatmap_follows_the_edit_mesh_and_stops_when_its_vertex_count_changes():
    from springwrap.blender import quality as quality_data

    _target, layout, _normal = plane_scene()
    fold(layout)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    stored = quality_data.read_readout(layout)
    assert stored.flipped.any() and stored.distances.max() > 0.0
    bpy.ops.object.mode_set(mode="EDIT")
    editable = bmesh.from_edit_mesh(layout.data)
    editable.verts.ensure_lookup_table()
    editable.verts[20].co.z += 0.5
    bmesh.update_edit_mesh(layout.data)
    corners, corner_vertices, _faces = quality_data.read_triangles(layout)
    moved = layout.matrix_world @ editable.verts[20].co
    assert np.allclose(corners[corner_vertices == 20], np.array(moved, dtype=np.float32), atol=1e-6)
    in_edit_mode = quality_data.read_readout(layout)  # the values as written, from the edit-mesh's layers
    assert all(np.allclose(now, then) for now, then in zip(in_edit_mode[:3], stored[:3]))
    bmesh.ops.delete(editable, geom=[editable.verts[0]], context="VERTS")
    bmesh.update_edit_mesh(layout.data)
    assert quality_data.read_triangles(layout) is None


def test_the_check_panel_has_the_heatmap_and_select_problems():
    from springwrap.ui.panels import SPRINGWRAP_PT_check

    _target, layout, _normal = plane_scene()
    layout.springwrap.problem_kind = "OFF_SURFACE"
    recorder = PanelRecorder()
    SPRINGWRAP_PT_check.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert {"show_heatmap", "heatmap_kind", "problem_kind"} <= set(recorder.props)
    # The toggle is a checkbox that says what it does, not a wide swatch without text.
    assert recorder.prop_options["show_heatmap"] == {"text": "Show Heat-Map"}
    (idname, button), *_ = recorder.operators
    assert idname == "springwrap.select_problems" and button.kind == "OFF_SURFACE"
