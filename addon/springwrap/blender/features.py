"""``springwrap.detect_features``'s Blender side: the mesh read evaluated in world space, the regions written as
a colour attribute, the ridges and valleys as one poly-curve object per kind (a spline per curve) in their own
collection.
"""

import collections
from typing import NamedTuple

import bpy

import numpy as np

import springwrap_kernel

from ..core import input_policy, transforms
from ..core.errors import LayoutError
from ..core.features import median_edge_length
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
    """``springwrap_kernel.TargetMesh.detect_features`` on the mesh (raises one of :data:`ERRORS`); ``scale``
    0 is the automatic one (the result's ``scale`` says which was used)."""
    mesh = springwrap_kernel.TargetMesh(feature_mesh.vertices, feature_mesh.triangles)
    return mesh.detect_features(scale, **settings)


def layout_edge_length(layout: bpy.types.Object) -> float:
    """The median length of the edges of ``layout``'s own mesh in world space (0 for a mesh without edges)."""
    mesh = layout.data
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", positions)
    positions = transforms.transform_points(transforms.matrix_array(layout.matrix_world), positions.reshape(-1, 3))
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    return median_edge_length(positions, edges.reshape(-1, 2))


def write_feature_colors(obj: bpy.types.Object, colors: np.ndarray) -> None:
    """Store (V, 4) RGBA colours as the point colour attribute ``springwrap_curvature`` of ``obj``'s
    mesh (replacing one of another type) and make it the active and render colour (object mode)."""
    mesh = obj.data
    attributes.write_point_attribute(mesh, FEATURE_COLOR_ATTRIBUTE, "FLOAT_COLOR", colors)
    compat.set_active_color(mesh, FEATURE_COLOR_ATTRIBUTE)
    mesh.update()


FEATURE_KIND_NAMES = {"RIDGE": "Ridges", "VALLEY": "Valleys"}
"""The feature curve objects' names after their target's: ``"<target> Ridges"``, ``"<target> Valleys"``."""


def feature_objects(source_name: str) -> list:
    """The feature curve objects detected on the object called ``source_name`` (any kind, in the collection)."""
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        return []
    return [obj for obj in collection.objects if obj.get(FEATURE_SOURCE_PROPERTY) == source_name]


def _remove_object(obj) -> None:
    """Remove a curve object, and its curve data when nothing else uses it."""
    data = obj.data
    bpy.data.objects.remove(obj)
    if data is not None and data.users == 0:
        bpy.data.curves.remove(data)


def remove_feature_curves(source_name: str) -> int:
    """Remove the feature curve objects detected on the object called ``source_name`` (and their
    curve data when nothing else uses it); how many were removed."""
    doomed = feature_objects(source_name)
    for obj in doomed:
        _remove_object(obj)
    return len(doomed)


def _fill_splines(data, curves) -> None:
    """Replace the splines of ``data`` by one open poly spline per feature curve (a closed one ends on its first
    point again, so that it stays one open chain a curve constraint can follow)."""
    data.splines.clear()
    for curve in curves:
        points = np.asarray(curve.points, dtype=np.float32)
        if curve.closed:
            points = np.concatenate([points, points[:1]])
        spline = data.splines.new("POLY")
        spline.points.add(points.shape[0] - 1)
        homogeneous = np.concatenate([points, np.ones((points.shape[0], 1), dtype=np.float32)], axis=1)
        spline.points.foreach_set("co", np.ascontiguousarray(homogeneous).reshape(-1))


def write_feature_curves(context, source: bpy.types.Object, curves) -> list:
    """One poly-curve object per kind of feature, its curves as splines (world space, identity transform):
    ``"<source> Ridges"`` and ``"<source> Valleys"``, in the collection ``Springwrap Features`` (made and
    linked to the scene when missing). Replaces what was detected on ``source`` before: an object of the
    same kind is kept and refilled (curve constraints that follow it stay valid), others are removed.
    Returns the objects, ridges first."""
    collection = bpy.data.collections.get(FEATURE_COLLECTION)
    if collection is None:
        collection = bpy.data.collections.new(FEATURE_COLLECTION)
    if collection not in context.scene.collection.children_recursive:
        context.scene.collection.children.link(collection)
    by_kind = collections.defaultdict(list)
    for curve in curves:
        by_kind[curve.kind].append(curve)
    previous = feature_objects(source.name)
    written = []
    for kind, kind_name in FEATURE_KIND_NAMES.items():
        if not by_kind[kind]:
            continue
        name = f"{source.name} {kind_name}"
        reused = [obj for obj in previous if obj.get(FEATURE_KIND_PROPERTY) == kind and obj.name == name]
        if reused:
            obj = reused[0]
            previous.remove(obj)
        else:
            data = bpy.data.curves.new(name, "CURVE")
            data.dimensions = "3D"
            obj = bpy.data.objects.new(name, data)
            obj[FEATURE_SOURCE_PROPERTY] = source.name
            obj[FEATURE_KIND_PROPERTY] = kind
            collection.objects.link(obj)
        _fill_splines(obj.data, by_kind[kind])
        written.append(obj)
    for obj in previous:  # a kind found no more, or objects of an older version (one per curve)
        _remove_object(obj)
    return written
