"""The template's rest shape: stored at the layout's first change, kept by the wrap's springs, set anew on request."""

import bpy

import numpy as np
import pytest

from bpy_helpers import local_positions, plane_scene, snapshot, wrap_with_anchors

REST = "springwrap_rest"


def read_rest(layout):
    attribute = layout.data.attributes.get(REST)
    if attribute is None:
        return None
    values = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    attribute.data.foreach_get("vector", values)
    return values.reshape(-1, 3)


def test_the_first_change_stores_the_template_and_later_ones_keep_it():
    _target, layout, _normal = plane_scene()
    template = local_positions(layout).copy()
    assert read_rest(layout) is None
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}
    assert not np.array_equal(local_positions(layout), template)
    np.testing.assert_array_equal(read_rest(layout), template)
    assert bpy.ops.springwrap.detach() == {"FINISHED"}
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    np.testing.assert_array_equal(read_rest(layout), template)


def test_a_wrap_keeps_the_templates_spacing_from_the_stored_rest():
    """A layout half squeezed after its first snap: the spring wrap evens it back to the template's spacing
    (the energy wrap lets each region keep a scale of its own, as a morph needs)."""
    _target, layout, _normal = plane_scene()
    template = local_positions(layout).astype(np.float64)
    bpy.ops.springwrap.snap(mode="SURFACE")
    bpy.ops.springwrap.detach()
    squeezed = local_positions(layout).copy()
    left = squeezed[:, 0] < 0.0
    squeezed[left, 0] *= 0.5  # local x, in the plane: the left half's columns at half their spacing
    layout.data.vertices.foreach_set("co", squeezed.reshape(-1))
    layout.data.update()
    world = np.array([tuple(layout.matrix_world @ vertex.co) for vertex in layout.data.vertices])
    corners = [
        int(np.argmin(squeezed[:, 0] + squeezed[:, 1])),
        int(np.argmax(squeezed[:, 0] + squeezed[:, 1])),
        int(np.argmin(squeezed[:, 0] - squeezed[:, 1])),
        int(np.argmax(squeezed[:, 0] - squeezed[:, 1])),
    ]
    for vertex in corners:
        assert bpy.ops.springwrap.anchor_add(vertex_index=vertex, location=world[vertex], use_location=True) == {
            "FINISHED"
        }
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    wrapped = local_positions(layout).astype(np.float64)
    edges = np.array([tuple(edge.vertices) for edge in layout.data.edges])
    along_x = np.abs(template[edges[:, 0], 1] - template[edges[:, 1], 1]) < 1e-6
    x_edges = edges[along_x]
    length = np.linalg.norm(wrapped[x_edges[:, 0]] - wrapped[x_edges[:, 1]], axis=1)
    assert length.max() / length.min() < 1.15, (length.min(), length.max())


def test_set_rest_shape_takes_the_current_shape_and_is_undoable():
    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.snap(mode="SURFACE")
    snapped = local_positions(layout).copy()
    name = layout.name
    bpy.ops.ed.undo_push(message="before rest")
    # The third positional argument asks bpy.ops to push the operator's own undo step.
    assert bpy.ops.springwrap.rest_set("EXEC_DEFAULT", True) == {"FINISHED"}
    np.testing.assert_array_equal(read_rest(bpy.data.objects[name]), snapped)
    bpy.ops.ed.undo()
    layout = bpy.data.objects[name]  # undo replaced the data blocks
    assert not np.array_equal(read_rest(layout), snapped)


def test_the_retired_even_rest_shape_is_no_longer_an_option():
    _target, layout, _normal = plane_scene()
    before = snapshot(layout)
    with pytest.raises(TypeError):
        bpy.ops.springwrap.wrap(rest="EVEN")
    assert snapshot(layout) == before


def test_a_broken_stored_rest_shape_is_reported_and_nothing_changes():
    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    rest = local_positions(layout).copy()
    rest[5] = np.nan
    layout.data.attributes.new(REST, "FLOAT_VECTOR", "POINT").data.foreach_set("vector", rest.reshape(-1))
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="rest shape of vertex 5 is not finite"):
        bpy.ops.springwrap.wrap()
    assert snapshot(layout) == before


def test_set_rest_shape_refuses_a_layout_with_a_nan():
    _target, layout, _normal = plane_scene()
    coordinates = local_positions(layout).copy()
    coordinates[3, 0] = np.nan
    layout.data.vertices.foreach_set("co", coordinates.reshape(-1))
    with pytest.raises(RuntimeError, match="Layout vertex 3 has a NaN"):
        bpy.ops.springwrap.rest_set()
    assert read_rest(layout) is None


def test_set_rest_shape_refuses_collapsed_edges_and_the_next_wrap_still_works():
    """A snap to the target's vertices collapses edges; taking that shape as the rest made every later wrap
    fail ("edge ... has zero length"). Set Rest Shape refuses it, names an edge, and keeps the stored rest."""
    _target, layout, _normal = plane_scene(subdivisions=30)
    template = local_positions(layout).copy()
    assert bpy.ops.springwrap.snap(mode="VERTEX") == {"FINISHED"}
    np.testing.assert_array_equal(read_rest(layout), template)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match=r"edge between layout vertices \d+ and \d+ has zero length"):
        bpy.ops.springwrap.rest_set()
    assert snapshot(layout) == before
    np.testing.assert_array_equal(read_rest(layout), template)
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    assert np.isfinite(local_positions(layout)).all()


def test_a_layout_snapped_to_coincident_points_wraps_from_its_stored_rest():
    """Snapping to target vertices puts many layout vertices at one place (zero-length edges now): the wrap
    takes the stored template as its rest shape, separates them again and writes finite positions."""
    _target, layout, _normal = plane_scene(subdivisions=30)
    assert bpy.ops.springwrap.snap(mode="VERTEX") == {"FINISHED"}
    snapped = local_positions(layout)
    edges = np.array([tuple(edge.vertices) for edge in layout.data.edges])
    assert (np.linalg.norm(snapped[edges[:, 0]] - snapped[edges[:, 1]], axis=1) == 0.0).sum() > 10
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    wrapped = local_positions(layout)
    assert np.isfinite(wrapped).all()
    lengths = np.linalg.norm(wrapped[edges[:, 0]] - wrapped[edges[:, 1]], axis=1)
    assert lengths.min() > 0.2 * np.median(lengths)
