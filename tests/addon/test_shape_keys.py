"""Shape keys carried over by the wrap, the mirror, snap and the live wrap, through the operators.

The test the feature is accepted by: a quad sphere layout (radius 1) whose key "Cap" pushes a cap out by 0.1 along the normal,
wrapped onto an ellipsoid twice its size (semi-axes 2.2, 2.0, 1.8: the mean radius of a sphere of radius
2); the transferred key pushes along the ellipsoid's normal by 0.2 within 5 %.
"""

import bpy

import numpy as np
import pytest

from bpy_helpers import activate, make_object
from helpers import cube_sphere_cage, uv_sphere

SEMI_AXES = np.array([2.2, 2.0, 1.8])
CAP_ANGLE = 35.0  # degrees: the cap around the +x and +y axes


def key_positions(layout, name):
    block = layout.data.shape_keys.key_blocks[name]
    values = np.empty(len(block.data) * 3, dtype=np.float32)
    block.data.foreach_get("co", values)
    return values.reshape(-1, 3)


def set_key(layout, name, positions):
    layout.data.shape_keys.key_blocks[name].data.foreach_set(
        "co", np.ascontiguousarray(positions, dtype=np.float32).ravel()
    )
    layout.data.update()


def key_attributes(layout):
    """Everything of the keys but their positions."""
    return [
        (
            block.name,
            round(block.value, 6),
            block.slider_min,
            block.slider_max,
            block.vertex_group,
            block.mute,
            block.interpolation,
            block.relative_key.name,
        )
        for block in layout.data.shape_keys.key_blocks
    ]


def all_keys(layout):
    return {block.name: key_positions(layout, block.name).tobytes() for block in layout.data.shape_keys.key_blocks}


def cap_mask(positions, axis):
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    return normals @ np.asarray(axis, dtype=np.float64) > np.cos(np.radians(CAP_ANGLE))


def sphere_layout_scene(cuts=10):
    """An ellipsoid target (semi-axes SEMI_AXES) and a quad sphere layout of radius 1 inside it with the keys
    Basis, Cap (+x cap out by 0.1), Tilt (the +y cap out by 0.1, slider -1..2, masked by the group 'Mask',
    value 0.3, muted, interpolation KEY_CARDINAL) and Lift (relative to Cap: 0.05 more along +z on its cap)."""
    vertices, triangles = uv_sphere(1.0, rings=48, segments=96)
    target = make_object("Target", vertices.astype(np.float64) * SEMI_AXES, triangles, matrix=np.eye(4).tolist())
    positions, corners, sizes = cube_sphere_cage(cuts)
    faces = corners.astype(np.int64).reshape(-1, 4)  # quads
    layout = make_object("Layout", positions, faces, matrix=np.eye(4).tolist())
    layout.springwrap.target = target
    activate(layout)
    rest = positions.astype(np.float64)
    normals = rest / np.linalg.norm(rest, axis=1, keepdims=True)
    group = layout.vertex_groups.new(name="Mask")
    group.add(list(range(len(positions))), 1.0, "REPLACE")
    layout.shape_key_add(name="Basis")
    cap = layout.shape_key_add(name="Cap", from_mix=False)
    set_key(layout, "Cap", rest + np.where(cap_mask(rest, (1, 0, 0))[:, None], 0.1 * normals, 0.0))
    tilt = layout.shape_key_add(name="Tilt", from_mix=False)
    set_key(layout, "Tilt", rest + np.where(cap_mask(rest, (0, 1, 0))[:, None], 0.1 * normals, 0.0))
    tilt.slider_min, tilt.slider_max, tilt.value = -1.0, 2.0, 0.3
    tilt.vertex_group, tilt.mute, tilt.interpolation = "Mask", True, "KEY_CARDINAL"
    lift = layout.shape_key_add(name="Lift", from_mix=False)
    lift.relative_key = cap
    cap_positions = key_positions(layout, "Cap").astype(np.float64)
    set_key(layout, "Lift", cap_positions + np.where(cap_mask(rest, (1, 0, 0))[:, None], [0.0, 0.0, 0.05], 0.0))
    return target, layout


def ellipsoid_normals(points):
    normals = points / SEMI_AXES**2
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def wrap_onto_ellipsoid(layout, **properties):
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=400, **properties) == {"FINISHED"}


def test_the_wrapped_cap_pushes_along_the_ellipsoid_normal_twice_as_far():
    _target, layout = sphere_layout_scene()
    rest = key_positions(layout, "Basis").astype(np.float64)
    wrap_onto_ellipsoid(layout)
    basis = key_positions(layout, "Basis").astype(np.float64)
    vertices = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", vertices)
    assert vertices.tobytes() == key_positions(layout, "Basis").tobytes()  # the mesh shows the basis
    radii = np.linalg.norm(basis / SEMI_AXES, axis=1)
    assert np.abs(radii - 1.0).max() < 0.01  # the basis is wrapped onto the ellipsoid
    normals = ellipsoid_normals(basis)
    for name, axis in (("Cap", (1, 0, 0)), ("Tilt", (0, 1, 0))):
        cap = cap_mask(rest, axis)
        offsets = key_positions(layout, name).astype(np.float64) - basis
        along = np.einsum("ij,ij->i", offsets, normals)
        across = np.linalg.norm(offsets - along[:, None] * normals, axis=1)
        assert along[cap].mean() == pytest.approx(0.2, rel=0.05)
        assert np.all(np.abs(along[cap] - 0.2) < 0.05 * 0.2 * 2)  # every cap vertex within 10 %
        assert np.all(across[cap] < 0.1 * 0.2)
        assert np.all(offsets[~cap] == 0.0)  # untouched vertices stay exactly on the basis


def test_key_names_order_values_ranges_groups_and_relative_keys_are_kept():
    _target, layout = sphere_layout_scene(cuts=6)
    before = key_attributes(layout)
    rest = key_positions(layout, "Basis").astype(np.float64)
    lift_offsets = key_positions(layout, "Lift").astype(np.float64) - key_positions(layout, "Cap")
    wrap_onto_ellipsoid(layout)
    assert key_attributes(layout) == before
    # Lift is relative to Cap: its offset from Cap is carried (0.05 along z grows to about 0.1), zero stays zero.
    carried = key_positions(layout, "Lift").astype(np.float64) - key_positions(layout, "Cap")
    moved = np.any(lift_offsets != 0.0, axis=1)
    assert np.all(carried[~moved] == 0.0)
    assert np.linalg.norm(carried[moved], axis=1).mean() == pytest.approx(0.1, rel=0.1)
    assert cap_mask(rest, (1, 0, 0)).sum() == moved.sum()


def test_refuse_keeps_the_old_refusal_and_changes_nothing():
    _target, layout = sphere_layout_scene(cuts=4)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    before = all_keys(layout)
    for call in (bpy.ops.springwrap.wrap, bpy.ops.springwrap.mirror):
        with pytest.raises(RuntimeError, match=r"has shape keys; Shape Keys is set to Refuse \(shape_keys='REFUSE'"):
            call(shape_keys="REFUSE", max_iterations=30)
        assert all_keys(layout) == before


def test_undo_puts_every_key_back():
    _target, layout = sphere_layout_scene(cuts=4)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="before")
    before = all_keys(layout)
    assert bpy.ops.springwrap.wrap("EXEC_DEFAULT", True, max_iterations=100) == {"FINISHED"}
    assert all_keys(bpy.data.objects["Layout"]) != before
    bpy.ops.ed.undo()
    assert all_keys(bpy.data.objects["Layout"]) == before


def test_a_failing_wrap_leaves_the_keys_untouched():
    _target, layout = sphere_layout_scene(cuts=4)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    set_key(
        layout,
        "Tilt",
        np.where(np.arange(len(layout.data.vertices))[:, None] == 5, np.nan, key_positions(layout, "Tilt")),
    )
    before = all_keys(layout)
    positions = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", positions)
    with pytest.raises(RuntimeError, match="shape key 'Tilt' has a NaN or infinite coordinate at vertex 5"):
        bpy.ops.springwrap.wrap(max_iterations=30)
    assert all_keys(layout) == before
    after = np.empty_like(positions)
    layout.data.vertices.foreach_get("co", after)
    assert after.tobytes() == positions.tobytes()


def test_the_live_wrap_moves_the_keys_along_and_cancel_puts_them_back_bit_for_bit():
    from bpy_helpers import wrap_session

    _target, layout = sphere_layout_scene(cuts=4)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    before = all_keys(layout)
    session = wrap_session(layout, max_iterations=200)
    session.advance()
    session.advance()
    basis = key_positions(layout, "Basis")
    assert basis.tobytes() != np.frombuffer(before["Basis"], np.float32).tobytes()
    # A frame moves every key with the basis (offsets unchanged), so the viewport shows the keys' mix on it.
    offsets = key_positions(layout, "Cap").astype(np.float64) - basis
    expected = np.frombuffer(before["Cap"], np.float32).reshape(-1, 3) - np.frombuffer(
        before["Basis"], np.float32
    ).reshape(-1, 3)
    np.testing.assert_allclose(offsets, expected, atol=1e-6)
    session.cancel()
    assert all_keys(layout) == before


def test_a_live_wrap_finished_carries_the_keys_from_where_they_were():
    from bpy_helpers import wrap_session

    _target, layout = sphere_layout_scene(cuts=4)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    before = all_keys(layout)
    session = wrap_session(layout, max_iterations=60)
    while not session.done:
        session.advance()
    session.finish()
    live = all_keys(layout)
    # The same wrap at once from the same start gives the same keys: frames left nothing behind.
    for name, values in before.items():
        set_key(layout, name, np.frombuffer(values, np.float32))
    from springwrap.blender import attributes

    attributes.restore_snapshot(layout, session.snapshot)
    layout.data.vertices.foreach_set("co", np.frombuffer(before["Basis"], np.float32))
    synchronous = wrap_session(layout, max_iterations=60)
    synchronous.run()
    synchronous.finish()
    assert all_keys(layout) == live


def test_snap_carries_the_keys_and_fit_subdivision_refuses_saying_why():
    _target, layout = sphere_layout_scene(cuts=4)
    rest = key_positions(layout, "Basis").astype(np.float64)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    basis = key_positions(layout, "Basis").astype(np.float64)
    assert np.abs(np.linalg.norm(basis / SEMI_AXES, axis=1) - 1.0).max() < 0.01
    cap = cap_mask(rest, (1, 0, 0))
    offsets = key_positions(layout, "Cap").astype(np.float64) - basis
    assert np.all(np.einsum("ij,ij->i", offsets, ellipsoid_normals(basis))[cap] > 0.15)
    before = all_keys(layout)
    with pytest.raises(RuntimeError, match="evaluate the layout through a Blender modifier"):
        bpy.ops.springwrap.fit_subdivision(rounds=1)
    assert all_keys(layout) == before


def test_the_mirror_mirrors_each_key_onto_the_new_half():
    """A half sphere (x >= 0) whose key pushes a cap around +x+y out: after the mirror the new half's key pushes
    the mirrored cap (around -x+y) out by as much."""
    vertices, triangles = uv_sphere(1.0, rings=48, segments=96)
    target = make_object("Target", vertices.astype(np.float64) * 2.0, triangles, matrix=np.eye(4).tolist())
    positions, corners, sizes = cube_sphere_cage(8)
    positions = positions.astype(np.float64) * 2.0
    faces = corners.astype(np.int64).reshape(-1, 4)  # quads
    keep = [face for face in faces if positions[face, 0].min() >= -1e-6]
    used = np.unique(np.concatenate(keep))
    index = -np.ones(len(positions), dtype=np.int64)
    index[used] = np.arange(used.size)
    half = positions[used]
    layout = make_object("Layout", half, [index[face] for face in keep], matrix=np.eye(4).tolist())
    layout.springwrap.target = target
    activate(layout)
    normals = half / np.linalg.norm(half, axis=1, keepdims=True)
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    cap = normals @ axis > np.cos(np.radians(30.0))
    layout.shape_key_add(name="Basis")
    layout.shape_key_add(name="Cap", from_mix=False)
    set_key(layout, "Cap", half + np.where(cap[:, None], 0.1 * normals, 0.0))
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=200) == {"FINISHED"}
    basis = key_positions(layout, "Basis").astype(np.float64)
    offsets = key_positions(layout, "Cap").astype(np.float64) - basis
    assert len(basis) > len(half)
    sides = basis[:, 0]
    pushed = np.linalg.norm(offsets, axis=1) > 0.05
    mirrored_axis = np.array([-1.0, 1.0, 0.0]) / np.sqrt(2.0)
    on_new_half = pushed & (sides < -1e-3)
    assert on_new_half.sum() == cap.sum()
    directions = basis[on_new_half] / np.linalg.norm(basis[on_new_half], axis=1, keepdims=True)
    assert np.all(directions @ mirrored_axis > np.cos(np.radians(35.0)))
    along = np.einsum("ij,ij->i", offsets[on_new_half], directions)
    assert np.all(np.abs(along - 0.1) < 0.01)
    assert np.all(offsets[~pushed] == 0.0)


@pytest.mark.parametrize("operator", ["wrap", "mirror"])
def test_a_failure_after_the_keys_were_written_puts_them_back(operator, monkeypatch):
    """An injected failure once the keys are written (the wrap's final anchor write; the mirror's anchor write
    after it copied and reflected the keys): every key, the vertex count and the vertices are as they were."""
    from springwrap.blender import anchors as anchor_data

    _target, layout = sphere_layout_scene(cuts=4)
    if operator == "mirror":  # the mirror takes a half (a layout on both sides of its plane is refused)
        import bmesh

        mesh = bmesh.new()
        mesh.from_mesh(layout.data)
        bmesh.ops.delete(mesh, geom=[vertex for vertex in mesh.verts if vertex.co.x < -1e-6], context="VERTS")
        mesh.to_mesh(layout.data)
        mesh.free()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.8) == {"FINISHED"}
    before = all_keys(layout)
    count = len(layout.data.vertices)
    real_write_anchors = anchor_data.write_anchors
    calls = []

    def failing_write_anchors(*args, **kwargs):
        calls.append(args)
        if len(calls) == 1:
            mesh = args[0].data
            assert len(mesh.vertices) > count or all_keys(args[0]) != before  # the keys were written by then
            raise RuntimeError("injected failure")
        return real_write_anchors(*args, **kwargs)

    monkeypatch.setattr(anchor_data, "write_anchors", failing_write_anchors)
    with pytest.raises(RuntimeError, match="injected failure"):
        getattr(bpy.ops.springwrap, operator)(max_iterations=50)
    assert len(calls) == 2  # the failing write, then the restore
    assert len(layout.data.vertices) == count
    assert all_keys(layout) == before


def test_the_panel_shows_shape_keys_only_with_keys_and_its_buttons_pass_it():
    from bpy_helpers import PanelRecorder
    from springwrap.ui import panels

    class Recorder(PanelRecorder):
        def prop_search(self, data, name, *args, **kwargs):
            self.props.append(name)

    def draw(panel_class):
        recorder = Recorder()
        panel_class.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
        return recorder

    vertices, triangles = uv_sphere(1.0, rings=8, segments=16)
    target = make_object("Target", vertices * 2.0, triangles, matrix=np.eye(4).tolist())
    layout = make_object("Layout", vertices, triangles, matrix=np.eye(4).tolist())
    layout.springwrap.target = target
    activate(layout)
    assert "shape_keys" not in draw(panels.SPRINGWRAP_PT_wrap).props
    layout.shape_key_add(name="Basis")
    layout.springwrap.shape_keys = "REFUSE"
    wrap_panel = draw(panels.SPRINGWRAP_PT_wrap)
    assert "shape_keys" in wrap_panel.props
    buttons = dict(wrap_panel.operators) | dict(draw(panels.SPRINGWRAP_PT_mirror).operators)
    assert buttons["springwrap.wrap"].shape_keys == "REFUSE"
    assert buttons["springwrap.mirror"].shape_keys == "REFUSE"
    with pytest.raises(RuntimeError, match="Shape Keys is set to Refuse"):
        bpy.ops.springwrap.wrap(shape_keys=buttons["springwrap.wrap"].shape_keys)


def test_a_baked_alignment_turns_and_scales_the_keys_with_the_layout():
    """Align with Bake moves every vertex by one similarity: each key's offsets are turned and scaled by it."""
    from mathutils import Euler

    _target, layout = sphere_layout_scene(cuts=6)
    layout.matrix_world = (Euler((0.3, -0.2, 0.5)).to_matrix().to_4x4() * 0.8).to_4x4()
    layout.location = (0.3, -0.2, 0.1)
    bpy.context.view_layer.update()
    rest = key_positions(layout, "Basis").astype(np.float64)
    offsets = key_positions(layout, "Cap").astype(np.float64) - rest
    assert bpy.ops.springwrap.align(method="SIMILARITY", use_anchors=False, apply="BAKE") == {"FINISHED"}
    basis = key_positions(layout, "Basis").astype(np.float64)
    assert np.abs(basis - rest).max() > 0.1  # it did move the vertices
    # The similarity the alignment applied, from the basis before and after (local coordinates).
    homogeneous = np.c_[rest, np.ones(len(rest))]
    linear = np.linalg.lstsq(homogeneous, basis, rcond=None)[0][:3].T
    carried = key_positions(layout, "Cap").astype(np.float64) - basis
    np.testing.assert_allclose(carried, offsets @ linear.T, atol=1e-5)
    assert np.all(carried[np.all(offsets == 0.0, axis=1)] == 0.0)
