"""Follow: a layout whose ``springwrap.follow`` is on re-settles by itself when its target changes (an edit, a
sculpt stroke, a modifier, a frame change: whatever :mod:`.target_changes` sees), from where it is and only
where the change concerns it (``core.follow``): the rest of the layout is held and written back bit for bit.

The handlers (``depsgraph_update_post``, ``frame_change_post``) only note which following layouts' targets
may have changed; the re-settle runs from a timer right after (never inside the depsgraph's evaluation), and
in the window it is an undo step of its own ("Follow"). :func:`settle_pending` runs the noted ones at once
(scripts, tests). A layout in edit mode, with a live wrap running, or while a sequence is being wrapped, waits.

What each layout's vertices measured against the target last time (their surface distances, and the target's
signature) is kept in memory; when it is not known (the file was just opened, Follow just turned on) the
quality read-out's distances written by the last wrap stand in, else nothing is taken as changed but the
face-points that moved.
"""

import contextlib

import bpy

import numpy as np

from ..core import defaults, follow, transforms
from ..core.errors import ERRORS
from ..core.quality import DISTANCE_ATTRIBUTE
from ..core.wrap_inputs import WrapParameters
from . import attributes, target_changes, wrap_session
from . import layout as layout_data
from . import target as target_data
from .wrap_session import WrapSession

_pending: set[str] = set()
"""Names of the following layouts whose target may have changed."""
_measured: dict[str, tuple[int, np.ndarray]] = {}
"""A layout's name -> (the moment it was measured, its vertices' surface distances then)."""
_paused = 0
"""Above 0 while a sequence (or anything else that moves the frame on its own) runs."""
_timer_registered = False

MAX_ITERATIONS = 200
"""The most iterations of one re-settle."""


def pause() -> None:
    """No re-settle until :func:`resume` (a sequence moves the frame itself)."""
    global _paused
    _paused += 1


def resume() -> None:
    """End a :func:`pause`; what changed meanwhile is forgotten."""
    global _paused
    _paused = max(_paused - 1, 0)
    _pending.clear()


@contextlib.contextmanager
def paused():
    """:func:`pause` while inside."""
    pause()
    try:
        yield
    finally:
        resume()


def followers(scene) -> list:
    """The scene's layouts that follow their target."""
    return [obj for obj in scene.objects if obj.type == "MESH" and obj.springwrap.follow and obj.springwrap.target]


def note_changes(scene) -> None:
    """Note the following layouts whose target may have changed since they were last measured."""
    if _paused:
        return
    for layout in followers(scene):
        measured = _measured.get(layout.name)
        if measured is None or not target_changes.unchanged_since(layout.springwrap.target, measured[0]):
            _pending.add(layout.name)
    if _pending and not bpy.app.background:
        _schedule()


def _schedule() -> None:
    global _timer_registered
    if not _timer_registered:
        _timer_registered = True
        bpy.app.timers.register(_on_timer, first_interval=0.0)


def _on_timer():
    global _timer_registered
    _timer_registered = False
    if settle_pending(bpy.context):
        _undo_step("Follow")
    return None


def _undo_step(message: str) -> None:
    """An undo step for what was just written, in the first window (a timer runs without one)."""
    windows = bpy.context.window_manager.windows
    if not windows:
        return
    with contextlib.suppress(RuntimeError), bpy.context.temp_override(window=windows[0]):
        bpy.ops.ed.undo_push(message=message)


def settle_pending(context) -> int:
    """Re-settle every noted layout that can be now; the number of layouts written."""
    if _paused:
        return 0
    written = 0
    for name in sorted(_pending):
        layout = bpy.data.objects.get(name)
        if layout is None or not layout.springwrap.follow or layout.springwrap.target is None:
            _pending.discard(name)
            continue
        if layout.mode != "OBJECT" or wrap_session.running_session(layout) is not None:
            continue  # waits: edit mode data is not the mesh's, a live wrap owns the layout
        _pending.discard(name)
        try:
            written += settle(context, layout)
        except ERRORS as error:
            print(f"Springwrap Follow: '{name}' could not follow its target: {error}")
    return written


def measure(context, layout) -> None:
    """Remember where ``layout``'s vertices are from its target now (Follow turned on, after a re-settle)."""
    moment = target_changes.moment()
    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    world = transforms.world_positions(layout_data.read_layout(layout))
    _measured[layout.name] = (moment, follow.surface_distances(target, world))


def _distances_before(layout, count: int) -> np.ndarray:
    measured = _measured.get(layout.name)
    if measured is not None and measured[1].shape[0] == count:
        return measured[1]
    readout = attributes.read_point_attribute(layout.data, DISTANCE_ATTRIBUTE, "FLOAT")
    if readout is not None and readout.shape[0] == count:
        return readout.astype(np.float64)
    return np.full(count, np.nan)


def settle(context, layout) -> int:
    """Re-settle ``layout`` onto its target where the change since it was last measured concerns it; 1 when
    the layout was written, 0 when nothing concerned it."""
    moment = target_changes.moment()
    target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
    arrays = layout_data.read_layout(layout)
    world = transforms.world_positions(arrays)
    same_topology = layout.springwrap.target_signature == target.signature
    edges = layout_data.read_layout_topology(layout).edges
    before = _distances_before(layout, world.shape[0])
    region, after = follow.changed_region(target, world, arrays.state, same_topology, before, edges)
    if not region.any():
        _measured[layout.name] = (moment, after)
        return 0
    settings = layout.springwrap
    parameters = WrapParameters(max_iterations=MAX_ITERATIONS, settings=_settings(settings))
    session = WrapSession(context, layout, parameters, target=target, region=region)
    try:
        session.run()
        session.finish()
        positions = follow.merged(layout_data.read_layout(layout).positions, arrays.positions, region)
        layout.data.vertices.foreach_set("co", positions.reshape(-1))
        layout.data.update()
    except Exception:
        session.cancel()
        raise
    measure(context, layout)
    return 1


def _settings(settings):
    """The kernel's default wrap settings with the panel's schedule (read from ``core.defaults``: the add-on's
    properties import this module for ``follow``'s update, so it imports nothing from them)."""
    return defaults.wrap_defaults().replace(schedule=settings.wrap_schedule)


def follow_changed(settings, context) -> None:
    """The Follow property's update: measure the layout now (turned on) or forget it (off)."""
    layout = settings.id_data
    _pending.discard(layout.name)
    if not settings.follow:
        _measured.pop(layout.name, None)
        return
    with contextlib.suppress(*ERRORS):
        if layout.mode == "OBJECT" and settings.target is not None:
            measure(context, layout)


@bpy.app.handlers.persistent
def _on_change(scene, _depsgraph=None) -> None:
    note_changes(scene)


_HANDLERS = (("depsgraph_update_post", _on_change), ("frame_change_post", _on_change))


def install() -> None:
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        if handler not in handlers:
            handlers.append(handler)


def uninstall() -> None:
    global _timer_registered
    for event, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, event)
        while handler in handlers:
            handlers.remove(handler)
    if _timer_registered and bpy.app.timers.is_registered(_on_timer):
        bpy.app.timers.unregister(_on_timer)
    _timer_registered = False
    _pending.clear()
    _measured.clear()
