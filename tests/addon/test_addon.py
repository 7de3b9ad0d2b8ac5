"""The Springwrap add-on under Blender (PyPI ``bpy``): operators checked against mathutils.

Scenes are small and generated: a UV-sphere target and a grid / ico-sphere layout, all with
object transforms that are not identity (rotation, non-uniform scale, offset) so that every
check also covers world-space handling. References come from ``mathutils`` (BVHTree, KDTree)
built on the evaluated target in world space, independent of the kernel.
"""

import math

import bpy

import bmesh
import numpy as np
import pytest
from mathutils import Quaternion, Vector

from bpy_helpers import (
    BARYCENTRIC_ATTRIBUTE,
    FACE_ATTRIBUTE,
    FACE_POINT,
    SPACE_POINT,
    STATE_ATTRIBUTE,
    STATE_NAMES,
    TOLERANCE,
    PanelRecorder,
    Reference,
    addon_module,
    as_layout,
    assert_face_points_consistent,
    delete_faces,
    empty_target,
    local_positions,
    make_grid_layout,
    make_target,
    nan_layout_vertex,
    nan_target_vertex,
    no_target,
    read_state,
    scene,
    set_selection,
    snapshot,
    target_without_faces,
    world_positions,
)

REATTACH_TOLERANCE = 1e-5  # relative to the target's bounding-box diagonal (paper 2.1 rule)
AXES = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1), "-X": (-1, 0, 0), "-Y": (0, -1, 0), "-Z": (0, 0, -1)}


# ---------------------------------------------------------------- scene builders


# ---------------------------------------------------------------- readers


def assert_reported(capfd, *parts):
    """The operator's report (printed in background mode) says each of ``parts``."""
    output = capfd.readouterr().out
    for part in parts:
        assert part in output, output


def assert_closest_points(reference, queries, results):
    """Each result is the closest target point to its query, as ``BVHTree.find_nearest`` says, to 1e-5.

    find_nearest works in float32, and far from the surface a distance that agrees to 1e-8 leaves
    the point free by ~1e-4 along the surface. So a result that is not within 1e-5 of the
    mathutils point must be an equally near point (distance within 1e-6) on the surface; this may
    happen for a few vertices only.
    """
    expected = np.array([reference.nearest(query)[0] for query in queries])
    expected_distances = np.linalg.norm(expected - queries, axis=1)
    distances = np.linalg.norm(results - queries, axis=1)
    on_surface = np.array([reference.nearest(result)[2] for result in results])
    np.testing.assert_allclose(distances, expected_distances, rtol=0, atol=1e-6)
    assert on_surface.max() <= TOLERANCE
    differs = np.linalg.norm(results - expected, axis=1) > TOLERANCE
    assert differs.sum() <= max(2, len(queries) // 20), f"{differs.sum()} of {len(queries)} points differ"


# ---------------------------------------------------------------- registration


def test_enable_registers_operators_panel_and_settings():
    import addon_utils

    import springwrap

    assert springwrap.bl_info["name"] == "Springwrap"
    assert springwrap.bl_info["category"] == "Mesh"
    assert springwrap.bl_info["blender"] >= (3, 4, 0)
    for name in ("detach", "snap", "project"):
        operator = getattr(bpy.ops.springwrap, name)
        assert operator.get_rna_type().identifier == f"SPRINGWRAP_OT_{name}"
        assert operator.get_rna_type().description  # the docstring tooltip
        assert getattr(bpy.types, f"SPRINGWRAP_OT_{name}").bl_options == {"REGISTER", "UNDO"}
    assert hasattr(bpy.types, "SPRINGWRAP_PT_layout")
    assert "springwrap" in bpy.types.Object.bl_rna.properties

    addon_utils.disable("springwrap", default_set=True)
    assert not hasattr(bpy.types, "SPRINGWRAP_OT_snap")
    assert "springwrap" not in bpy.types.Object.bl_rna.properties
    addon_utils.enable("springwrap", default_set=True)
    assert hasattr(bpy.types, "SPRINGWRAP_OT_snap")


def test_target_poll_accepts_only_other_mesh_objects():
    target, layout = scene()
    poll = type(layout.springwrap).bl_rna.properties["target"]
    assert poll.fixed_type.identifier == "Object"
    from springwrap.properties import _is_target_candidate

    bpy.ops.object.empty_add()
    empty = bpy.context.active_object
    assert _is_target_candidate(layout.springwrap, target)
    assert not _is_target_candidate(layout.springwrap, layout)
    assert not _is_target_candidate(layout.springwrap, empty)


def test_poll_fails_with_a_message_when_no_target_is_set():
    target = make_target()
    layout = make_grid_layout(target)
    layout.springwrap.target = None
    assert not bpy.ops.springwrap.snap.poll()
    assert not bpy.ops.springwrap.project.poll()
    with pytest.raises(RuntimeError, match="No target set"):
        bpy.ops.springwrap.snap()
    # Detach needs no target: it only frees vertices.
    assert bpy.ops.springwrap.detach.poll()


def test_poll_fails_without_an_active_mesh():
    make_target()
    bpy.ops.object.empty_add()
    assert not bpy.ops.springwrap.snap.poll()
    with pytest.raises(RuntimeError, match="No active mesh object"):
        bpy.ops.springwrap.detach()


# ---------------------------------------------------------------- snap


@pytest.mark.parametrize("layout_kind", ["grid", "inner"])
def test_snap_surface_lands_on_the_closest_point(layout_kind, capfd):
    target, layout = scene(layout_kind)
    reference = Reference(target)
    before = world_positions(layout)
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}

    after = world_positions(layout)
    assert_closest_points(reference, before, after)
    assert np.abs(after - before).max() > 0.1  # the vertices really moved
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == FACE_POINT)
    assert_face_points_consistent(layout, reference)
    assert layout.springwrap.target_signature == reference.signature()
    assert f"Snapped {len(before)} vertices (SURFACE)" in capfd.readouterr().out


def test_snap_vertex_lands_on_the_nearest_target_vertex():
    target, layout = scene()
    reference = Reference(target)
    before = world_positions(layout)
    bpy.ops.springwrap.snap(mode="VERTEX")

    after = world_positions(layout)
    nearest = np.array([reference.kd.find(point)[1] for point in before])
    np.testing.assert_allclose(after, reference.vertices[nearest], rtol=0, atol=TOLERANCE)
    states, faces, barycentrics = read_state(layout)
    assert np.all(states == FACE_POINT)
    assert np.all(np.sort(barycentrics, axis=1) == [0.0, 0.0, 1.0])  # exactly one corner
    corner = np.argmax(barycentrics, axis=1)
    assert np.array_equal(reference.triangles[faces, corner], nearest)


def test_snap_max_distance_leaves_far_vertices_untouched(capfd):
    target, layout = scene()
    reference = Reference(target)
    before_local = local_positions(layout).copy()
    before = world_positions(layout)
    distances = np.array([reference.nearest(point)[2] for point in before])
    ordered = np.sort(distances)
    gap = np.argmax(np.diff(ordered[10:-10])) + 10  # a threshold well away from any vertex
    max_distance = float(ordered[gap] + ordered[gap + 1]) / 2
    near = distances <= max_distance
    assert 0 < near.sum() < len(near)

    bpy.ops.springwrap.snap(mode="SURFACE", max_distance=max_distance)
    after_local = local_positions(layout)
    states, faces, _barycentrics = read_state(layout)
    assert after_local[~near].tobytes() == before_local[~near].tobytes()
    assert np.all(states[~near] == SPACE_POINT) and np.all(faces[~near] == -1)
    assert np.all(states[near] == FACE_POINT)
    assert_closest_points(reference, before[near], world_positions(layout)[near])
    assert_reported(capfd, f"Snapped {near.sum()} vertices", f"{(~near).sum()} beyond max distance left untouched")


def test_snap_only_selected_touches_only_selected_vertices():
    target, layout = scene()
    reference = Reference(target)
    count = len(layout.data.vertices)
    selected = np.arange(count) % 3 == 0
    set_selection(layout, selected)
    before_local = local_positions(layout).copy()
    before = world_positions(layout)

    bpy.ops.springwrap.snap(only_selected=True)
    states, faces, barycentrics = read_state(layout)
    assert local_positions(layout)[~selected].tobytes() == before_local[~selected].tobytes()
    assert np.all(states[~selected] == 0) and np.all(faces[~selected] == -1) and not barycentrics[~selected].any()
    assert np.all(states[selected] == 1)
    assert_closest_points(reference, before[selected], world_positions(layout)[selected])


def test_snap_follows_target_changes_and_caches_at_most_two_targets():
    target, layout = scene()
    bpy.ops.springwrap.snap()
    assert addon_module("blender.target").cached_target_count() == 1
    bpy.ops.springwrap.snap()  # same content: no rebuild
    assert addon_module("blender.target").cached_target_count() == 1

    target.location.z += 0.25  # new world content: rebuilt
    bpy.context.view_layer.update()
    bpy.ops.springwrap.detach()
    before = world_positions(layout)
    bpy.ops.springwrap.snap()
    reference = Reference(target)
    assert_closest_points(reference, before, world_positions(layout))
    assert addon_module("blender.target").cached_target_count() == 2

    layout.springwrap.target = make_target("Other", location=(0.0, 0.0, 0.0))
    bpy.context.view_layer.objects.active = layout
    bpy.ops.springwrap.snap()
    assert addon_module("blender.target").cached_target_count() == 2


def test_snap_uses_the_evaluated_target_with_modifiers():
    target, layout = scene()
    target.modifiers.new("Subdivision", "SUBSURF").levels = 1
    reference = Reference(target)
    assert len(reference.triangles) > 2 * len(target.data.polygons)
    before = world_positions(layout)
    bpy.ops.springwrap.snap()
    assert_closest_points(reference, before, world_positions(layout))
    assert_face_points_consistent(layout, reference)
    assert layout.springwrap.target_signature == reference.signature()


# ---------------------------------------------------------------- project


@pytest.mark.parametrize(
    ("direction", "orientation", "both_directions", "height"),
    [
        ("-Z", "GLOBAL", True, 2.4),
        ("-Z", "LOCAL", True, 2.4),
        ("-Z", "GLOBAL", False, 2.4),
        ("X", "GLOBAL", True, 0.9),  # a grid that cuts through the target: hits both ways
        ("-Y", "LOCAL", False, 0.9),
    ],
)
def test_project_along_an_axis_hits_what_ray_cast_hits(direction, orientation, both_directions, height, capfd):
    target, layout = scene()
    layout.location.z = height
    bpy.context.view_layer.update()
    reference = Reference(target)
    before_local = local_positions(layout).copy()
    before = world_positions(layout)
    axis = Vector(AXES[direction])
    if orientation == "LOCAL":
        axis = (layout.matrix_world.to_3x3() @ axis).normalized()
    hits = [reference.ray(point, axis, both_directions) for point in before]
    hit = np.array([location is not None for location, _ in hits])

    bpy.ops.springwrap.project(direction=direction, orientation=orientation, both_directions=both_directions)
    after = world_positions(layout)
    states, _faces, _barycentrics = read_state(layout)
    assert 0 < hit.sum() < len(hit)  # some rays hit, some miss
    expected = np.array([location for location, _ in hits if location is not None])
    np.testing.assert_allclose(after[hit], expected, rtol=0, atol=TOLERANCE)
    assert local_positions(layout)[~hit].tobytes() == before_local[~hit].tobytes()
    assert np.all(states[hit] == 1) and np.all(states[~hit] == 0)
    assert_face_points_consistent(layout, reference)
    assert_reported(capfd, f"Projected {hit.sum()} vertices", f"{(~hit).sum()} missed the target")


def test_project_away_from_the_target_misses_everything():
    target, layout = scene()
    before = snapshot(layout)
    bpy.ops.springwrap.project(direction="Z", both_directions=False)  # the grid is above the target
    after = snapshot(layout)
    assert after["positions"] == before["positions"]
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == SPACE_POINT)


def test_project_max_distance_ignores_far_hits():
    target, layout = scene()
    reference = Reference(target)
    before = world_positions(layout)
    hits = [reference.ray(point, Vector((0, 0, -1)), True) for point in before]
    distances = np.array([abs(distance) if distance is not None else np.inf for _, distance in hits])
    finite = np.sort(distances[np.isfinite(distances)])
    gap = np.argmax(np.diff(finite[5:-5])) + 5
    max_distance = float(finite[gap] + finite[gap + 1]) / 2
    near = distances <= max_distance
    assert 0 < near.sum() < np.isfinite(distances).sum()

    bpy.ops.springwrap.project(direction="-Z", max_distance=max_distance)
    states, _faces, _barycentrics = read_state(layout)
    assert np.array_equal(states == 1, near)
    expected = np.array([hits[index][0] for index in np.flatnonzero(near)])
    np.testing.assert_allclose(world_positions(layout)[near], expected, rtol=0, atol=TOLERANCE)


def test_project_along_normals_hits_what_ray_cast_hits():
    target, layout = scene("inner")
    reference = Reference(target)
    before = world_positions(layout)
    normal_matrix = layout.matrix_world.to_3x3().inverted().transposed()
    normals = [(normal_matrix @ vertex.normal).normalized() for vertex in layout.data.vertices]
    hits = [reference.ray(point, normal, True) for point, normal in zip(before, normals)]
    assert all(location is not None for location, _ in hits)

    bpy.ops.springwrap.project(direction="NORMAL")
    expected = np.array([location for location, _ in hits])
    np.testing.assert_allclose(world_positions(layout), expected, rtol=0, atol=TOLERANCE)
    # The nearer hit is the outward one: every vertex moved outwards, along its normal.
    moved = world_positions(layout) - before
    assert np.all(np.einsum("kx,kx->k", moved, np.array(normals)) > 0)
    assert_face_points_consistent(layout, reference)


def test_project_along_normals_skips_vertices_on_no_face(capfd):
    target = make_target()
    mesh = bpy.data.meshes.new("Layout")
    quad = [(0.1, 0.1, 0.2), (0.5, 0.1, 0.2), (0.5, 0.5, 0.2), (0.1, 0.5, 0.2)]
    chain = [(-0.2, 0.0, 0.0), (-0.3, 0.1, 0.0), (-0.4, 0.2, 0.1)]
    mesh.from_pydata(quad + chain, [(4, 5), (5, 6)], [(0, 1, 2, 3)])
    layout = bpy.data.objects.new("Layout", mesh)
    bpy.context.collection.objects.link(layout)
    layout.rotation_euler = (0.3, 0.0, 0.2)
    layout = as_layout(layout, "Layout", target)
    before_local = local_positions(layout).copy()

    bpy.ops.springwrap.project(direction="NORMAL")
    states, _faces, _barycentrics = read_state(layout)
    assert states.tolist() == [1, 1, 1, 1, 0, 0, 0]
    assert local_positions(layout)[4:].tobytes() == before_local[4:].tobytes()
    assert "3 on no face (no normal) skipped" in capfd.readouterr().out


def test_project_along_view_needs_a_3d_view():
    target, layout = scene()
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="needs a 3D view"):
        bpy.ops.springwrap.project(direction="VIEW")
    assert snapshot(layout) == before


def _view_3d_context(region_type="WINDOW"):
    window = bpy.context.window_manager.windows[0]
    area = next(area for area in window.screen.areas if area.type == "VIEW_3D")
    region = next(region for region in area.regions if region.type == region_type)
    return window, area, region


@pytest.mark.parametrize("region_type", ["WINDOW", "UI"])  # the view itself, or its sidebar
def test_project_along_view_uses_the_view_direction(region_type):
    target, layout = scene()
    reference = Reference(target)
    window, area, region = _view_3d_context(region_type)
    rotation = Quaternion((1.0, 0.0, 0.0), 0.3) @ Quaternion((0.0, 0.0, 1.0), 0.8)
    area.spaces.active.region_3d.view_rotation = rotation
    looking = rotation @ Vector((0.0, 0.0, -1.0))
    before = world_positions(layout)
    hits = [reference.ray(point, looking, True) for point in before]
    hit = np.array([location is not None for location, _ in hits])
    assert hit.sum() > 10

    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.springwrap.project(direction="VIEW")
    expected = np.array([location for location, _ in hits if location is not None])
    np.testing.assert_allclose(world_positions(layout)[hit], expected, rtol=0, atol=TOLERANCE)
    np.testing.assert_array_equal(world_positions(layout)[~hit], before[~hit])


# ---------------------------------------------------------------- detach


def test_detach_makes_space_points_and_keeps_positions(capfd):
    target, layout = scene()
    bpy.ops.springwrap.snap()
    snapped = local_positions(layout).copy()
    count = len(snapped)
    selected = np.arange(count) % 2 == 0
    set_selection(layout, selected)

    bpy.ops.springwrap.detach(only_selected=True)
    states, faces, barycentrics = read_state(layout)
    assert local_positions(layout).tobytes() == snapped.tobytes()
    assert np.all(states[selected] == 0) and np.all(faces[selected] == -1) and not barycentrics[selected].any()
    assert np.all(states[~selected] == 1) and np.all(faces[~selected] >= 0)

    bpy.ops.springwrap.detach()
    states, faces, barycentrics = read_state(layout)
    assert np.all(states == 0) and np.all(faces == -1) and not barycentrics.any()
    assert local_positions(layout).tobytes() == snapped.tobytes()
    assert f"Detached {count} vertices" in capfd.readouterr().out


def test_detach_creates_the_attributes_on_a_fresh_layout():
    target, layout = scene()
    assert read_state(layout) is None
    bpy.ops.springwrap.detach()
    states, faces, barycentrics = read_state(layout)
    for name in STATE_NAMES:
        assert layout.data.attributes[name].domain == "POINT"
    assert layout.data.attributes[STATE_ATTRIBUTE].data_type == "INT"
    assert layout.data.attributes[FACE_ATTRIBUTE].data_type == "INT"
    assert layout.data.attributes[BARYCENTRIC_ATTRIBUTE].data_type == "FLOAT_VECTOR"
    assert np.all(states == 0) and np.all(faces == -1) and not barycentrics.any()


# ---------------------------------------------------------------- deleted target faces (paper 2.1)


def test_deleting_target_faces_detaches_the_face_points_on_them(capfd):
    target, layout = scene()
    bpy.ops.springwrap.snap()
    reference = Reference(target)
    _states, faces_before, _barycentrics = read_state(layout)
    world = world_positions(layout)
    positions_before = local_positions(layout).copy()
    # Delete the target polygons under the layout vertices on one side.
    side = world[:, 0] > np.median(world[:, 0])
    deleted_polygons = np.unique(reference.polygons[faces_before[side]])
    on_deleted = np.isin(reference.polygons[faces_before], deleted_polygons)
    delete_faces(target, deleted_polygons)
    capfd.readouterr()

    # The next operation, whatever it acts on (here: nothing selected), resolves the whole layout.
    set_selection(layout, np.zeros(len(world), dtype=bool))
    bpy.ops.springwrap.snap(only_selected=True)
    current = Reference(target)
    states, faces, _barycentrics = read_state(layout)
    tolerance = REATTACH_TOLERANCE * current.diagonal
    distances = np.array([current.nearest(point)[2] for point in world])
    clear = (distances < 0.5 * tolerance) | (distances > 2 * tolerance)
    expected_face = distances <= tolerance
    assert np.array_equal((states == 1)[clear], expected_face[clear])
    detached = states == 0
    assert detached.sum() > 10 and (~detached).sum() > 10
    assert np.all(on_deleted[detached])  # only the points on deleted faces lost them
    assert local_positions(layout).tobytes() == positions_before.tobytes()
    assert_face_points_consistent(layout, current)  # the survivors' new triangle indices are right
    assert layout.springwrap.target_signature == current.signature() != reference.signature()
    report = (
        f"{detached.sum()} face-points lost their target face and became space-points, {(~detached).sum()} re-attached"
    )
    assert report in capfd.readouterr().out


def test_face_points_stay_attached_when_the_target_only_moves():
    target, layout = scene()
    bpy.ops.springwrap.snap()
    before = snapshot(layout)
    target.data.vertices.foreach_set("co", [coordinate * 1.1 for coordinate in _flat_coordinates(target)])
    target.data.update()  # same topology, other shape
    set_selection(layout, np.zeros(len(layout.data.vertices), dtype=bool))
    bpy.ops.springwrap.detach(only_selected=True)
    assert snapshot(layout) == before  # same triangles and barycentrics: nothing to resolve


def _flat_coordinates(obj):
    coordinates = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", coordinates)
    return coordinates


# ---------------------------------------------------------------- persistence and undo


def test_state_survives_save_and_reload(tmp_path):
    target, layout = scene()
    set_selection(layout, np.arange(len(layout.data.vertices)) % 4 != 0)
    bpy.ops.springwrap.snap(only_selected=True)
    saved = snapshot(layout)
    assert saved["state"] is not None
    path = tmp_path / "springwrap_state.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    assert "Layout" not in bpy.data.objects
    bpy.ops.wm.open_mainfile(filepath=str(path))
    layout = bpy.data.objects["Layout"]
    assert snapshot(layout) == saved
    assert layout.springwrap.target.name == "Target"


def test_undo_restores_positions_and_state():
    target, layout = scene()
    bpy.ops.springwrap.snap()
    bpy.ops.ed.undo_push(message="Before project")
    before = snapshot(layout)
    # The third positional argument asks bpy.ops to push the operator's own undo step.
    bpy.ops.springwrap.project("EXEC_DEFAULT", True, direction="X")
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]  # undo replaced the data blocks: fetch again
    assert snapshot(layout) == before


def test_undo_restores_a_fresh_layout_without_attributes():
    target, layout = scene()
    bpy.ops.ed.undo_push(message="Before snap")
    before = snapshot(layout)
    bpy.ops.springwrap.snap("EXEC_DEFAULT", True)
    assert read_state(bpy.data.objects["Layout"]) is not None
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert snapshot(layout) == before
    assert read_state(layout) is None


# ---------------------------------------------------------------- edit mode


def _select_in_edit_mode(layout, mask):
    editable = bmesh.from_edit_mesh(layout.data)
    for vertex, selected in zip(editable.verts, mask):
        vertex.select_set(bool(selected))
    editable.select_flush_mode()
    bmesh.update_edit_mesh(layout.data)


def test_edit_mode_snap_only_selected():
    target, layout = scene()
    reference = Reference(target)
    before_local = local_positions(layout).copy()
    before = world_positions(layout)
    selected = np.arange(len(before)) % 5 == 1
    bpy.ops.object.mode_set(mode="EDIT")
    _select_in_edit_mode(layout, selected)

    bpy.ops.springwrap.snap(only_selected=True, mode="SURFACE")
    assert layout.mode == "EDIT"
    # The edit-mesh itself has the result (not only the object-mode data).
    editable = bmesh.from_edit_mesh(layout.data)
    edit_positions = np.array([tuple(vertex.co) for vertex in editable.verts], dtype=np.float32)
    state_layer = editable.verts.layers.int[STATE_ATTRIBUTE]
    edit_states = np.array([vertex[state_layer] for vertex in editable.verts])
    assert np.array_equal(edit_states == 1, selected)
    bpy.ops.object.mode_set(mode="OBJECT")

    assert local_positions(layout).tobytes() == edit_positions.tobytes()
    assert local_positions(layout)[~selected].tobytes() == before_local[~selected].tobytes()
    assert_closest_points(reference, before[selected], world_positions(layout)[selected])
    selection = np.empty(len(before), dtype=bool)
    layout.data.vertices.foreach_get("select", selection)
    assert np.array_equal(selection, selected)  # the selection survived


def test_edit_mode_undo_restores_positions():
    target, layout = scene()
    bpy.ops.object.mode_set(mode="EDIT")
    _select_in_edit_mode(layout, np.arange(len(layout.data.vertices)) % 2 == 0)
    bpy.ops.ed.undo_push(message="Before snap")
    bpy.ops.object.mode_set(mode="OBJECT")
    before = snapshot(bpy.data.objects["Layout"])
    bpy.ops.object.mode_set(mode="EDIT")

    bpy.ops.springwrap.snap("EXEC_DEFAULT", True, only_selected=True)
    bpy.ops.object.mode_set(mode="OBJECT")
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.ed.undo()
    assert bpy.context.mode == "EDIT_MESH"
    bpy.ops.object.mode_set(mode="OBJECT")
    after = snapshot(bpy.data.objects["Layout"])
    # Edit-mode undo restores the mesh (positions, attributes), not object properties such as
    # the stored target signature: a known limitation of Blender's edit-mesh undo steps.
    assert {key: value for key, value in after.items() if key != "signature"} == {
        key: value for key, value in before.items() if key != "signature"
    }


def test_edit_mode_error_leaves_the_layout_in_edit_mode_untouched():
    target, layout = scene()
    bpy.ops.springwrap.snap()
    before = snapshot(layout)
    target.data.vertices[3].co.x = math.nan
    target.data.update()
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError, match="Target"):
        bpy.ops.springwrap.snap(only_selected=True)
    assert layout.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    assert snapshot(layout) == before


# ---------------------------------------------------------------- bad input never crashes, never loses work


def _target_is_layout(target, layout):
    layout.springwrap.target = layout  # Python assignment bypasses the picker's poll


def _target_not_a_mesh(target, layout):
    bpy.ops.object.empty_add()
    layout.springwrap.target = bpy.context.active_object
    bpy.context.view_layer.objects.active = layout


BAD_INPUTS = {
    "no target": (no_target, "No target set"),
    "target is the layout": (_target_is_layout, "layout itself"),
    "target is not a mesh": (_target_not_a_mesh, "not a mesh"),
    "empty target mesh": (empty_target, "has no faces"),
    "target without faces": (target_without_faces, "has no faces"),
    "NaN target vertex": (nan_target_vertex, "Target 'Target'"),
    "NaN layout vertex": (nan_layout_vertex, "Layout vertex 7 has a NaN"),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
@pytest.mark.parametrize("operator", ["snap", "project", "detach"])
def test_bad_input_is_reported_and_leaves_the_layout_untouched(case, operator):
    target, layout = scene()
    set_selection(layout, np.arange(len(layout.data.vertices)) % 2 == 0)
    bpy.ops.springwrap.snap(only_selected=True)  # a hybrid layout: face- and space-points
    break_scene, message = BAD_INPUTS[case]
    break_scene(target, layout)
    before = snapshot(layout)
    # Detach needs no target; a NaN layout vertex is refused by every operation on the vertices (the input policy).
    expect_failure = not (operator == "detach" and case == "no target")
    call = getattr(bpy.ops.springwrap, operator)
    if expect_failure:
        with pytest.raises(RuntimeError, match=message):
            call(**({"direction": "-Z"} if operator == "project" else {}))
        assert snapshot(layout) == before
    else:
        # Detach needs no target: it works and moves nothing.
        assert call() == {"FINISHED"}
        assert snapshot(layout)["positions"] == before["positions"]


def test_layout_without_vertices_is_reported():
    target = make_target()
    mesh = bpy.data.meshes.new("Layout")
    layout = bpy.data.objects.new("Layout", mesh)
    bpy.context.collection.objects.link(layout)
    as_layout(layout, "Layout", target)
    with pytest.raises(RuntimeError, match="has no vertices"):
        bpy.ops.springwrap.snap()
    assert len(layout.data.attributes) == 0 or read_state(layout) is None


def test_layout_with_shape_keys_is_refused_where_they_cannot_be_carried_over():
    """Snap carries shape keys over (tests/addon/test_shape_keys.py); Fit Subdivision refuses them, saying why."""
    target, layout = scene()
    layout.shape_key_add(name="Basis")
    before = local_positions(layout).copy()
    with pytest.raises(RuntimeError, match="shape keys; Fit Subdivision and Align Armature evaluate the layout"):
        bpy.ops.springwrap.fit_subdivision()
    assert local_positions(layout).tobytes() == before.tobytes()
    assert bpy.ops.springwrap.detach() == {"FINISHED"}
    assert bpy.ops.springwrap.snap() == {"FINISHED"}


# ---------------------------------------------------------------- panel


def draw_panels(panels, recorder):
    """Draw the panels (classes) into the recorder, as Blender would one after the other."""
    for panel_class in panels:
        assert panel_class.poll(bpy.context)
        panel_class.draw(type("Panel", (), {"layout": recorder})(), bpy.context)


@pytest.mark.parametrize("mode", ["OBJECT", "EDIT"])
def test_panel_buttons_act_on_the_selection_in_edit_mode(mode):
    from springwrap.ui import panels

    target, layout = scene()
    layout.springwrap.snap_mode = "VERTEX"
    layout.springwrap.project_direction = "-Y"
    bpy.ops.object.mode_set(mode=mode)
    recorder = PanelRecorder()
    draw_panels([panels.SPRINGWRAP_PT_snap, panels.SPRINGWRAP_PT_project, panels.SPRINGWRAP_PT_detach], recorder)
    by_name = dict(recorder.operators)
    assert set(by_name) == {"springwrap.detach", "springwrap.snap", "springwrap.project"}
    assert all(button.only_selected == (mode == "EDIT") for button in by_name.values())
    assert by_name["springwrap.snap"].mode == "VERTEX"
    assert by_name["springwrap.project"].direction == "-Y"
    texts = [kwargs.get("text") for _name, kwargs in recorder.texts]
    assert texts == (
        ["Snap Selected", "Project Selected", "Detach Selected"] if mode == "EDIT" else ["Snap", "Project", "Detach"]
    )
    if mode == "OBJECT":
        recorder = PanelRecorder()
        draw_panels([panels.SPRINGWRAP_PT_check], recorder)
        assert recorder.labels == ["On Surface", "0", "In Space", "121"]


def test_panel_counts_face_and_space_points():
    from springwrap.ui.panels import SPRINGWRAP_PT_check

    target, layout = scene()
    set_selection(layout, np.arange(len(layout.data.vertices)) < 40)
    bpy.ops.springwrap.snap(only_selected=True)
    recorder = PanelRecorder()
    draw_panels([SPRINGWRAP_PT_check], recorder)
    assert recorder.labels == ["On Surface", "40", "In Space", "81"]
