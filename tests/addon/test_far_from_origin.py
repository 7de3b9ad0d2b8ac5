"""Precision far from the world origin: the same scene snapped and wrapped at the origin, 1e4 and 1e6 away.

The kernel works in float32; the add-on hands it coordinates relative to the target's (rounded) bounding-box
centre, so a unit sphere 1e6 from the origin is snapped and wrapped exactly as at the origin. Before, the
snap there was off by 0.042 and the wrap by 3.2 % of the object's size.
"""

import bpy

import numpy as np
import pytest

from bpy_helpers import local_positions, world_positions

DISTANCES = (1e4, 1e6)

DIRECTION = np.array([0.6, -0.48, 0.64])  # a unit vector off every axis


def _stored_shift(offset):
    """The layout's offset from the target, (0.05, -0.03, 0.02), as the float32 object locations at ``offset``
    can hold it."""
    location = np.asarray(offset, dtype=np.float32).astype(np.float64)
    return np.asarray(location + [0.05, -0.03, 0.02], dtype=np.float32).astype(np.float64) - location


def _scene(offset, shift):
    """A unit UV sphere at ``offset`` and an ico-sphere layout of radius 1.3 at ``offset + shift``."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.0, location=tuple(offset))
    target = bpy.context.active_object
    target.name = "Target"
    target_location = np.array(target.location, dtype=np.float64)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.3, location=(0.0, 0.0, 0.0))
    layout = bpy.context.active_object
    layout.name = "Layout"
    layout.location = tuple(target_location + shift)
    layout.springwrap.target = target
    bpy.context.view_layer.objects.active = layout
    bpy.context.view_layer.update()
    stored = np.array(layout.location, dtype=np.float64) - target_location
    np.testing.assert_array_equal(stored, shift)  # the same geometry relative to the target
    return target, layout


def _relative_result(offset, shift, operation):
    """The layout's world positions relative to the target's location after ``operation``, and its stored ones."""
    target, layout = _scene(offset, shift)
    operation()
    relative = world_positions(layout) - np.array(target.location, dtype=np.float64)
    return relative, local_positions(layout).copy()


def _snap():
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}


def _wrap():
    assert bpy.ops.springwrap.detach() == {"FINISHED"}
    assert bpy.ops.springwrap.anchors_auto(spacing=0.6) == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=300) == {"FINISHED"}


@pytest.mark.parametrize("distance", DISTANCES)
@pytest.mark.parametrize("operation", [_snap, _wrap], ids=["snap", "wrap"])
def test_an_object_far_from_the_origin_gives_the_result_it_gives_at_the_origin(operation, distance):
    offset = distance * DIRECTION
    shift = _stored_shift(offset)  # the scene at the origin gets the very same relative placement
    far, local_far = _relative_result(offset, shift, operation)
    bpy.ops.wm.read_homefile(use_empty=True)
    at_origin, local_at_origin = _relative_result(np.zeros(3), shift, operation)
    # The layout's stored (local) coordinates hold the result; they are near its object origin, so they agree
    # with the result at the origin to float32 storage wherever the object is (before: 0.042 off at 1e6).
    size = 2.0  # the target's diameter
    local_difference = float(np.abs(local_far.astype(np.float64) - local_at_origin).max())
    assert local_difference <= 1e-6 * size, f"stored coordinates differ by {local_difference:.3g} at {distance:g}"
    np.testing.assert_allclose(far, at_origin, rtol=0, atol=1e-6 * size)


def test_a_layout_whose_mesh_data_is_far_from_its_object_origin_is_reported(capfd):
    """When the layout's own (local) coordinates are far out, float32 cannot store the result precisely:
    the operation finishes and says so; near its object origin it says nothing."""
    target, layout = _scene(np.zeros(3), _stored_shift(np.zeros(3)))
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert "float32" not in capfd.readouterr().out
    bpy.ops.wm.read_homefile(use_empty=True)
    target, layout = _scene(1e6 * DIRECTION, _stored_shift(1e6 * DIRECTION))
    matrix = np.array(layout.matrix_world, dtype=np.float64)
    world = local_positions(layout).astype(np.float64) + matrix[:3, 3]
    layout.location = (0.0, 0.0, 0.0)  # the same vertices, stored 1e6 from the object's origin
    layout.data.vertices.foreach_set("co", world.astype(np.float32).reshape(-1))
    layout.data.update()
    bpy.context.view_layer.update()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    output = capfd.readouterr().out
    assert "float32 keeps them only to 0.062" in output and "Origin to Geometry" in output, output
