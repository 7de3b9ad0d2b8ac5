"""The wrap onto a cylinder with a hole in its side (plane, sphere and cylinder)."""

import math

import bpy

import bmesh
import numpy as np
from mathutils import Vector

from bpy_helpers import (
    Reference,
    activate_layout,
    assert_no_flipped_quads,
    assert_wrapped_onto,
    local_positions,
    read_state,
    world_positions,
    wrap_with_anchors,
)

RADIUS = 1.0
SEGMENTS = 64
HOLE_CENTER = Vector((RADIUS, 0.0, 0.0))  # on the +X side, half-way up
HOLE_RADIUS = 0.3


def cylinder_scene():
    """An open tube (radius 1, height 3, 64 x 30 quads) with a round hole in its side, and a 12x12 grid
    bent onto a coaxial arc of radius 1.25 (100 degrees, height 1.6) over the hole."""
    editable = bmesh.new()
    rings = 31
    ring_vertices = []
    for ring in range(rings):
        z = -1.5 + 3.0 * ring / (rings - 1)
        ring_vertices.append(
            [
                editable.verts.new(
                    (RADIUS * math.cos(2 * math.pi * s / SEGMENTS), RADIUS * math.sin(2 * math.pi * s / SEGMENTS), z)
                )
                for s in range(SEGMENTS)
            ]
        )
    for ring in range(rings - 1):
        for s in range(SEGMENTS):
            a, b = ring_vertices[ring][s], ring_vertices[ring][(s + 1) % SEGMENTS]
            c, d = ring_vertices[ring + 1][(s + 1) % SEGMENTS], ring_vertices[ring + 1][s]
            editable.faces.new((a, b, c, d))
    doomed = [face for face in editable.faces if (face.calc_center_median() - HOLE_CENTER).length < HOLE_RADIUS]
    bmesh.ops.delete(editable, geom=doomed, context="FACES")
    mesh = bpy.data.meshes.new("Tube")
    editable.to_mesh(mesh)
    editable.free()
    target = bpy.data.objects.new("Target", mesh)
    bpy.context.scene.collection.objects.link(target)

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=2)
    layout = activate_layout(bpy.context.active_object, target)
    flat = local_positions(layout).astype(np.float64)
    angle = flat[:, 0] * math.radians(50.0)
    arc = np.stack([1.25 * np.cos(angle), 1.25 * np.sin(angle), flat[:, 1] * 0.8 + 0.05], axis=1)
    layout.data.vertices.foreach_set("co", arc.astype(np.float32).reshape(-1))
    layout.data.update()
    return target, layout


def _outward(points):
    directions = np.asarray(points, dtype=np.float64) * np.array([1.0, 1.0, 0.0])
    return directions / np.linalg.norm(directions, axis=1)[:, None]


def test_a_layout_wraps_onto_a_cylinder_and_caps_the_hole_in_its_side():
    target, layout = cylinder_scene()
    template = world_positions(layout)
    reference = Reference(target)
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    # Face-points on the target within 1e-5, anchors met, no quad flipped, spacing kept within bounds.
    assert_wrapped_onto(layout, reference, template, _outward, (0.5, 2.0))
    assert_no_flipped_quads(layout, _outward)
    states, _faces, _barycentrics = read_state(layout)
    world = world_positions(layout)
    radii = np.linalg.norm(world[:, :2], axis=1)
    # Face-points lie on the 64-gon (between its flat faces and its corners) ...
    assert radii[states == 1].max() <= RADIUS + 1e-5
    assert radii[states == 1].min() >= RADIUS * math.cos(math.pi / SEGMENTS) - 1e-5
    # ... points over the hole are space-points on the cylinder the hole was cut from, within 2 %.
    over_hole = np.linalg.norm(world - np.array(HOLE_CENTER), axis=1) < HOLE_RADIUS - 0.1
    assert over_hole.sum() >= 3 and (states[over_hole] == 0).all()
    assert np.abs(radii[over_hole] - RADIUS).max() < 0.02 * RADIUS, radii[over_hole]
