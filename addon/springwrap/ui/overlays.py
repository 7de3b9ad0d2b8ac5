"""Draws the active layout's anchors in the 3D view: a line from each anchored vertex to its target;
and its curve constraints: dashed lines from each chain vertex to the matching point of its target curve.

One ``SpaceView3D`` draw handler (``POST_VIEW``), installed by :func:`install` on register and
removed by :func:`uninstall` on unregister. It draws nothing in background mode, for an object
that is not the active mesh, or when ``object.springwrap.show_anchors`` (for the anchors) and
``show_curve_constraints`` (for the curves) are off.

The anchored vertices' world positions are cached and read again only after a depsgraph update
(a ``depsgraph_update_post`` handler bumps a generation counter), so orbiting the view does not
re-read the mesh; the anchor list itself is a few small arrays, read on every draw.
"""

import bpy

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..blender import anchors as anchor_data
from ..blender import curves as curve_data
from ..blender import layout as layout_data
from ..core import anchors, curves

LINE_COLOR = (1.0, 0.55, 0.1, 0.9)
"""Colour of the lines (orange)."""
LAYOUT_POINT_COLOR = (1.0, 0.85, 0.2, 1.0)
"""Colour of the anchored layout vertices."""
TARGET_POINT_COLOR = (1.0, 0.3, 0.1, 1.0)
"""Colour of the target points."""
CURVE_LINE_COLOR = (0.2, 0.8, 1.0, 0.9)
"""Colour of the dashed curve-constraint lines (light blue)."""
CURVE_DASH_COUNT = 5
"""Dashes per line between a chain vertex and its target-curve point."""
LINE_WIDTH = 2.0
"""Width of the lines in pixels (polyline shader)."""
POINT_SIZE = 7.0
"""Size of the end points in pixels."""

LINE_SHADERS = ("POLYLINE_UNIFORM_COLOR", "3D_POLYLINE_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR")
"""Builtin shaders for the lines, best first (names differ across Blender versions)."""
POINT_SHADERS = ("POINT_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR")
"""Builtin shaders for the end points, best first."""

_draw_handle = None
_generation = 0
_position_cache = {"key": None, "positions": None}
_curve_cache = {"key": None, "segments": None}
_shaders = {}
_failed = False


def install() -> None:
    """Add the draw handler and the depsgraph handler (once)."""
    global _draw_handle, _failed
    _failed = False
    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(draw_anchors, (), "WINDOW", "POST_VIEW")
    if _on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)


def uninstall() -> None:
    """Remove what :func:`install` added and drop the caches."""
    global _draw_handle
    if _draw_handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        _draw_handle = None
    while _on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_on_depsgraph_update)
    _position_cache.update(key=None, positions=None)
    _curve_cache.update(key=None, segments=None)
    _shaders.clear()


def is_installed() -> bool:
    """Whether the draw handler is installed."""
    return _draw_handle is not None


@bpy.app.handlers.persistent
def _on_depsgraph_update(_scene, _depsgraph):
    """Something changed (geometry, transform, mode...): the cached positions are stale."""
    global _generation
    _generation += 1


_NO_SEGMENTS = (np.zeros((0, 3), dtype=np.float32), np.zeros((0, 3), dtype=np.float32))
"""Nothing to draw: no starts, no ends."""


def _cache_key(layout, what) -> tuple:
    """When the positions cached for ``what`` (the items drawn) are still current: nothing changed since (the
    depsgraph generation), the same layout and mesh, the same mode."""
    return (_generation, layout.as_pointer(), layout.data.as_pointer(), layout.data.is_editmode, what)


def anchor_segments(layout) -> tuple[np.ndarray, np.ndarray]:
    """The lines to draw for ``layout``: (K, 3) float32 world starts (layout vertices) and ends (targets).

    Empty when the layout has no anchors or hides them. Anchors whose vertex no longer exists are
    left out.
    """
    settings = layout.springwrap
    if not settings.show_anchors or not len(settings.anchors):
        return _NO_SEGMENTS
    anchor_list = anchor_data.read_anchors(layout)
    key = _cache_key(layout, anchor_list.vertex_indices.tobytes())
    if _position_cache["key"] != key:
        positions = layout_data.read_world_vertex_positions(layout, anchor_list.vertex_indices)
        _position_cache.update(key=key, positions=positions)
    return anchors.segments(anchor_list, _position_cache["positions"])


def curve_segments(layout) -> tuple[np.ndarray, np.ndarray]:
    """The dashes to draw for ``layout``'s curve constraints: (D, 3) float32 world starts and ends.

    Each chain vertex is joined to the point of its target polyline (as last resolved) at the same
    fraction of arc length, by a dashed line. Empty when there are none or they are hidden.
    """
    settings = layout.springwrap
    if not settings.show_curve_constraints or not len(settings.curve_constraints):
        return _NO_SEGMENTS
    constraints = curve_data.read_curve_constraints(layout)
    key = _cache_key(layout, tuple((c.layout_vertices.tobytes(), c.points.tobytes()) for c in constraints))
    if _curve_cache["key"] != key:
        starts, ends = [], []
        for constraint in constraints:
            chain = layout_data.read_world_vertex_positions(layout, constraint.layout_vertices)
            starts.append(chain)
            ends.append(curves.arc_length_points(chain, constraint.points))
        segments = curves.dashed_segments(np.concatenate(starts), np.concatenate(ends), CURVE_DASH_COUNT)
        _curve_cache.update(key=key, segments=segments)
    return _curve_cache["segments"]


def draw_anchors() -> None:
    """The draw handler: the active layout's anchors and curve constraints (never in background mode)."""
    global _failed
    if bpy.app.background or _failed:
        return
    layout = bpy.context.active_object
    if layout is None or layout.type != "MESH":
        return
    settings = layout.springwrap
    show_anchors = settings.show_anchors and len(settings.anchors)
    show_curves = settings.show_curve_constraints and len(settings.curve_constraints)
    if not (show_anchors or show_curves):
        return
    try:
        if show_anchors:
            starts, ends = anchor_segments(layout)
            if starts.shape[0]:
                _draw_segments(starts, ends)
        if show_curves:
            starts, ends = curve_segments(layout)
            if starts.shape[0]:
                _draw_segments(starts, ends, CURVE_LINE_COLOR, with_points=False)
    except Exception as error:  # noqa: BLE001  (a draw callback must not raise on every redraw)
        _failed = True
        print(f"Springwrap: drawing anchors failed, anchors are no longer drawn: {error!r}")


def _draw_segments(starts: np.ndarray, ends: np.ndarray, color=LINE_COLOR, with_points=True) -> None:

    lines = np.empty((starts.shape[0] * 2, 3), dtype=np.float32)
    lines[0::2] = starts
    lines[1::2] = ends
    gpu.state.blend_set("ALPHA")
    gpu.state.depth_test_set("NONE")
    try:
        name, shader = _shader(LINE_SHADERS)
        batch = batch_for_shader(shader, "LINES", {"pos": lines})
        shader.bind()
        if "POLYLINE" in name:
            shader.uniform_float("viewportSize", gpu.state.viewport_get()[2:])
            shader.uniform_float("lineWidth", LINE_WIDTH)
        else:
            gpu.state.line_width_set(LINE_WIDTH)
        shader.uniform_float("color", color)
        batch.draw(shader)
        if not with_points:
            return

        name, shader = _shader(POINT_SHADERS)
        shader.bind()
        if name.startswith("POINT"):
            gpu.state.program_point_size_set(True)  # the shader writes the point size itself
            shader.uniform_float("size", POINT_SIZE)
        else:
            gpu.state.point_size_set(POINT_SIZE)
        for points, color in ((starts, LAYOUT_POINT_COLOR), (ends, TARGET_POINT_COLOR)):
            shader.uniform_float("color", color)
            batch_for_shader(shader, "POINTS", {"pos": points}).draw(shader)
    finally:
        gpu.state.line_width_set(1.0)
        gpu.state.program_point_size_set(False)
        gpu.state.point_size_set(1.0)
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")


def _shader(names):
    """The first builtin shader of ``names`` this Blender has, as ``(name, shader)``; cached."""
    if names not in _shaders:
        for name in names:
            try:
                _shaders[names] = (name, gpu.shader.from_builtin(name))
                break
            except (ValueError, TypeError):
                continue
        else:
            raise RuntimeError(f"none of the builtin shaders {names} exists")
    return _shaders[names]
