"""The quality read-out's heat-map in the 3D view: the active layout's faces coloured by distance, stretch or
flips (``object.springwrap.show_heatmap`` and ``heatmap_kind``, the Check panel), and a legend with the numbers
in the view's top-left corner.

Two ``SpaceView3D`` draw handlers: ``POST_VIEW`` draws the triangles with per-corner colours (per vertex for
distance and stretch, flat per face for flips), depth-tested and pulled a little toward the viewer so that a
layout lying on its target is not hidden by it; ``POST_PIXEL`` draws the legend (a ramp and ``blf`` text). In
background mode nothing is installed, so turning the heat-map on there does nothing. The triangles and their
colours are cached until a depsgraph update (or the kind, the object, the mode changes).
"""

import bpy

import blf
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..blender import quality as quality_data
from ..core import quality
from .overlays import builtin_shader

DEPTH_BIAS = 2e-5
"""How far (normalised device depth) the heat-map is pulled toward the viewer, so it wins over coplanar faces."""
ALPHA = 0.85
"""Opacity of the heat-map's colours."""
LEGEND_MARGIN, LEGEND_WIDTH, LEGEND_HEIGHT = 20, 220, 12
"""The legend's margin and size in pixels."""
LEGEND_BELOW_TOP = 150
"""How far below the view's top edge the legend's numbers sit (pixels): under the view's name and collection
text, in the top-left corner, where Blender's redo panel (bottom left) and the navigation gizmo (top right) are
not."""
TEXT_SIZE = 12

SMOOTH_SHADERS_3D = ("SMOOTH_COLOR", "3D_SMOOTH_COLOR")
"""Builtin per-vertex colour shaders, best first (Blender 4 dropped the 3D_ / 2D_ prefixes)."""
SMOOTH_SHADERS_2D = ("SMOOTH_COLOR", "2D_SMOOTH_COLOR")

_handles = []
_generation = 0
_cache = {"key": None, "batch": None, "scale": None}
_failed = False


def install() -> None:
    """Add the two draw handlers and the depsgraph handler; nothing in background mode (no viewport to draw in)."""
    global _failed
    _failed = False
    if bpy.app.background or _handles:
        return
    _handles.append((bpy.types.SpaceView3D.draw_handler_add(draw_heatmap, (), "WINDOW", "POST_VIEW"), "WINDOW"))
    _handles.append((bpy.types.SpaceView3D.draw_handler_add(draw_legend, (), "WINDOW", "POST_PIXEL"), "WINDOW"))
    if _on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)


def uninstall() -> None:
    """Remove what :func:`install` added and drop the cache."""
    while _handles:
        handle, region = _handles.pop()
        bpy.types.SpaceView3D.draw_handler_remove(handle, region)
    while _on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_on_depsgraph_update)
    _cache.update(key=None, batch=None, scale=None)
    quality_data.forget_readouts()


def is_installed() -> bool:
    """Whether the draw handlers are installed."""
    return bool(_handles)


@bpy.app.handlers.persistent
def _on_depsgraph_update(_scene, _depsgraph):
    global _generation
    _generation += 1


def _shown_layout():
    """The active layout when its heat-map is on (and Blender draws), else None."""
    if bpy.app.background or _failed:
        return None
    layout = bpy.context.active_object
    if layout is None or layout.type != "MESH" or not layout.springwrap.show_heatmap:
        return None
    return layout


def heat_batch(layout):
    """(the triangles' batch, its ``HeatScale``) for the layout, or (None, None) without a read-out; cached."""
    settings = layout.springwrap
    key = (_generation, layout.as_pointer(), layout.data.as_pointer(), layout.data.is_editmode, settings.heatmap_kind)
    if _cache["key"] != key:
        batch = scale = None
        readout = quality_data.read_readout(layout)
        triangles = quality_data.read_triangles(layout) if readout is not None else None
        if triangles is not None:
            corners, corner_vertices, corner_faces = triangles
            scale = quality.heat_scale(settings.heatmap_kind, readout)
            colours = quality.ramp_colours(scale.values, ALPHA)
            corner_colours = colours[corner_faces if scale.per_face else corner_vertices]
            batch = batch_for_shader(
                builtin_shader(SMOOTH_SHADERS_3D)[1], "TRIS", {"pos": corners, "color": corner_colours}
            )
        _cache.update(key=key, batch=batch, scale=scale)
    return _cache["batch"], _cache["scale"]


def _handler(draw):
    """A draw handler around ``draw(layout, batch, scale)``: the shown layout's cached batch and scale, nothing
    without a shown layout, and given up for good (said once) when drawing raises; blending off afterwards."""

    def handler() -> None:
        layout = _shown_layout()
        if layout is None:
            return
        try:
            draw(layout, *heat_batch(layout))
        except Exception as error:  # noqa: BLE001  (a draw callback must not raise on every redraw)
            _give_up(error)
        finally:
            gpu.state.depth_test_set("NONE")
            gpu.state.blend_set("NONE")

    handler.__name__, handler.__doc__ = draw.__name__, draw.__doc__
    return handler


@_handler
def draw_heatmap(layout, batch, _scale) -> None:
    """The ``POST_VIEW`` handler: the active layout's triangles in the heat-map's colours."""
    if batch is None:
        return
    shader = builtin_shader(SMOOTH_SHADERS_3D)[1]
    projection = gpu.matrix.get_projection_matrix().copy()
    projection[2] = projection[2] - DEPTH_BIAS * projection[3]  # z_ndc - bias: toward the viewer
    gpu.state.blend_set("ALPHA")
    gpu.state.depth_test_set("LESS_EQUAL")
    with gpu.matrix.push_pop_projection():
        gpu.matrix.load_projection_matrix(projection)
        shader.bind()
        batch.draw(shader)


@_handler
def draw_legend(layout, _batch, scale) -> None:
    """The ``POST_PIXEL`` handler: the ramp, its numbers and the title in the top-left corner."""
    region, area = bpy.context.region, bpy.context.area
    base = max((region.height if region is not None else 0) - LEGEND_BELOW_TOP, LEGEND_MARGIN)
    tools = next((other for other in area.regions if other.type == "TOOLS"), None) if area is not None else None
    left = LEGEND_MARGIN + (tools.width if tools is not None and tools.width > 1 else 0)  # clear of the toolbar
    if scale is None:
        _text(left, base, "Springwrap heat-map: no read-out (Snap, Project, Wrap or Mirror)")
        return
    bottom = base + TEXT_SIZE + 6
    if scale.per_face:  # two flat boxes: blue and red
        places, colours = np.array([0.0, 0.48, 0.52, 1.0]), quality.ramp_colours([0.0, 0.0, 1.0, 1.0])
    else:
        places = np.linspace(0.0, 1.0, 33)
        colours = quality.ramp_colours(places)
    xs = left + places * LEGEND_WIDTH
    strip = np.empty((places.size * 2, 2), dtype=np.float32)
    strip[0::2] = np.column_stack([xs, np.full(places.size, bottom)])
    strip[1::2] = np.column_stack([xs, np.full(places.size, bottom + LEGEND_HEIGHT)])
    name, shader = builtin_shader(SMOOTH_SHADERS_2D)
    positions = strip if name.startswith("2D") else np.column_stack([strip, np.zeros(strip.shape[0])])
    gpu.state.blend_set("ALPHA")
    batch = batch_for_shader(
        shader, "TRI_STRIP", {"pos": positions.astype(np.float32), "color": np.repeat(colours, 2, axis=0)}
    )
    shader.bind()
    batch.draw(shader)
    for place, label in scale.labels:
        width = blf.dimensions(0, label)[0]
        x = left + place * LEGEND_WIDTH - width * place
        _text(x, base, label)
    _text(left, bottom + LEGEND_HEIGHT + 6, f"{scale.title}  ·  {layout.name}")


def _text(x: float, y: float, text: str) -> None:
    font = 0
    blf.position(font, x, y, 0)
    if hasattr(blf, "size"):
        try:
            blf.size(font, TEXT_SIZE)
        except TypeError:  # Blender before 4.0 also takes a dpi
            blf.size(font, TEXT_SIZE, 72)
    blf.color(font, 1.0, 1.0, 1.0, 1.0)
    blf.draw(font, text)


def _give_up(error: BaseException) -> None:
    global _failed
    _failed = True
    print(f"Springwrap: drawing the heat-map failed, it is no longer drawn: {error!r}")
