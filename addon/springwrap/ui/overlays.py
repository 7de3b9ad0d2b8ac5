"""Draws the active layout's anchors in the 3D view: a line from each anchored vertex to its target, the pair's
number at both ends (the anchor under the pair tool's mouse and the list's active anchor highlighted), and what
the pair tool's mouse is over; and its curve constraints: dashed lines from each chain vertex to the matching point
of its target curve, those Pair Feature Lines proposed (with a confidence) in violet like proposed point pairs,
with their stretch of target feature drawn as a solid line.

Two ``SpaceView3D`` draw handlers (``POST_VIEW`` for the lines and points, ``POST_PIXEL`` for the numbers), installed by :func:`install` on register and
removed by :func:`uninstall` on unregister. It draws nothing in background mode, for an object
that is not the active mesh, or when ``object.springwrap.show_anchors`` (for the anchors) and
``show_curve_constraints`` (for the curves) are off.

The anchored vertices' world positions are cached and read again only after a depsgraph update
(a ``depsgraph_update_post`` handler bumps a generation counter), so orbiting the view does not
re-read the mesh; the anchor list itself is a few small arrays, read on every draw.
"""

import bpy

import blf
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..blender import anchors as anchor_data
from ..blender import curves as curve_data
from ..blender import layout as layout_data
from ..core import anchors, curves, pair_pick
from . import anchor_focus

LINE_COLOR = (1.0, 0.55, 0.1, 0.9)
"""Colour of the lines (orange)."""
LAYOUT_POINT_COLOR = (1.0, 0.85, 0.2, 1.0)
"""Colour of the anchored layout vertices."""
TARGET_POINT_COLOR = (1.0, 0.3, 0.1, 1.0)
"""Colour of the target points."""
PROPOSED_LINE_COLOR = (0.75, 0.45, 1.0, 0.7)
"""A proposed pair's line (not used by the wrap until accepted): violet, against the hand pairs' orange."""
CURVE_LINE_COLOR = (0.2, 0.8, 1.0, 0.9)
"""Colour of the dashed curve-constraint lines (light blue)."""
FEATURE_CURVE_COLOR = (0.75, 0.45, 1.0, 0.8)
"""Colour of a feature pair's dashes and of its stretch of target feature (violet, like a proposed point pair)."""
CURVE_DASH_COUNT = 5
"""Dashes per line between a chain vertex and its target-curve point."""
HOVERED_COLOR = (1.0, 1.0, 1.0, 1.0)
"""Colour of the pair under the pair tool's mouse (white)."""
ACTIVE_COLOR = (0.3, 0.9, 1.0, 1.0)
"""Colour of the list's active pair (light blue)."""
HOVER_VERTEX_COLOR = (0.2, 1.0, 0.3, 1.0)
"""Colour of the layout vertex a pair tool click takes (green)."""
HOVER_TARGET_COLOR = (1.0, 0.2, 0.9, 1.0)
"""Colour of the target point under the pair tool's mouse (magenta)."""
PENDING_COLOR = (1.0, 1.0, 0.2, 1.0)
"""Colour of the first end of a pair being made (yellow)."""
LABEL_COLOR = (1.0, 1.0, 1.0, 1.0)
"""Colour of the pair numbers (a black shadow keeps them readable over any mesh)."""
LABEL_SIZE = 14
"""Size of the pair numbers in pixels."""
MAX_LABELS = 1000
"""More anchors than this are drawn without numbers."""
LINE_WIDTH = 2.0
"""Width of the lines in pixels (polyline shader)."""
POINT_SIZE = 7.0
"""Size of the end points in pixels."""

LINE_SHADERS = ("POLYLINE_UNIFORM_COLOR", "3D_POLYLINE_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR")
"""Builtin shaders for the lines, best first (names differ across Blender versions)."""
POINT_SHADERS = ("POINT_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR")
"""Builtin shaders for the end points, best first."""

_draw_handle = None
_label_handle = None
_tool_points = {"layout": None, "points": (None, None, None)}
_generation = 0
_position_cache = {"key": None, "positions": None}
_curve_cache = {"key": None, "segments": None, "feature": None, "stretches": None}
_shaders = {}
_failed = False


def install() -> None:
    """Add the draw handler and the depsgraph handler (once)."""
    global _draw_handle, _label_handle, _failed
    _failed = False
    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(draw_anchors, (), "WINDOW", "POST_VIEW")
    if _label_handle is None:
        _label_handle = bpy.types.SpaceView3D.draw_handler_add(draw_labels, (), "WINDOW", "POST_PIXEL")
    if _on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)


def uninstall() -> None:
    """Remove what :func:`install` added and drop the caches."""
    global _draw_handle, _label_handle
    if _draw_handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        _draw_handle = None
    if _label_handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_label_handle, "WINDOW")
        _label_handle = None
    clear_tool_points()
    while _on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_on_depsgraph_update)
    _position_cache.update(key=None, positions=None)
    _curve_cache.update(key=None, segments=None, feature=None, stretches=None)
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


def set_tool_points(layout, vertex_point, target_point, pending_point) -> None:
    """What the pair tool's mouse is over on ``layout``: the world positions of the layout vertex a click takes,
    of the target point under the mouse and of a pair's first end (each None when there is none)."""
    _tool_points.update(layout=layout.name, points=(vertex_point, target_point, pending_point))


def clear_tool_points() -> None:
    """The pair tool ended: nothing to highlight."""
    _tool_points.update(layout=None, points=(None, None, None))


def tool_points(layout) -> tuple:
    """The pair tool's points on ``layout`` (:func:`set_tool_points`), Nones when the tool is not on it."""
    return _tool_points["points"] if _tool_points["layout"] == layout.name else (None, None, None)


def anchor_ends(layout) -> tuple[anchors.Anchors, np.ndarray]:
    """The layout's anchors and (K, 3) world positions of their vertices (NaN for a missing one), cached."""
    anchor_list = anchor_data.read_anchors(layout)
    key = _cache_key(layout, anchor_list.vertex_indices.tobytes())
    if _position_cache["key"] != key:
        positions = layout_data.read_world_vertex_positions(layout, anchor_list.vertex_indices)
        _position_cache.update(key=key, positions=positions)
    return anchor_list, _position_cache["positions"]


def anchor_segments(layout, proposed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The lines to draw for ``layout``: (K, 3) float32 world starts (layout vertices) and ends (targets), of
    the hand (and accepted) pairs, or with ``proposed`` of the proposed pairs.

    Empty when the layout has no anchors or hides them. Anchors whose vertex no longer exists are
    left out.
    """
    settings = layout.springwrap
    if not settings.show_anchors or not len(settings.anchors):
        return _NO_SEGMENTS
    anchor_list, positions = anchor_ends(layout)
    chosen = np.asarray(anchor_list.proposed, dtype=bool) == proposed
    return anchors.segments(anchors.take(anchor_list, chosen), positions[chosen])


def curve_segments(layout, feature: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The dashes to draw for ``layout``'s curve constraints: (D, 3) float32 world starts and ends; with
    ``feature`` those of the feature pairs (Pair Feature Lines' proposals), otherwise those of the others.

    Each chain vertex is joined to the point of its target polyline (as last resolved) at the same
    fraction of arc length, by a dashed line. Empty when there are none or they are hidden.
    """
    if not _read_curves(layout):
        return _NO_SEGMENTS
    return _curve_cache["feature" if feature else "segments"]


def feature_stretches(layout) -> tuple[np.ndarray, np.ndarray]:
    """The stretches of target feature the feature pairs follow, as (S, 3) float32 world segment starts and
    ends (each polyline's edges); empty when there are none or curve constraints are hidden."""
    if not _read_curves(layout):
        return _NO_SEGMENTS
    return _curve_cache["stretches"]


def _read_curves(layout) -> bool:
    """Fill the curve cache for ``layout`` (dashes of the hand pairs and of the feature pairs, the feature
    pairs' stretches) when the constraints or the mesh changed; False when there is nothing to draw."""
    settings = layout.springwrap
    if not settings.show_curve_constraints or not len(settings.curve_constraints):
        return False
    constraints = curve_data.read_curve_constraints(layout)
    key = _cache_key(
        layout, tuple((c.layout_vertices.tobytes(), c.points.tobytes(), c.fractions.tobytes()) for c in constraints)
    )
    if _curve_cache["key"] != key:
        found = {False: ([], []), True: ([], [])}
        for constraint in constraints:
            starts, ends = found[constraint.source_kind == curves.FEATURE_LINE]
            chain = layout_data.read_world_vertex_positions(layout, constraint.layout_vertices)
            starts.append(chain)
            ends.append(curves.arc_length_points(chain, constraint.points, constraint.fractions))
        dashes = {
            feature: curves.dashed_segments(np.concatenate(starts), np.concatenate(ends), CURVE_DASH_COUNT)
            if starts
            else _NO_SEGMENTS
            for feature, (starts, ends) in found.items()
        }
        lines = [c.points for c in constraints if c.source_kind == curves.FEATURE_LINE and c.points.shape[0] > 1]
        stretches = (
            (
                np.concatenate([points[:-1] for points in lines]).astype(np.float32),
                np.concatenate([points[1:] for points in lines]).astype(np.float32),
            )
            if lines
            else _NO_SEGMENTS
        )
        _curve_cache.update(key=key, segments=dashes[False], feature=dashes[True], stretches=stretches)
    return True


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
    if not (show_anchors or show_curves or _tool_points["layout"] == layout.name):
        return
    try:
        if show_anchors:
            starts, ends = anchor_segments(layout)
            if starts.shape[0]:
                _draw_segments(starts, ends)
            starts, ends = anchor_segments(layout, proposed=True)
            if starts.shape[0]:
                _draw_segments(starts, ends, PROPOSED_LINE_COLOR)
            _draw_highlights(layout)
        _draw_tool_points(layout)
        if show_curves:
            for (starts, ends), color in (
                (curve_segments(layout), CURVE_LINE_COLOR),
                (curve_segments(layout, feature=True), FEATURE_CURVE_COLOR),
                (feature_stretches(layout), FEATURE_CURVE_COLOR),
            ):
                if starts.shape[0]:
                    _draw_segments(starts, ends, color, with_points=False)
    except Exception as error:  # noqa: BLE001  (a draw callback must not raise on every redraw)
        _failed = True
        print(f"Springwrap: drawing anchors failed, anchors are no longer drawn: {error!r}")


def _highlighted(layout) -> list[tuple[int, tuple]]:
    """``[(anchor index, colour)]`` of the pairs drawn highlighted: the list's active one, then the hovered one."""
    settings = layout.springwrap
    chosen = [(settings.active_anchor_index, ACTIVE_COLOR), (anchor_focus.hovered_anchor(layout), HOVERED_COLOR)]
    return [(index, color) for index, color in chosen if 0 <= index < len(settings.anchors)]


def _draw_highlights(layout) -> None:
    """The active and the hovered pair, drawn again over the others in their colours."""
    anchor_list, positions = anchor_ends(layout)
    for index, color in _highlighted(layout):
        start, end = positions[index : index + 1], anchor_list.locations[index : index + 1]
        if np.all(np.isfinite(start)) and np.all(np.isfinite(end)):
            _draw_segments(start.astype(np.float32), end.astype(np.float32), color, end_colors=(color, color))


def _draw_tool_points(layout) -> None:
    """The pair tool's hovered vertex, hovered target point and pending first end."""
    colors = (HOVER_VERTEX_COLOR, HOVER_TARGET_COLOR, PENDING_COLOR)
    for point, color in zip(tool_points(layout), colors):
        if point is not None:
            location = np.asarray(point, dtype=np.float32).reshape(1, 3)
            _draw_segments(location, location, color, end_colors=(color, color), point_size=2.0 * POINT_SIZE)


def draw_labels() -> None:
    """The ``POST_PIXEL`` handler: each pair's number beside both of its ends (never in background mode)."""
    global _failed
    if bpy.app.background or _failed:
        return
    context = bpy.context
    layout = context.active_object
    if layout is None or layout.type != "MESH" or context.region_data is None:
        return
    settings = layout.springwrap
    if not settings.show_anchors or not 0 < len(settings.anchors) <= MAX_LABELS:
        return
    try:
        anchor_list, positions = anchor_ends(layout)
        view = pair_pick.make_view(
            np.array(context.region_data.perspective_matrix), context.region.width, context.region.height
        )
        _draw_numbers(view, positions, anchor_list.locations, dict(_highlighted(layout)))
    except Exception as error:  # noqa: BLE001  (a draw callback must not raise on every redraw)
        _failed = True
        print(f"Springwrap: drawing anchors failed, anchors are no longer drawn: {error!r}")


def _draw_numbers(view, starts, ends, colors) -> None:
    font = 0
    try:
        blf.size(font, LABEL_SIZE)
    except TypeError:  # Blender before 4.0 wants a dpi
        blf.size(font, LABEL_SIZE, 72)
    blf.enable(font, blf.SHADOW)
    blf.shadow(font, 3, 0.0, 0.0, 0.0, 1.0)
    blf.shadow_offset(font, 1, -1)
    try:
        for points in (starts, ends):
            pixels, in_front = pair_pick.project(view, points)
            for index in np.flatnonzero(in_front).tolist():
                color = colors.get(index, LABEL_COLOR)
                blf.color(font, *color)
                blf.position(font, pixels[index, 0] + 6.0, pixels[index, 1] + 6.0, 0.0)
                blf.draw(font, str(anchor_focus.pair_number(index)))
    finally:
        blf.disable(font, blf.SHADOW)


def _draw_segments(
    starts: np.ndarray,
    ends: np.ndarray,
    color=LINE_COLOR,
    with_points=True,
    end_colors=(LAYOUT_POINT_COLOR, TARGET_POINT_COLOR),
    point_size=POINT_SIZE,
) -> None:

    lines = np.empty((starts.shape[0] * 2, 3), dtype=np.float32)
    lines[0::2] = starts
    lines[1::2] = ends
    gpu.state.blend_set("ALPHA")
    gpu.state.depth_test_set("NONE")
    try:
        name, shader = builtin_shader(LINE_SHADERS)
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

        name, shader = builtin_shader(POINT_SHADERS)
        shader.bind()
        if name.startswith("POINT"):
            gpu.state.program_point_size_set(True)  # the shader writes the point size itself
            shader.uniform_float("size", point_size)
        else:
            gpu.state.point_size_set(point_size)
        for points, color in zip((starts, ends), end_colors):
            shader.uniform_float("color", color)
            batch_for_shader(shader, "POINTS", {"pos": points}).draw(shader)
    finally:
        gpu.state.line_width_set(1.0)
        gpu.state.program_point_size_set(False)
        gpu.state.point_size_set(1.0)
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")


def builtin_shader(names):
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
