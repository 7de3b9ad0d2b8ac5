"""``springwrap.detect_features`` under Blender (PyPI ``bpy``): region colours, feature curves, reruns,
undo, a plane refused, and a wrap with a curve constraint on a detected feature curve.

The target is the rounded box of ``test_feature_binding`` (half-size 1, blend radius 0.25, moved
by ``OFFSET``), whose answer is known: 12 ridges on the blends' centre-lines, flat faces, convex blends.
"""

import bpy

import numpy as np
import pytest

from bpy_helpers import RecordingLayout, chain_pairs, distance_to_polyline, select_edges, world_positions
from helpers import centre_line_distance, rounded_box

OFFSET = np.array([0.3, -0.2, 0.1])
COLOR_ATTRIBUTE = "springwrap_curvature"
COLLECTION = "Springwrap Features"


def box_target(name="Box"):
    """The rounded box as a mesh object at ``OFFSET``, made active."""
    vertices, triangles = rounded_box()
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], triangles.tolist())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = OFFSET.tolist()
    bpy.context.scene.collection.objects.link(obj)
    activate(obj)
    bpy.context.view_layer.update()
    return obj


def activate(obj):
    for other in bpy.context.view_layer.objects:
        other.select_set(other == obj)
    bpy.context.view_layer.objects.active = obj


def feature_curves():
    collection = bpy.data.collections.get(COLLECTION)
    return [] if collection is None else sorted(collection.objects, key=lambda obj: obj.name)


def curve_points(curve, spline=0):
    """(P, 3) world points of a spline of a poly curve object (the objects have identity transforms)."""
    points = curve.data.splines[spline].points
    values = np.empty(len(points) * 4, dtype=np.float32)
    points.foreach_get("co", values)
    return values.reshape(-1, 4)[:, :3].astype(np.float64)


def colors_of(obj):
    attribute = obj.data.attributes[COLOR_ATTRIBUTE]
    values = np.empty(len(obj.data.vertices) * 4, dtype=np.float32)
    attribute.data.foreach_get("color", values)
    return values.reshape(-1, 4)


def scene_rows():
    """Objects, collections, curves and mesh attribute names: what the operator may add or change."""
    return (
        sorted(obj.name for obj in bpy.data.objects),
        sorted(collection.name for collection in bpy.data.collections),
        sorted(curve.name for curve in bpy.data.curves),
        {mesh.name: sorted(mesh.attributes.keys()) for mesh in bpy.data.meshes},
    )


def test_operator_is_registered_with_a_poll_message():
    assert hasattr(bpy.ops.springwrap, "detect_features")
    assert not bpy.ops.springwrap.detect_features.poll()
    with pytest.raises(RuntimeError, match="No active mesh object"):
        bpy.ops.springwrap.detect_features()


def test_panel_names_the_object_and_has_the_button():
    from springwrap.ui.panels import SPRINGWRAP_PT_features

    box = box_target()
    assert SPRINGWRAP_PT_features.bl_parent_id == "SPRINGWRAP_PT_layout" and SPRINGWRAP_PT_features.poll(bpy.context)
    recorder = RecordingLayout()
    SPRINGWRAP_PT_features.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.operators == ["springwrap.detect_features"] and recorder.labels == ["On 'Box'"]
    bpy.ops.mesh.primitive_grid_add(size=1, location=(0, 0, 3))
    bpy.context.active_object.springwrap.target = box
    recorder = RecordingLayout()
    SPRINGWRAP_PT_features.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.labels == ["On 'Box'"]


def test_rounded_box_gets_region_colours_and_twelve_ridge_curves(capfd):
    box = box_target()
    assert bpy.ops.springwrap.detect_features(scale=0.25) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "12 ridges and 0 valleys" in output, output

    attribute = box.data.attributes[COLOR_ATTRIBUTE]
    assert (attribute.domain, attribute.data_type) == ("POINT", "FLOAT_COLOR")
    assert box.data.color_attributes.active_color.name == COLOR_ATTRIBUTE
    colors = colors_of(box)
    vertices = world_positions(box) - OFFSET
    face_middle = np.sort(np.abs(vertices), axis=1)[:, 1] < 0.4
    on_blend = centre_line_distance(vertices) < 0.02
    from springwrap.core.features import REGION_COLORS

    np.testing.assert_array_equal(colors[face_middle], np.broadcast_to(REGION_COLORS[0], colors[face_middle].shape))
    np.testing.assert_array_equal(colors[on_blend], np.broadcast_to(REGION_COLORS[1], colors[on_blend].shape))

    # One object for the ridges (no valleys on a box), named after the target, a spline per ridge.
    assert [curve.name for curve in feature_curves()] == ["Box Ridges"]
    ridges = feature_curves()[0]
    assert ridges.type == "CURVE" and ridges["springwrap_feature"] == "RIDGE"
    assert len(ridges.data.splines) == 12
    for number, spline in enumerate(ridges.data.splines):
        assert spline.type == "POLY" and not spline.use_cyclic_u
        assert centre_line_distance(curve_points(ridges, number) - OFFSET).max() < 0.05


def test_the_default_scale_is_automatic_from_the_target(capfd):
    box = box_target()
    assert bpy.ops.springwrap.detect_features.get_rna_type().properties["scale"].default == 0.0
    assert bpy.ops.springwrap.detect_features() == {"FINISHED"}
    output = capfd.readouterr().out
    # A tenth of the box's diagonal (2 * sqrt(3) = 3.46): 0.346, above the blend radius, still 12 ridges.
    assert "at scale 0.3464 (automatic, from the target)" in output, output
    assert "12 ridges and 0 valleys" in output, output
    assert len(feature_curves()[0].data.splines) == 12
    assert box.data.attributes.get(COLOR_ATTRIBUTE) is not None


def test_run_from_a_layout_the_scale_is_the_layouts_median_edge(capfd):
    box = box_target()
    # A 4 x 4 grid of size 1 scaled by 1.5 in object mode: edges 0.375 in world space (above 6 mean box edges).
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=1, location=(0, 0, 3))
    layout = bpy.context.active_object
    layout.scale = (1.5, 1.5, 1.5)
    layout.springwrap.target = box
    bpy.context.view_layer.update()
    assert bpy.ops.springwrap.detect_features() == {"FINISHED"}
    output = capfd.readouterr().out
    assert "at scale 0.375 (automatic, from the edges of 'Grid' (median 0.375))" in output, output
    assert "12 ridges" in output, output
    # A scale given wins over the layout; a layout named explicitly is used from anywhere.
    assert bpy.ops.springwrap.detect_features(scale=0.25) == {"FINISHED"}
    assert "at scale 0.25 (given)" in capfd.readouterr().out
    activate(box)
    assert bpy.ops.springwrap.detect_features(layout_name="Grid") == {"FINISHED"}
    assert "from the edges of 'Grid'" in capfd.readouterr().out


def test_a_missing_layout_is_reported_and_the_scene_left_untouched():
    box_target()
    before = scene_rows()
    with pytest.raises(RuntimeError, match="No mesh object called 'Nowhere'"):
        bpy.ops.springwrap.detect_features(layout_name="Nowhere")
    assert scene_rows() == before


def test_a_layout_with_a_target_analyses_its_target_and_a_rerun_replaces_the_curves():
    box = box_target()
    bpy.ops.mesh.primitive_grid_add(size=1, location=(0, 0, 3))
    layout = bpy.context.active_object
    layout.springwrap.target = box
    assert bpy.ops.springwrap.detect_features(scale=0.25) == {"FINISHED"}
    assert COLOR_ATTRIBUTE not in layout.data.attributes
    assert COLOR_ATTRIBUTE in box.data.attributes
    assert [curve.name for curve in feature_curves()] == ["Box Ridges"]
    ridges = feature_curves()[0]
    curve_count = len(bpy.data.curves)
    assert bpy.ops.springwrap.detect_features(scale=0.25, write_colors=False) == {"FINISHED"}
    assert feature_curves() == [ridges] and len(ridges.data.splines) == 12  # the same object, refilled
    assert len(bpy.data.curves) == curve_count
    # A coarser scale finds fewer ridges: the object keeps only the new ones.
    assert bpy.ops.springwrap.detect_features(scale=0.25, ridge_threshold=100.0, write_colors=False) == {"FINISHED"}
    assert feature_curves() == [] and len(bpy.data.curves) == curve_count - 1


def test_a_plane_is_reported_and_the_scene_left_untouched():
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=20, size=4)
    before = scene_rows()
    with pytest.raises(RuntimeError, match="no curvature"):
        bpy.ops.springwrap.detect_features()
    assert scene_rows() == before


def test_undo_removes_the_colours_and_curves():
    box_target()
    bpy.ops.ed.undo_push(message="Box added")
    before = scene_rows()
    assert bpy.ops.springwrap.detect_features("EXEC_DEFAULT", True, scale=0.25) == {"FINISHED"}
    assert scene_rows() != before
    bpy.ops.ed.undo()
    assert scene_rows() == before


def strip_over_the_edge():
    """A 2 x 10 quad strip (a grid primitive, reshaped) bent round the box's (+x, +y) edge, 0.15 off
    the blend (radius 0.4 about the inner edge), rows at 0°, 45° and 90°; row 1 (vertices 11..21)
    runs over the centre-line."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=2, size=1)
    layout = bpy.context.active_object
    layout.name = "Layout"
    assert len(layout.data.vertices) == 33
    angles = np.radians([0.0, 45.0, 90.0])
    heights = np.linspace(-0.6, 0.6, 11)
    rows = [
        np.stack([0.75 + 0.4 * np.cos(a) + 0 * heights, 0.75 + 0.4 * np.sin(a) + 0 * heights, heights], axis=1)
        for a in angles
    ]
    # The grid's vertices run along x first: vertex k * 11 + j is row k, column j.
    vertices = np.concatenate(rows) + OFFSET
    layout.data.vertices.foreach_set("co", vertices.astype(np.float32).reshape(-1))
    layout.data.update()
    return layout


def test_a_detected_curve_is_a_curve_constraint_the_wrap_follows():
    box = box_target()
    assert bpy.ops.springwrap.detect_features(scale=0.25) == {"FINISHED"}
    layout = strip_over_the_edge()
    layout.springwrap.target = box
    activate(layout)
    # The detected ridge along the (+x, +y) edge: a spline of the one ridges object, which the constraint
    # picks as the one nearest the chain.
    ridges = feature_curves()[0]
    polylines = [curve_points(ridges, number) for number in range(len(ridges.data.splines))]
    polyline = min(polylines, key=lambda points: np.abs(points[:, :2] - OFFSET[:2] - 0.927).sum())
    chain = list(range(11, 22))
    select_edges(layout, chain_pairs(chain))
    assert bpy.ops.springwrap.curve_constraint_add(curve_object=ridges.name) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    before = distance_to_polyline(world_positions(layout)[chain], polyline)
    assert before.min() > 0.1
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    after = distance_to_polyline(world_positions(layout)[chain], polyline)
    assert after.max() < 1e-3, after
    # And so the chain lies on the blend's centre-line.
    assert centre_line_distance(world_positions(layout)[chain] - OFFSET).max() < 0.05


def test_a_voxel_remeshed_round_body_has_no_feature_curves_at_the_automatic_scale(capfd):
    """A smooth round body (a subdivided cube) remeshed with voxels of 4 % of its size has steps but no crease.
    Run from a fine layout, the automatic scale is the least the target's edges allow, and the fit there must
    not trace the steps (at 3 mean edges with joins within one scale it traced 8 curves)."""
    from benchmarks.retarget import cases

    bpy.ops.mesh.primitive_cube_add(size=2.0)
    cube = bpy.context.active_object
    cube.modifiers.new("Subdivision", "SUBSURF").levels = 3
    evaluated = cube.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    vertices = np.array([vertex.co[:] for vertex in evaluated.vertices])
    quads = np.array([polygon.vertices[:] for polygon in evaluated.polygons])
    cube.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh_clear()
    bpy.data.objects.remove(cube)
    remeshed, triangles = cases.voxel_remesh(vertices, quads, 0.04)
    mesh = bpy.data.meshes.new("Remeshed")
    mesh.from_pydata(remeshed.tolist(), [], triangles.tolist())
    target = bpy.data.objects.new("Remeshed", mesh)
    bpy.context.scene.collection.objects.link(target)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=100, y_subdivisions=100, size=1, location=(0, 0, 3))
    layout = bpy.context.active_object  # edges of 0.01: finer than the target's
    layout.springwrap.target = target
    capfd.readouterr()
    assert bpy.ops.springwrap.detect_features(write_curves=False) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "0 ridges and 0 valleys" in output, output
