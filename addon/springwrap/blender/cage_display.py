"""Show the layout as a cage over its target, and put the user's display back when it is turned off.

In solid shading a layout lying on its target z-fights with it (patchy colours). With the cage on, the
layout object is drawn *In Front* and as *Wire* (every Blender version, object and edit mode), and on
Blender 4.0+, whose 3D views have the Retopology overlay (``overlay.show_retopology``, edit mode), that
overlay is turned on in the 3D views of every open window too. What was changed is stored on the layout
(``springwrap.cage_saved_display``, JSON: the object's ``show_in_front`` and ``display_type``, each view's
overlay, by screen name and area index), so turning the cage off puts exactly that back, also after
the file was saved and opened again.
"""

import json

import bpy

RETOPOLOGY_OFFSET = 0.001
"""The Retopology overlay's offset toward the view (world units) while the cage is on: Blender's default."""


def has_retopology_overlay() -> bool:
    """Whether this Blender's 3D views have the Retopology overlay (4.0 and later)."""
    return "show_retopology" in bpy.types.View3DOverlay.bl_rna.properties


def _views(window_manager):
    """(key, overlay) of every 3D view in the open windows; the key names its screen and area."""
    for window in window_manager.windows:
        screen = window.screen
        for area_index, area in enumerate(screen.areas):
            if area.type != "VIEW_3D":
                continue
            for space in area.spaces:
                if space.type == "VIEW_3D":
                    yield f"{screen.name}/{area_index}", space.overlay


def show_cage(obj: bpy.types.Object, window_manager=None) -> None:
    """Draw ``obj`` as a cage (In Front, Wire; the Retopology overlay where there is one), saving what it replaces."""
    saved = {"show_in_front": obj.show_in_front, "display_type": obj.display_type, "views": {}}
    if window_manager is not None and has_retopology_overlay():
        for key, overlay in _views(window_manager):
            saved["views"][key] = [overlay.show_retopology, overlay.retopology_offset]
            overlay.show_retopology = True
            overlay.retopology_offset = RETOPOLOGY_OFFSET
    obj.springwrap.cage_saved_display = json.dumps(saved)
    obj.show_in_front = True
    obj.display_type = "WIRE"


def hide_cage(obj: bpy.types.Object, window_manager=None) -> None:
    """Put back what :func:`show_cage` changed (views that are gone are skipped); nothing when nothing was saved."""
    text = obj.springwrap.cage_saved_display
    if not text:
        return
    try:
        saved = json.loads(text)
        obj.show_in_front = bool(saved["show_in_front"])
        obj.display_type = str(saved["display_type"])
        views = dict(saved.get("views", {}))
    except (ValueError, KeyError, TypeError):  # a hand-edited property: leave the display as it is
        views = {}
    if window_manager is not None and has_retopology_overlay():
        for key, overlay in _views(window_manager):
            if key in views:
                overlay.show_retopology, overlay.retopology_offset = bool(views[key][0]), float(views[key][1])
    obj.springwrap.cage_saved_display = ""


def update_show_cage(settings, context) -> None:
    """``show_cage``'s update: show or hide the cage of the object the settings belong to."""
    obj = settings.id_data
    window_manager = None if context is None else context.window_manager
    if settings.show_cage:
        if not settings.cage_saved_display:  # already shown (an undo brought the flag back): keep the first save
            show_cage(obj, window_manager)
    else:
        hide_cage(obj, window_manager)
