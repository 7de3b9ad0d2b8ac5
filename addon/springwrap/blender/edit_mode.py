"""The one way out of edit mode and back: operations work on the mesh data, which edit mode holds back.

Leaving edit mode flushes the edit-mesh into the mesh; going back rebuilds it from the mesh, so the
result shows (and is one edit-mode undo step). :func:`object_mode` does both around a block; the
modal wrap, which spans many events, holds an :class:`EditModeGuard` instead.
"""

import contextlib

import bpy


class EditModeGuard:
    """Takes an object out of edit mode (when it is in it) and, on :meth:`restore`, puts it back."""

    def __init__(self, obj: bpy.types.Object):
        self.was_editing = obj.mode == "EDIT"
        if self.was_editing:
            bpy.ops.object.mode_set(mode="OBJECT")

    def restore(self) -> None:
        """Go back into edit mode if the object was in it (once: a second call does nothing)."""
        if self.was_editing:
            self.was_editing = False
            bpy.ops.object.mode_set(mode="EDIT")


@contextlib.contextmanager
def object_mode(obj: bpy.types.Object):
    """Run the block with ``obj`` out of edit mode, so its mesh data is current and writable."""
    guard = EditModeGuard(obj)
    try:
        yield
    finally:
        guard.restore()
