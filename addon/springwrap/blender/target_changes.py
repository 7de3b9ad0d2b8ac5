"""Which objects may have changed since a moment: app handlers that watch the depsgraph, so that
:mod:`.target` can reuse a built target mesh without reading (and hashing) the target again.

Every event that can change an object's evaluated mesh moves a counter on: ``depsgraph_update_post``
for each object it lists as updated (geometry or transform: Blender lists an object whose evaluated
mesh follows another datablock, such as its mesh data, its shape keys, a modifier's object or an
armature's pose, with ``is_updated_geometry``, and ``context.evaluated_depsgraph_get()`` fires it
before an operator reads anything), and for *every* object at once a scene or collection whose
geometry it lists as updated (objects added or removed), ``frame_change_post`` (the frame
is applied without a depsgraph update), ``load_post``, ``undo_post``, ``redo_post`` and the moment
the handlers are installed (what happened before could not be seen).

A reader notes :func:`moment` when it reads an object and asks :func:`unchanged_since` later: True
only when the handlers are installed and no event touched that object (or everything) after it.
When in doubt the answer is False, and the reader reads the object again.
"""

import bpy

_counter = 0
"""Moves on at every event; a moment is its value."""

_everything_changed_at = 0
"""The last event that may have changed any object."""

_object_changed_at: dict[int, int] = {}
"""An object's ``session_uid`` -> the last event that may have changed it."""


def object_key(obj) -> int:
    """The key of an object (original or evaluated) for :func:`unchanged_since`: its ``session_uid`` (unique in
    a session; before Blender 4.x Python has none: then its address, which a later object may reuse, but a
    new object is listed as updated when it enters the depsgraph, and adding or removing objects counts as a
    change of everything)."""
    original = obj.original
    session_uid = getattr(original, "session_uid", None)
    return original.as_pointer() if session_uid is None else session_uid


def moment() -> int:
    """Now, for a later :func:`unchanged_since`."""
    return _counter


def unchanged_since(obj, since: int) -> bool:
    """True when no event could have changed ``obj``'s evaluated mesh after the moment ``since``."""
    if not installed():
        return False
    return _everything_changed_at <= since and _object_changed_at.get(object_key(obj), 0) <= since


def everything_changed() -> None:
    """Treat every object as changed now (the handler below, and for a caller that knows better)."""
    global _counter, _everything_changed_at
    _counter += 1
    _everything_changed_at = _counter
    _object_changed_at.clear()  # everything is newer than any of them


@bpy.app.handlers.persistent
def _on_depsgraph_update(scene, depsgraph=None) -> None:
    global _counter
    if depsgraph is None:  # a Blender that does not pass it: nothing can be told apart
        everything_changed()
        return
    changed = []
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Object):
            if update.is_updated_geometry or update.is_updated_transform:
                changed.append(update.id)
        elif isinstance(update.id, (bpy.types.Scene, bpy.types.Collection)) and update.is_updated_geometry:
            everything_changed()  # objects added, removed, linked or unlinked
            return
    if not changed:
        return
    _counter += 1
    for obj in changed:
        _object_changed_at[object_key(obj)] = _counter


@bpy.app.handlers.persistent
def _on_everything_changed(*_arguments) -> None:
    everything_changed()


_HANDLERS = (
    ("depsgraph_update_post", _on_depsgraph_update),
    ("frame_change_post", _on_everything_changed),
    ("load_post", _on_everything_changed),
    ("undo_post", _on_everything_changed),
    ("redo_post", _on_everything_changed),
)


def installed() -> bool:
    """True while every handler is in place (a script may have removed one: then nothing is trusted)."""
    return all(handler in getattr(bpy.app.handlers, event) for event, handler in _HANDLERS)


def install() -> None:
    """Add the handlers (``register()`` calls it); what happened before counts as a change of everything."""
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        if handler not in handlers:
            handlers.append(handler)
    everything_changed()


def uninstall() -> None:
    """Remove what :func:`install` added."""
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        while handler in handlers:
            handlers.remove(handler)
    everything_changed()
