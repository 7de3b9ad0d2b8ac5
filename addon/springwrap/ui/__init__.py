"""The add-on's user interface: the sidebar's panels, their lists, and the viewport overlay that draws anchors
and curve constraints. Only Blender's UI API here; data is read through ``blender``."""

from . import lists, overlays, panels  # noqa: F401  (overlays: installed by register())

classes = lists.classes + panels.classes
"""Every UI class, lists before the panels that show them (panels in their order in the sidebar)."""
