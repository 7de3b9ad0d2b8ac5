"""``springwrap.fit_subdivision``: the layout as a subdivision cage whose Subdivision Surface is fitted onto the
target. Distances are measured on Blender's own modifier output with ``mathutils`` trees, not the kernel."""

import math

import bpy

import bmesh
import numpy as np
import pytest
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree
from mathutils.kdtree import KDTree

import springwrap_kernel
from bpy_helpers import local_positions, make_object, read_state, snapshot, world_positions

LAYOUT_MATRIX = Matrix.LocRotScale(Vector((0.3, -0.2, 0.1)), Matrix.Rotation(0.4, 3, "Z"), Vector((1.5, 1.5, 1.5)))


def sphere_target(radius=1.0, hole=False, centre=(0.0, 0.0, 0.0)):
    """A fine UV sphere about ``centre`` (world); ``hole``: without the cap above z = 0.8 radius."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64, radius=radius, location=centre)
    target = bpy.context.active_object
    target.name = "Target"
    if hole:
        editable = bmesh.new()
        editable.from_mesh(target.data)
        doomed = [face for face in editable.faces if face.calc_center_median().z > 0.8 * radius]
        bmesh.ops.delete(editable, geom=doomed, context="FACES")
        editable.to_mesh(target.data)
        editable.free()
    return target


def cube_sphere_cage(target, cuts=2, radius=1.0, matrix=LAYOUT_MATRIX, centre=(0.0, 0.0, 0.0)):
    """A subdivided cube whose vertices lie on the sphere of ``radius`` (world), as the layout placed by ``matrix``
    (its mesh holds the inverse-transformed points): a cage whose subdivided surface shrinks inside the sphere."""
    bpy.ops.mesh.primitive_cube_add(size=2)
    cube = bpy.context.active_object
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.subdivide(number_cuts=cuts)
    bpy.ops.object.mode_set(mode="OBJECT")
    points = local_positions(cube).astype(np.float64)
    points *= radius / np.linalg.norm(points, axis=1)[:, None]
    points += np.array(centre)
    inverse = np.array(matrix.inverted())
    local = points @ inverse[:3, :3].T + inverse[:3, 3]
    cube.data.vertices.foreach_set("co", local.astype(np.float32).reshape(-1))
    cube.data.update()
    cube.matrix_world = matrix
    cube.name = "Layout"
    cube.springwrap.target = target
    bpy.context.view_layer.objects.active = cube
    return cube


def subdivided_world_points(obj, levels=2, boundary="ALL"):
    """Blender's Subdivision Surface of ``obj`` at ``levels`` (a modifier added, evaluated and removed), world."""
    modifier = obj.modifiers.new("Check", "SUBSURF")
    modifier.levels = levels
    modifier.boundary_smooth = boundary
    try:
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        points = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", points)
        evaluated.to_mesh_clear()
    finally:
        obj.modifiers.remove(modifier)
    matrix = np.array(obj.matrix_world)
    return points.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def distances_to(target, points):
    """Distances of world points to the target's evaluated surface, by a ``mathutils`` BVH tree."""
    tree = BVHTree.FromObject(target, bpy.context.evaluated_depsgraph_get())
    inverse = target.matrix_world.inverted()
    return np.array(
        [(Vector(p) - target.matrix_world @ tree.find_nearest(inverse @ Vector(p))[0]).length for p in points]
    )


def cage_arrays(obj):
    mesh = obj.data
    sizes = np.empty(len(mesh.polygons), dtype=np.uint32)
    mesh.polygons.foreach_get("loop_total", sizes)
    corners = np.empty(len(mesh.loops), dtype=np.uint32)
    mesh.loops.foreach_get("vertex_index", corners)
    return np.ascontiguousarray(local_positions(obj)), corners, sizes


@pytest.mark.parametrize("centre", [(0.0, 0.0, 0.0), (40.0, -25.0, 12.5)], ids=["at-origin", "far-away"])
def test_the_subdivided_surface_of_a_sphere_cage_comes_onto_the_sphere(centre):
    """The cage fit's acceptance test: the level-2 surface's max distance to the sphere falls at least 5 times."""
    target = sphere_target(centre=centre)
    layout = cube_sphere_cage(target, matrix=Matrix.Translation(centre) @ LAYOUT_MATRIX, centre=centre)
    before = distances_to(target, subdivided_world_points(layout))
    assert bpy.ops.springwrap.fit_subdivision(levels=2) == {"FINISHED"}
    after = distances_to(target, subdivided_world_points(layout))
    assert before.max() > 0.05
    assert after.max() * 5.0 <= before.max(), (before.max(), after.max())
    assert after.mean() * 10.0 <= before.mean(), (before.mean(), after.mean())
    # The operator's own numbers are those of Blender's surface.
    outcome = bpy.types.SPRINGWRAP_OT_fit_subdivision.last_outcome
    assert outcome.exact
    assert outcome.before.max == pytest.approx(before.max(), rel=2e-2)
    assert outcome.after.max == pytest.approx(after.max(), rel=5e-2, abs=1e-4)
    # The cage moved out past the sphere; every moved vertex is a space-point now.
    assert np.linalg.norm(world_positions(layout) - np.array(centre), axis=1).min() > 1.0
    states, faces, _ = read_state(layout)
    assert (states == 0).all() and (faces == -1).all()
    # Nothing temporary is left behind.
    assert sorted(obj.name for obj in bpy.data.objects) == ["Layout", "Target"]
    assert len(bpy.data.meshes) == 2


def test_a_cage_over_a_hole_follows_its_neighbours_across_it():
    target = sphere_target(hole=True)
    layout = cube_sphere_cage(target)
    assert bpy.ops.springwrap.fit_subdivision(levels=2) == {"FINISHED"}
    points = world_positions(layout)
    radii = np.linalg.norm(points, axis=1)
    top = points[:, 2] > 0.9
    assert top.any() and (radii[top] > 1.0).all()
    # Over the hole the cage grew about as much as around it, not pulled in to the rim.
    assert abs(radii[top].mean() - radii[np.abs(points[:, 2]) < 0.5].mean()) < 0.03


def test_a_curve_on_the_cage_and_a_loose_vertex_stay_and_blenders_surface_is_still_fitted():
    """A loose edge from a face vertex (a curve) makes that vertex non-manifold for OpenSubdiv, so Blender's
    surface differs from the stencils' around it: the points still pair up, and the fit uses Blender's."""
    target = sphere_target()
    layout = cube_sphere_cage(target)
    editable = bmesh.new()
    editable.from_mesh(layout.data)
    editable.verts.ensure_lookup_table()
    first = editable.verts[0]
    tip = editable.verts.new(first.co * 1.3)
    editable.edges.new((first, tip))
    editable.verts.new((3.0, 3.0, 3.0))
    editable.to_mesh(layout.data)
    editable.free()
    start = local_positions(layout).copy()
    assert bpy.ops.springwrap.fit_subdivision() == {"FINISHED"}
    end = local_positions(layout)
    assert end[-2:].tobytes() == start[-2:].tobytes()
    outcome = bpy.types.SPRINGWRAP_OT_fit_subdivision.last_outcome
    assert outcome.exact
    assert outcome.fine_vertex_count == 866  # 56 quads subdivided twice: the loose vertices are not surface
    # The outcome's distances are Blender's surface points' (the curve's own points and the loose vertex aside).
    assert outcome.after.max * 5.0 < outcome.before.max
    after = distances_to(target, subdivided_world_points(layout))
    assert np.count_nonzero(after < outcome.after.max + 1e-6) >= 866


def test_unselected_vertices_are_held_and_anchors_hold_the_surface_on_their_points():
    target = sphere_target()
    layout = cube_sphere_cage(target)
    start = local_positions(layout).copy()
    selection = np.arange(len(start)) % 3 != 0
    selection[[1, 7]] = True
    layout.data.vertices.foreach_set("select", selection)
    # Anchors at the target's closest point to their vertex (on the sphere: the vertex itself), one moved aside.
    for vertex in (1, 7):
        assert bpy.ops.springwrap.anchor_add(vertex_index=vertex) == {"FINISHED"}
    anchor_points = np.array([anchor.location[:] for anchor in layout.springwrap.anchors])
    assert bpy.ops.springwrap.fit_subdivision(only_selected=True) == {"FINISHED"}
    end = local_positions(layout)
    assert end[~selection].tobytes() == start[~selection].tobytes()
    assert (np.linalg.norm(end[selection] - start[selection], axis=1) > 1e-4).all()
    states, _, _ = read_state(layout)
    assert (states[selection] == 0).all()
    # Blender numbers the cage's vertices first: their points of the subdivided surface are on the anchors.
    surface = subdivided_world_points(layout)
    assert np.linalg.norm(surface[[1, 7]] - anchor_points, axis=1).max() < 2e-3
    assert bpy.types.SPRINGWRAP_OT_fit_subdivision.last_outcome.anchors == 2


@pytest.mark.parametrize(
    ("name", "faces", "boundary"),
    [
        ("grid", "grid", "ALL"),
        ("grid", "grid", "PRESERVE_CORNERS"),
        ("cube", "cube", "ALL"),
        ("sphere with triangles", "uv_sphere", "ALL"),
        ("hexagon", "ngon", "PRESERVE_CORNERS"),
        ("hexagon", "ngon", "ALL"),
    ],
)
def test_the_stencils_are_blenders_subdivision_surface(name, faces, boundary):
    """Blender's Subdivision Surface points (limit surface on, the default) against the kernel's stencils, as
    point sets; the cage's vertices come first in both. Exact to float precision except at smooth corners of a
    border (a border vertex of one face under "All"), where Blender's patches approximate the limit surface."""
    builders = {
        "grid": lambda: bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3, size=2),
        "cube": lambda: bpy.ops.mesh.primitive_cube_add(size=2),
        "uv_sphere": lambda: bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=5),
        "ngon": lambda: bpy.ops.mesh.primitive_circle_add(vertices=6, fill_type="NGON"),
    }
    builders[faces]()
    obj = bpy.context.active_object
    points, corners, sizes = cage_arrays(obj)
    # Jitter the cage so that nothing is exact by symmetry.
    points = points + np.random.default_rng(7).normal(scale=0.05, size=points.shape).astype(np.float32)
    obj.data.vertices.foreach_set("co", points.reshape(-1))
    obj.data.update()
    smooth_corners = 0
    if boundary == "ALL":
        edge_faces = {}
        for polygon in obj.data.polygons:
            for key in polygon.edge_keys:
                edge_faces[key] = edge_faces.get(key, 0) + 1
        face_count = np.bincount(corners, minlength=len(points))
        on_border = np.zeros(len(points), dtype=bool)
        on_border[[v for key, count in edge_faces.items() if count == 1 for v in key]] = True
        smooth_corners = int(np.count_nonzero(on_border & (face_count == 1)))
    for levels in (1, 2, 3):
        stencils = springwrap_kernel.SubdivisionStencils(len(points), corners, sizes, levels, boundary=boundary)
        mine = stencils.apply(points).astype(np.float64)
        theirs = subdivided_world_points(obj, levels, boundary)
        assert theirs.shape == mine.shape
        tree = KDTree(len(mine))
        for index, point in enumerate(mine):
            tree.insert(point, index)
        tree.balance()
        found = [tree.find(point) for point in theirs]
        gaps = np.array([distance for _, _, distance in found])
        assert len({index for _, index, _ in found}) == len(mine), "one to one"
        exact = gaps < 1e-5
        assert np.count_nonzero(~exact) <= smooth_corners, (name, levels, np.sort(gaps)[-5:])
        assert gaps.max() < 0.01
        first = np.abs(theirs[: len(points)] - mine[: len(points)]).max(axis=1)
        assert np.count_nonzero(first > 1e-5) <= smooth_corners


def non_manifold_layout(target):
    """Three quads on one edge."""
    vertices = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (1, -1, 0), (0, -1, 0), (1, 0, 1), (0, 0, 1)]
    faces = [(0, 1, 2, 3), (1, 0, 5, 4), (0, 1, 6, 7)]
    return make_object("Layout", vertices, faces, matrix=Matrix.Identity(4))


def edges_only_layout(target):
    return make_object("Layout", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [], matrix=Matrix.Identity(4))


def _add_edges(obj):
    obj.data.edges.add(2)
    obj.data.edges.foreach_set("vertices", np.array([0, 1, 1, 2], dtype=np.int32))
    obj.data.update()
    return obj


def creased_layout(target):
    layout = cube_sphere_cage(target)
    if bpy.app.version >= (4, 0, 0):
        attribute = layout.data.attributes.new("crease_edge", "FLOAT", "EDGE")
        values = np.zeros(len(layout.data.edges), dtype=np.float32)
        values[3] = 1.0
        attribute.data.foreach_set("value", values)
    else:
        layout.data.edges[3].crease = 1.0
    return layout


def shape_key_layout(target):
    layout = cube_sphere_cage(target)
    layout.shape_key_add(name="Basis")
    return layout


def nan_layout(target):
    layout = cube_sphere_cage(target)
    layout.data.vertices[4].co.x = math.nan
    return layout


@pytest.mark.parametrize(
    ("make_layout", "message"),
    [
        (non_manifold_layout, "three or more faces"),
        (lambda target: _add_edges(edges_only_layout(target)), "no faces"),
        (creased_layout, "creased edges"),
        (shape_key_layout, "shape keys"),
        (nan_layout, "NaN"),
    ],
)
def test_bad_cages_are_refused_and_left_as_they_were(make_layout, message):
    target = sphere_target()
    layout = make_layout(target)
    layout.name = "Layout"
    layout.springwrap.target = target
    bpy.context.view_layer.objects.active = layout
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.fit_subdivision()
    assert snapshot(layout) == before
    assert sorted(obj.name for obj in bpy.data.objects) == ["Layout", "Target"]


def test_without_a_target_the_fit_cannot_run():
    target = sphere_target()
    layout = cube_sphere_cage(target)
    layout.springwrap.target = None
    assert not bpy.ops.springwrap.fit_subdivision.poll()
    with pytest.raises(RuntimeError, match="No target"):
        bpy.ops.springwrap.fit_subdivision()


def test_the_operator_is_one_undo_step_and_works_from_edit_mode():
    target = sphere_target()
    layout = cube_sphere_cage(target)
    operator = bpy.types.SPRINGWRAP_OT_fit_subdivision
    assert operator.bl_options == {"REGISTER", "UNDO"} and bpy.ops.springwrap.fit_subdivision.get_rna_type().description
    bpy.ops.ed.undo_push(message="Before the fit")
    before = snapshot(layout)
    bpy.ops.object.mode_set(mode="EDIT")
    # The third positional argument asks bpy.ops to push the operator's own undo step.
    assert bpy.ops.springwrap.fit_subdivision("EXEC_DEFAULT", True) == {"FINISHED"}
    assert bpy.context.object.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.ed.undo()
    bpy.ops.object.mode_set(mode="OBJECT")
    assert snapshot(bpy.data.objects["Layout"]) == before


@pytest.mark.parametrize("levels", [0, 7, 99])
def test_a_level_out_of_range_from_a_script_is_refused_naming_the_range(levels):
    target = sphere_target()
    layout = cube_sphere_cage(target)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match=f"Levels must be 1 to 6, not {levels}"):
        bpy.ops.springwrap.fit_subdivision(levels=levels)
    assert snapshot(layout) == before


def test_a_fit_that_will_not_fit_in_memory_is_refused_saying_which_level_would(monkeypatch):
    from springwrap.core import cage_fit

    target = sphere_target()
    layout = cube_sphere_cage(target)  # 54 quads: level 4 has 13,824 points (26 MB a round), level 3 3,456 (6.6 MB)
    monkeypatch.setattr(cage_fit, "available_memory", lambda: 10_000_000)
    before = snapshot(layout)
    with pytest.raises(
        RuntimeError, match=r"Level 4 of this cage has 13,824 subdivided points: .* level 3 \(3,456 points"
    ):
        bpy.ops.springwrap.fit_subdivision(levels=4)
    assert snapshot(layout) == before
    assert sorted(obj.name for obj in bpy.data.objects) == ["Layout", "Target"]
    assert bpy.ops.springwrap.fit_subdivision(levels=3) == {"FINISHED"}


def cube_fit_scene(rounds: int):
    """The cube-sphere cage over the sphere: (layout, its snapshot, level-2 fit parameters, the fit's target)."""
    from springwrap.blender import cage_fit as cage_fit_data
    from springwrap.blender import target as target_data

    layout = cube_sphere_cage(sphere_target())
    parameters = cage_fit_data.CageFitParameters(levels=2, rounds=rounds)
    return layout, snapshot(layout), parameters, target_data.read_target(bpy.context.evaluated_depsgraph_get(), layout)


def test_a_fit_stopped_between_rounds_leaves_the_layout_as_it_was_and_reports_its_progress():
    """What Esc does to the modal fit: the session's rounds run one by one, its cancel writes nothing."""
    from springwrap.blender import cage_fit as cage_fit_data

    layout, before, parameters, fit_target = cube_fit_scene(rounds=3)
    session = cage_fit_data.CageFitSession(bpy.context, layout, fit_target, parameters).start()
    assert "round 1 of 3, level 2" in session.status_text() and "Esc" in session.status_text()
    session.step()
    assert "round 2 of 3" in session.status_text() and not session.done
    session.cancel()
    assert snapshot(layout) == before
    assert sorted(obj.name for obj in bpy.data.objects) == ["Layout", "Target"]
    assert bpy.ops.springwrap.fit_subdivision("INVOKE_DEFAULT", levels=2) == {"FINISHED"}  # headless: at once
    assert snapshot(layout) != before


def test_a_round_asked_to_stop_raises_cancelled_and_an_unset_flag_changes_nothing():
    """The kernel's round asks its cancellation flag inside its loops: set, it raises; unset, the round is the
    plain round."""
    from springwrap.blender import cage_fit as cage_fit_data

    sk = springwrap_kernel
    layout, _before, parameters, fit_target = cube_fit_scene(rounds=2)
    session = cage_fit_data.CageFitSession(bpy.context, layout, fit_target, parameters).start()
    try:
        run = session.run
        plain = run.solve()
        unset = run.solve(sk.CancelFlag())
        np.testing.assert_array_equal(plain[0], unset[0])
        flag = sk.CancelFlag()
        flag.cancel()
        assert flag.cancelled
        with pytest.raises(sk.CancelledError, match="subdivision fit round cancelled"):
            run.solve(flag)
        assert issubclass(sk.CancelledError, sk.SpringwrapError)
    finally:
        session.cancel()


def test_the_modal_fit_runs_its_rounds_in_a_worker_and_a_stop_inside_a_round_leaves_the_layout_as_it_was():
    """The modal operator's tick: each round's kernel part in a worker thread (the same rounds as one by one);
    cancel while a round runs stops it through its flag, removes the temporary object, writes nothing."""
    from springwrap.blender import cage_fit as cage_fit_data

    layout, before, parameters, fit_target = cube_fit_scene(rounds=2)

    stepped = cage_fit_data.CageFitSession(bpy.context, layout, fit_target, parameters).start()
    while not stepped.done:
        stepped.step()
    stepped_positions = stepped.run.outcome().positions
    stepped.cancel()

    ticked = cage_fit_data.CageFitSession(bpy.context, layout, fit_target, parameters).start()
    ticks = 0
    while not ticked.done:
        ticked.tick()
        ticks += 1
        if ticked._worker is not None:
            ticked._worker.outcome()  # wait for the worker (the modal's timer would come back later)
    np.testing.assert_array_equal(ticked.run.outcome().positions, stepped_positions)
    assert ticks == 2 * parameters.rounds
    ticked.cancel()

    stopped = cage_fit_data.CageFitSession(bpy.context, layout, fit_target, parameters).start()
    stopped.tick()  # a round starts in the worker
    worker = stopped._worker
    assert worker is not None
    stopped.cancel()  # Esc: the flag set, the worker joined
    assert worker.cancel_flag.cancelled and not worker.running and stopped._worker is None
    assert stopped.run.round == 0
    assert snapshot(layout) == before
    assert sorted(obj.name for obj in bpy.data.objects) == ["Layout", "Target"]
