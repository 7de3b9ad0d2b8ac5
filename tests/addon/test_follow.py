"""Follow: a layout set to follow its target re-settles by itself when the target changes (an edit, a modifier, a
frame change), only where the change concerns it: vertices far from the change do not move at all."""

import bpy

import numpy as np

from bpy_helpers import (
    Reference,
    addon_module,
    animated_target,
    local_positions,
    make_sphere_layout,
    surface_distances,
    world_positions,
)

ON_SURFACE = 1e-4


def wrapped_scene(target=None):
    target = target or animated_target()
    bpy.context.scene.frame_set(1)
    layout = make_sphere_layout(target)
    assert bpy.ops.springwrap.wrap("EXEC_DEFAULT", True) == {"FINISHED"}
    return target, layout


def settle():
    """What the timer does in the window: the depsgraph's handlers note the change, then the layout re-settles."""
    bpy.context.view_layer.update()
    return addon_module("blender.follow").settle_pending(bpy.context)


def push_cap(target, height=1.2, amount=0.25):
    """Move the target's vertices above ``height`` (in z) outward along z: a local edit."""
    mesh = target.data
    points = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", points)
    points = points.reshape(-1, 3)
    points[points[:, 2] > height, 2] += amount
    mesh.vertices.foreach_set("co", points.reshape(-1))
    if mesh.shape_keys is not None:
        for block in mesh.shape_keys.key_blocks:
            block.data.foreach_set("co", points.reshape(-1))
    mesh.update()


def plain_target():
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=1.5)
    target = bpy.context.active_object
    target.name = "Target"
    return target


def test_follow_is_off_by_default_and_then_nothing_moves():
    target, layout = wrapped_scene(plain_target())
    assert not layout.springwrap.follow
    before = local_positions(layout).copy()
    push_cap(target)
    assert settle() == 0
    assert np.array_equal(local_positions(layout), before)


def test_an_edit_re_settles_the_layout_there_and_nowhere_else():
    target, layout = wrapped_scene(plain_target())
    layout.springwrap.follow = True
    addon_module("blender.follow").follow_changed(layout.springwrap, bpy.context)  # the update (bpy 4.2 has none)
    before = world_positions(layout)
    push_cap(target)
    assert settle() == 1
    after = world_positions(layout)
    moved = np.linalg.norm(after - before, axis=1)
    far = before[:, 2] < 0.6  # well below the edited cap (and the rings grown around it)
    assert far.sum() > 50
    assert moved[far].max() < 1e-6
    near = before[:, 2] > 1.25
    assert moved[near].min() > 0.1  # the cap's vertices followed it out
    assert surface_distances(Reference(target), after).max() < ON_SURFACE * 3.0
    assert settle() == 0  # nothing changed since: nothing written


def test_a_modifier_is_followed():
    target, layout = wrapped_scene(plain_target())
    layout.springwrap.follow = True
    addon_module("blender.follow").follow_changed(layout.springwrap, bpy.context)
    modifier = target.modifiers.new("Bend", "SIMPLE_DEFORM")
    modifier.deform_method = "TAPER"
    modifier.factor = 0.3
    assert settle() == 1
    assert surface_distances(Reference(target), world_positions(layout)).max() < ON_SURFACE * 3.0


def test_a_frame_change_is_followed():
    target, layout = wrapped_scene()
    layout.springwrap.follow = True
    addon_module("blender.follow").follow_changed(layout.springwrap, bpy.context)
    bpy.context.scene.frame_set(3)
    assert settle() == 1
    assert surface_distances(Reference(target), world_positions(layout)).max() < ON_SURFACE * 5.0


def test_no_re_settle_while_paused():
    target, layout = wrapped_scene(plain_target())
    layout.springwrap.follow = True
    follow = addon_module("blender.follow")
    follow.follow_changed(layout.springwrap, bpy.context)
    before = local_positions(layout).copy()
    with follow.paused():
        push_cap(target)
        assert settle() == 0
    assert np.array_equal(local_positions(layout), before)


def test_the_panel_shows_follow_on_and_passes_its_settings_to_wrap_sequence():
    from bpy_helpers import PanelRecorder
    from springwrap.ui import follow_indicator, panels

    _target, layout = wrapped_scene(plain_target())
    recorder = PanelRecorder()
    panels.SPRINGWRAP_PT_over_time.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert "follow" in recorder.props and recorder.prop_options["follow"]["icon"] == "UNLINKED"
    ((idname, button),) = [entry for entry in recorder.operators if entry[0] == "springwrap.wrap_sequence"]
    assert button.source == "TARGET" and button.schedule == layout.springwrap.wrap_schedule
    layout.springwrap.follow = True
    recorder = PanelRecorder()
    panels.SPRINGWRAP_PT_over_time.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.prop_options["follow"]["icon"] == "LINKED" and recorder.labels  # visibly on
    header = PanelRecorder()
    follow_indicator.draw_header(type("Header", (), {"layout": header})(), bpy.context)
    assert header.props == ["follow"]  # the 3D view's header shows it too
    layout.springwrap.follow = False
    header = PanelRecorder()
    follow_indicator.draw_header(type("Header", (), {"layout": header})(), bpy.context)
    assert header.props == []
