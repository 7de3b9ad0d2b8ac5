"""The add-on's user interface: the sidebar's workflow panels, their lists, the viewport overlay that draws
anchors and curve constraints, the quality read-out's heat-map, and the frame clock that measures what a redraw costs. Only Blender's UI
API here; data is read through ``blender``."""

import bpy

from ..blender import wrap_session
from . import follow_indicator, frame_clock, heatmap, lists, overlays, pair_tool, panels

classes = lists.classes + panels.classes
"""Every UI class, lists before the panels that show them (panels in their order in the sidebar)."""


def install() -> None:
    """Add the draw handlers (the overlay, the frame clock) and forget the Check panel's last wraps when another
    file is loaded; ``register()`` calls it after the classes."""
    overlays.install()
    heatmap.install()  # nothing in background mode
    frame_clock.install()
    pair_tool.install()  # nothing in background mode
    follow_indicator.install()
    if wrap_session.forget_results_on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(wrap_session.forget_results_on_load)


def uninstall() -> None:
    """Remove what :func:`install` added."""
    while wrap_session.forget_results_on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(wrap_session.forget_results_on_load)
    follow_indicator.uninstall()
    pair_tool.uninstall()
    frame_clock.uninstall()
    heatmap.uninstall()
    overlays.uninstall()
