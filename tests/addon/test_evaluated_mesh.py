"""The evaluated-mesh reader: its loop triangles, a triangle mesh's corners as they are or rebuilt from the corner
arrays for triangles and quads (folded quads split over their other diagonal, as Blender does), are Blender's own,
triangle for triangle."""

import bpy

import numpy as np
import pytest

from bpy_helpers import addon_module


def blender_triangles(obj):
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    mesh.calc_loop_triangles()
    triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    polygons = np.empty(len(mesh.loop_triangles), dtype=np.int64)
    mesh.loop_triangles.foreach_get("polygon_index", polygons)
    obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh_clear()
    return triangles.reshape(-1, 3), polygons


def noisy(obj, sigma):
    mesh = obj.data
    points = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", points)
    points += np.random.default_rng(7).normal(0.0, sigma, points.shape).astype(np.float32)
    mesh.vertices.foreach_set("co", points)
    mesh.update()
    return obj


@pytest.mark.parametrize(
    "make",
    [
        lambda: noisy(_added(bpy.ops.mesh.primitive_grid_add, x_subdivisions=40, y_subdivisions=40), 0.04),
        lambda: noisy(_added(bpy.ops.mesh.primitive_ico_sphere_add, subdivisions=3), 0.02),  # corners as they are
        lambda: _added(bpy.ops.mesh.primitive_monkey_add),  # triangles and quads
        lambda: _added(bpy.ops.mesh.primitive_cylinder_add, vertices=12),  # n-gon caps: read element by element
    ],
    ids=["folded quads", "triangles only", "triangles and quads", "n-gons"],
)
def test_the_loop_triangles_read_are_blender_s_own(make):
    obj = make()
    reader = addon_module("blender.evaluated_mesh")
    read = reader.read_evaluated_mesh(bpy.context.evaluated_depsgraph_get(), obj, triangles=True, world=False)
    triangles, polygons = blender_triangles(obj)
    assert np.array_equal(read.triangles, triangles)
    assert np.array_equal(read.triangle_polygons, polygons)
    local = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", local)
    assert np.array_equal(read.vertices, local.reshape(-1, 3))


def _added(operator, **options):
    operator(**options)
    return bpy.context.active_object
