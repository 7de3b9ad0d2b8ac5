"""The live wraps in progress and the last results, as the panel shows them (this Blender session only): which
``blender.wrap_session.WrapSession`` runs on a layout, and each layout's last wrap or mirror result."""

import bpy

from ..core.errors import LayoutError
from ..core.wrap_run import WrapResult, tool_event
from . import last_run

_running: list = []
_hand_overs: dict = {}
"""For a running session whose owner can end it when another wrap starts on its layout (the pair tool's Live
re-settle): the owner's ``hand_over(context)``, which ends it and returns None, or returns why it cannot now (see
:func:`take_over`)."""
_tool: dict = {"layout": None, "dragging": False, "refresh": None}
"""The tool editing a layout's anchors while a wrap may run on it (the pair tool): its layout's name, whether it
drags a pair's end, and how it writes its status again."""


def set_tool(layout_name: str | None, dragging: bool = False, refresh=None) -> None:
    """Say that a tool edits ``layout_name``'s anchors (None: no tool any more), and whether it drags now;
    ``refresh`` (kept until the tool goes): a callable writing the tool's status again (:func:`refresh_tool`)."""
    _tool.update(layout=layout_name, dragging=bool(layout_name) and dragging)
    if refresh is not None or layout_name is None:
        _tool["refresh"] = refresh


def refresh_tool() -> None:
    """Have the tool editing anchors write its status again: a live wrap's end cleared the header they share."""
    if _tool["refresh"] is not None:
        try:
            _tool["refresh"]()
        except (ReferenceError, RuntimeError):  # its area or layout went away meanwhile: it ends at its next event
            pass


def tool_takes(layout: bpy.types.Object, event_type: str, event_value: str) -> bool:
    """Whether a live wrap on ``layout`` lets an event through to the tool editing its anchors (``core.wrap_run.
    tool_event``): the tool's clicks and keys, and Esc or right-click while it drags (they cancel the drag)."""
    try:
        name = layout.name
    except ReferenceError:
        return False
    return _tool["layout"] == name and tool_event(event_type, event_value, _tool["dragging"])


def set_running(session, running: bool = True, hand_over=None) -> None:
    """Mark ``session`` as the live wrap in progress (the panel shows its progress), or no longer. ``hand_over``
    (optional): how its owner ends it when another wrap starts on the layout (:func:`take_over`)."""
    if session is None:
        return
    if running and session not in _running:
        _running.append(session)
        if hand_over is not None:
            _hand_overs[session] = hand_over
    elif not running and session in _running:
        _running.remove(session)
        _hand_overs.pop(session, None)


def take_over(context, layout: bpy.types.Object) -> None:
    """Make way for a wrap about to start on ``layout`` (one wrap per layout): the pair tool's Live re-settle
    running there is kept as far as it got (its owner finishes it: one undo step of its own) and the new wrap starts
    from that; any other wrap running there (a live wrap of the Wrap operator), or a re-settle its owner cannot end
    now (the tool is dragging a pair), refuses the new wrap with ``LayoutError`` saying why."""
    session = running_session(layout)
    if session is None:
        return
    hand_over = _hand_overs.get(session)
    if hand_over is None:
        raise LayoutError(
            f"A wrap is already running on '{layout.name}': let it finish, or press Esc to cancel it, then start "
            "another"
        )
    refusal = hand_over(context)
    if refusal is not None:
        raise LayoutError(refusal)
    set_running(session, running=False)  # ended by its owner (who says so too)


def running_session(layout: bpy.types.Object):
    """The live wrap in progress on ``layout``, if any."""
    for session in _running:
        try:
            if session.layout == layout:
                return session
        except ReferenceError:  # the layout was deleted under a session that was never ended
            set_running(session, running=False)
            return None
    return None


def remember_result(result: WrapResult, operation: str = "Wrap") -> None:
    """Keep a finished wrap's result (or the wrap of a mirror's, ``operation="Mirror"``) for the panel's Check
    section (``blender.last_run``: this Blender session only, by layout name)."""
    rows = (
        (f"Last {operation}", "Converged" if result.converged else "At the limit"),
        ("Iterations", str(result.iterations)),
        ("Time", f"{result.seconds:.2f} s"),
    )
    if result.frames:  # the live wrap: how much of that was solving, over how many redraws
        rows += (("Solving", f"{result.kernel_seconds:.2f} s"), ("Frames", str(result.frames)))
    last_run.remember(result.layout_name, last_run.LastRun(operation, result, rows))


def last_result(layout: bpy.types.Object) -> WrapResult | None:
    """The result of the last wrap (or mirror) on a layout of this name in this Blender session, if that is still
    what last changed the layout."""
    run = last_run.last(layout.name)
    return None if run is None else run.result


def forget_results() -> None:
    """Drop the remembered results and live wraps (the add-on is unregistered, another file is loaded); their worker
    threads are stopped."""
    for session in _running:
        session.stop_worker(raise_error=False)
    _running.clear()
    _hand_overs.clear()
    last_run.forget_all()


@bpy.app.handlers.persistent
def forget_results_on_load(_scene, _data=None) -> None:
    """``load_post`` handler: a result belongs to the file it was made in (layouts are found by name)."""
    forget_results()
