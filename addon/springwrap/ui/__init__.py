"""The add-on's user interface: the sidebar's workflow panels, their lists, the viewport overlay that draws
anchors and curve constraints, and the frame clock that measures what a redraw costs. Only Blender's UI
API here; data is read through ``blender``."""

from . import frame_clock, lists, overlays, panels

classes = lists.classes + panels.classes
"""Every UI class, lists before the panels that show them (panels in their order in the sidebar)."""


def install() -> None:
    """Add the draw handlers (the overlay, the frame clock); ``register()`` calls it after the classes."""
    overlays.install()
    frame_clock.install()


def uninstall() -> None:
    """Remove what :func:`install` added."""
    frame_clock.uninstall()
    overlays.uninstall()
