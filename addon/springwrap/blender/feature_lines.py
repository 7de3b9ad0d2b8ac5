"""``springwrap.feature_lines_pair``'s Blender side: the layout's marked edges (sharp, seam, a vertex group, a
boolean edge attribute), its rest shape and faces in world space, and the target's feature curves and hole
borders.
"""

from typing import NamedTuple

import bpy

import numpy as np

from ..core import feature_lines, transforms
from ..core.errors import LayoutError
from ..core.features import median_edge_length
from . import attributes, compat
from . import features as feature_data
from .layout import read_layout_group, read_positions


class LayoutLines(NamedTuple):
    """What the pairing reads from the layout."""

    rest: np.ndarray  # (N, 3) float64 world rest shape (the stored one, else the mesh as it is)
    current: np.ndarray  # (N, 3) float64 world positions now (the current fit)
    face_corners: np.ndarray  # uint32
    face_sizes: np.ndarray  # uint32
    edges: np.ndarray  # (E, 2) int64
    marked: np.ndarray  # (K, 2) uint32 the marked edges


def _edge_flags(mesh: bpy.types.Mesh, name: str) -> np.ndarray:
    """(E,) bool: the boolean edge attribute ``name`` (all False when the mesh has none)."""
    values = attributes.read_attribute(mesh, name, "BOOLEAN", "EDGE")
    return np.zeros(len(mesh.edges), dtype=bool) if values is None else values.astype(bool)


def read_marked(layout: bpy.types.Object, edges: np.ndarray, sharp: bool, seams: bool, group: str, attribute: str):
    """(K, 2) uint32 edges marked as feature lines: sharp edges, seams, the edges inside vertex group ``group``
    and those whose boolean edge attribute ``attribute`` is set (each when asked for). Raises
    :class:`LayoutError` for a group or attribute the layout does not have, or a group holding no edge."""
    mesh = layout.data
    flags = np.zeros(len(mesh.edges), dtype=bool)
    if sharp:
        if bpy.app.version >= (4, 0, 0):
            flags |= _edge_flags(mesh, "sharp_edge")
        else:
            values = np.empty(len(mesh.edges), dtype=bool)
            mesh.edges.foreach_get("use_edge_sharp", values)
            flags |= values
    if seams:
        values = np.empty(len(mesh.edges), dtype=bool)
        mesh.edges.foreach_get("use_seam", values)
        flags |= values
    if attribute:
        if attributes.find_attribute(mesh, attribute, "BOOLEAN", "EDGE") is None:
            raise LayoutError(f"Layout '{layout.name}' has no boolean edge attribute '{attribute}'")
        flags |= _edge_flags(mesh, attribute)
    marked = feature_lines.marked_edges(edges, flags)
    if group:
        _weights, member = read_layout_group(layout, group)
        marked = np.concatenate([marked, feature_lines.group_edges(edges, member, group)])
    return marked


def read_layout_lines(layout: bpy.types.Object, sharp: bool, seams: bool, group: str, attribute: str) -> LayoutLines:
    """The layout's rest shape, positions, faces, edges and marked edges (object mode data)."""
    mesh = layout.data
    matrix = transforms.matrix_array(layout.matrix_world)
    current = transforms.transform_points(matrix, read_positions(layout).reshape(-1, 3).astype(np.float64))
    rest = attributes.read_rest(layout)
    rest = current if rest is None else transforms.transform_points(matrix, rest.astype(np.float64))
    face_corners, face_sizes = compat.read_face_corners(mesh)
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edges)
    edges = edges.reshape(-1, 2)
    return LayoutLines(
        rest=rest,
        current=current,
        face_corners=np.ascontiguousarray(face_corners, dtype=np.uint32),
        face_sizes=np.ascontiguousarray(face_sizes, dtype=np.uint32),
        edges=edges,
        marked=read_marked(layout, edges, sharp, seams, group, attribute),
    )


def median_layout_edge(lines: LayoutLines) -> float:
    """The median length of the layout's edges where the fit has them now."""
    return median_edge_length(lines.current, lines.edges)


def read_target_features(depsgraph, target: bpy.types.Object, layout_edge: float, crease_degrees: float, **settings):
    """``(target curves for pairing, crease junctions (J, 3), feature scale used)``: the target's sharp creases
    (``crease_degrees``, 0: none) and the corners where they meet, its ridges and valleys (detected at the
    automatic scale for a layout of median edge ``layout_edge``, or ``settings``' scale) and its hole borders."""
    mesh = feature_data.read_feature_mesh(depsgraph, target)
    scale = settings.pop("scale", 0.0)
    found = feature_data.detect_features(mesh, scale, layout_edge_length=layout_edge, **settings)
    curves, junctions = feature_lines.target_features(
        found.curves, mesh.vertices, mesh.triangles, crease_degrees, found.scale
    )
    return curves, junctions, found.scale


_free_lines: dict[str, list] = {}
"""The feature lines the last pairing left free, by layout name (this Blender session only)."""


def remember_free(layout_name: str, free: list) -> None:
    """Keep the last pairing's free lines of the layout of this name: ``(label, reason)`` each."""
    _free_lines[layout_name] = list(free)


def free_lines(layout_name: str) -> list:
    """``(label, reason)`` of each line the last pairing on the layout of this name left free."""
    return list(_free_lines.get(layout_name, ()))
