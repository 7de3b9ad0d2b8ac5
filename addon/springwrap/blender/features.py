"""``springwrap.detect_features``'s Blender side: the mesh read evaluated in world space, the regions written as
a colour attribute, the ridges and valleys as poly-curve objects in their own collection.
"""

import collections
from typing import NamedTuple

import bpy

import numpy as np

import springwrap_kernel

from ..core import input_policy, transforms
from ..core.errors import LayoutError
from . import attributes, compat
from .evaluated_mesh import read_evaluated_mesh

FEATURE_COLLECTION = "Springwrap Features"
"""Collection holding the feature curve objects of ``springwrap.detect_features``."""

FEATURE_COLOR_ATTRIBUTE = "springwrap_curvature"
"""Point colour attribute of the regions (flat / convex / concave / saddle)."""

FEATURE_SOURCE_PROPERTY = "springwrap_feature_source"
"""Custom property of a feature curve object: the name of the mesh object it was detected on."""

FEATURE_KIND_PROPERTY = "springwrap_feature"
"""Custom property of a feature curve object: ``RIDGE`` or ``VALLEY``."""


class FeatureMesh(NamedTuple):
    """A mesh object's evaluated geometry in world space, as the kernel takes it."""

    vertices: np.ndarray  # (V, 3) float32 world positions of the evaluated mesh
    triangles: np.ndarray  # (T, 3) uint32 loop triangles
    base_vertex_count: int  # vertices of the object's own mesh (colours go there)


def read_feature_mesh(depsgraph: bpy.types.Depsgraph, obj: bpy.types.Object) -> FeatureMesh:
    """The evaluated mesh of ``obj`` in world space; raises :class:`LayoutError` when it has no faces."""
    evaluated = read_evaluated_mesh(depsgraph, obj, triangles=True)
    if evaluated.vertices.size == 0 or evaluated.triangles.size == 0:
        raise LayoutError(f"'{obj.name}' has no faces: there is no surface to detect features on")
    vertices = evaluated.vertices
    input_policy.check_points(  # non-finite vertices: the kernel names them
        vertices[np.all(np.isfinite(vertices), axis=1)], lambda _row: "A vertex", fix="fix the mesh or its modifiers"
    )
    return FeatureMesh(
        vertices=transforms.as_float32_points(evaluated.vertices),
        triangles=evaluated.triangles,
        base_vertex_count=len(obj.data.vertices),
    )


def detect_features(feature_mesh: FeatureMesh, scale: float, **settings):
    """``springwrap_kernel.TargetMesh.detect_features`` on the mesh (raises one of :data:`ERRORS`)."""
    mesh = springwrap_kernel.TargetMesh(feature_mesh.vertices, feature_mesh.triangles)
    return mesh.detect_features(scale, **settings)


def write_feature_colors(obj: bpy.types.Object, colors: np.ndarray) -> None:
    """Store (V, 4) RGBA colours as the point colour attribute ``springwrap_curvature`` of ``obj``'s
    mesh (replacing one of another type) and make it the active and render colour (object mode)."""
    mesh = obj.data
    attributes.write_point_attribute(mesh, FEATURE_COLOR_ATTRIBUTE, "FLOAT_COLOR", colors)
    compat.set_active_color(mesh, FEATURE_COLOR_ATTRIBUTE)
    mesh.update()


def remove_feature_curves(source_name: str) -> int:
    """Remove the feature curve objects detected on the object called ``source_name`` (and their
    curve data when nothing else uses it); how many were removed."""
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        return 0
    doomed = [obj for obj in collection.objects if obj.get(FEATURE_SOURCE_PROPERTY) == source_name]
    for obj in doomed:
        data = obj.data
        bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            bpy.data.curves.remove(data)
    return len(doomed)


def write_feature_curves(context, source: bpy.types.Object, curves) -> list:
    """One poly-curve object per feature curve (world space, identity transform), in the collection
    ``Springwrap Features`` (made and linked to the scene when missing), named by kind; each an open
    spline, a closed curve ending on its first point again, so that it can be a curve constraint's
    target. Replaces the curves detected on ``source`` before. Returns the new objects."""
    remove_feature_curves(source.name)
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        collection = bpy.data.collections.new(FEATURE_COLLECTION)
    if collection not in context.scene.collection.children_recursive:
        context.scene.collection.children.link(collection)
    created = []
    counts = collections.Counter()
    for curve in curves:
        counts[curve.kind] += 1
        name = f"{source.name} {curve.kind.title()} {counts[curve.kind]}"
        points = np.asarray(curve.points, dtype=np.float32)
        if curve.closed:
            points = np.concatenate([points, points[:1]])
        data = bpy.data.curves.new(name, "CURVE")
        data.dimensions = "3D"
        spline = data.splines.new("POLY")
        spline.points.add(points.shape[0] - 1)
        homogeneous = np.concatenate([points, np.ones((points.shape[0], 1), dtype=np.float32)], axis=1)
        spline.points.foreach_set("co", np.ascontiguousarray(homogeneous).reshape(-1))
        obj = bpy.data.objects.new(name, data)
        obj[FEATURE_SOURCE_PROPERTY] = source.name
        obj[FEATURE_KIND_PROPERTY] = curve.kind
        collection.objects.link(obj)
        created.append(obj)
    return created
