"""What a redraw of the 3D view costs, measured as the viewport draws: the live wrap paces its first frame from it.

Two ``SpaceView3D`` draw handlers, installed with the overlay by ``register()``: one at the start of the
view's drawing (``PRE_VIEW``), one at its end (``POST_PIXEL``). The time between them is the viewport's
own draw (scene, overlays, our lines), the bulk of a redraw; a smoothed value is kept, and a live wrap
adds what it measured between its frames (the whole redraw) when it ends. Under software
OpenGL at 1920x1080 it is about a second, on a GPU a few milliseconds. The handlers only read the
clock: they cost nothing and cannot fail.
"""

import time

import bpy

SMOOTHING = 0.5
"""Weight of the newest draw in the smoothed draw time."""

_handles = []
_state = {"start": None, "seconds": None}


def _draw_started() -> None:
    _state["start"] = time.perf_counter()


def _draw_ended() -> None:
    start = _state["start"]
    if start is None:
        return
    _state["start"] = None
    record(time.perf_counter() - start)


def display_seconds() -> float | None:
    """The viewport's smoothed draw time in seconds, or None before any 3D view was drawn (or in background mode)."""
    return _state["seconds"]


def record(seconds: float) -> None:
    """Account for a redraw of ``seconds`` (a view's draw, or what the live wrap measured between its frames)."""
    previous = _state["seconds"]
    _state["seconds"] = seconds if previous is None else (1.0 - SMOOTHING) * previous + SMOOTHING * seconds


def install() -> None:
    """Add the two draw handlers (once); nothing in background mode, where nothing is drawn."""
    if _handles or bpy.app.background:
        return
    _handles.append(bpy.types.SpaceView3D.draw_handler_add(_draw_started, (), "WINDOW", "PRE_VIEW"))
    _handles.append(bpy.types.SpaceView3D.draw_handler_add(_draw_ended, (), "WINDOW", "POST_PIXEL"))


def uninstall() -> None:
    """Remove the handlers and forget the measurement."""
    while _handles:
        bpy.types.SpaceView3D.draw_handler_remove(_handles.pop(), "WINDOW")
    _state.update(start=None, seconds=None)
