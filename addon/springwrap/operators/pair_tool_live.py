"""The pair tool's Live half (a mixin of ``operators.pair_tool``'s operator): the undo step of each edit, the Live
re-settle (started, advanced on the timer, kept, cancelled), and the edits made while a wrap runs on the layout (the
re-settle, or a live wrap of the Wrap operator) handed to its solver (``blender.pair_live``), a drag's at every
mouse move, with a drag's cancel (Esc, right-click)."""

import bpy

from ..blender import live_wraps, pair_live, wrap_session
from ..blender import pair_tool as pair_data
from ..core.errors import ERRORS
from ..ui import frame_clock

TIMER_SECONDS = 0.01
"""Interval of the Live re-settle's timer."""


class PairToolLive:
    """The pair tool operator's methods for undo steps and Live (its state: ``_settle``, ``_timer``, ``_dragging``,
    ``_drag_start``, ``_drag_settle``, ``_press``, ``_layout_name``, ``_area``; its ``_layout``, ``_status`` and
    ``_hover``)."""

    def _edited(self, context, name: str) -> None:
        """An edit is done: one undo step; with Live on, a re-settle starts from the layout as it is, unless one
        runs already (it was handed the edit)."""
        bpy.ops.ed.undo_push(message=f"Pair Tool: {name}")
        layout = self._layout()
        if layout is not None and layout.springwrap.pair_live and self._live() is None:
            self._start_settle(context)
        self._status(context)
        self._area.tag_redraw()

    def _start_settle(self, context) -> bool:
        """Start a Live re-settle from the layout as it is; whether it started (else reported why)."""
        try:
            self._settle = pair_data.start_settle(context, self._layout(), frame_clock.display_seconds())
        except ERRORS as error:
            self.report({"ERROR"}, f"Live: {error}")
            return False
        wrap_session.set_running(self._settle, hand_over=self._hand_over)
        if self._timer is None:
            self._timer = context.window_manager.event_timer_add(TIMER_SECONDS, window=context.window)
        return True

    def _hand_over(self, context) -> str | None:
        """Another wrap starts on the layout (``blender.live_wraps.take_over``: the Wrap button): the re-settle is
        kept as far as it got (one undo step, as before any edit it cannot take) and the tool's edits go to that
        wrap from now on; None, or why not now (a drag in progress: it is one undo step, the re-settle part of it)."""
        if self._dragging:
            return (
                f"The pair tool is dragging a pair of '{self._layout_name}' while its Live re-settle runs: release "
                "the pair, then start the wrap"
            )
        settle = self._settle
        try:
            self._finish_settle(context)
        except Exception as error:  # noqa: BLE001 - its solver failed: undone (the edits kept), the wrap starts
            self._settle = settle
            self._live_failed(context, error)
        return None

    def _live(self):
        """The running wrap an edit goes to: the re-settle, else a live wrap on the layout; None."""
        return pair_live.live_session(self._layout(), self._settle)

    def _live_takes_edit(self, context) -> bool:
        """Before an edit: whether it may go on. A running wrap that cannot take anchors moved while it runs is
        finished first when it is the re-settle (kept as it is, as before any edit); a live wrap that cannot
        (a plane held, soft pairs) refuses the edit."""
        session, layout = self._live(), self._layout()
        if session is None or pair_live.takes_edits(session, layout):
            return True
        if session is self._settle:
            self._finish_settle(context)
            return True
        self.report({"ERROR"}, f"The wrap running on '{layout.name}' cannot take moved anchors: edit them after it")
        return False

    def _send(self, context) -> None:
        """After an edit: hand the anchors as written to the running wrap (the newest wins); when it fails the
        re-settle is undone, the edit kept."""
        session = self._live()
        if session is None:
            return
        try:
            taken = pair_live.send(session, self._layout())
        except Exception as error:  # noqa: BLE001 - the solver's failure: undo the re-settle, keep the edit
            self._live_failed(context, error)
            return
        if not taken and session is self._settle:  # it can no longer take them: undone (the edit kept), then anew
            pair_live.cancel_keeping_anchors(session, self._layout())
            self._settle = None
            self._start_settle(context)

    def _live_failed(self, context, error) -> None:
        """The re-settle (or the live wrap) failed: the re-settle is undone, the edits kept, the tool goes on (a
        live wrap ends itself at its next frame, its anchors as last edited)."""
        if self._settle is None:
            self.report({"ERROR"}, f"The running wrap failed (the edits are kept): {error}")
            return
        self._cancel_settle(context)
        self.report({"ERROR"}, f"Live re-settle failed and was undone (the edits are kept): {error}")

    def _begin_drag(self, context) -> bool:
        """The first move of a drag: remember the pair to put back, check the running wrap takes edits, with Live
        on start a re-settle when none runs; whether the drag goes on."""
        layout = self._layout()
        if not self._live_takes_edit(context):
            return False
        self._drag_start = pair_live.remember(layout)
        self._drag_settle = False
        if layout.springwrap.pair_live and self._live() is None:
            self._drag_settle = self._start_settle(context)
        self._dragging = True
        live_wraps.set_tool(self._layout_name, dragging=True)
        self._status(context)
        return True

    def _cancel_drag(self, context, mouse) -> None:
        """Esc or right-click during a drag: the pair back where it was, the running wrap given the anchors as they
        were (a re-settle the drag started is cancelled: the layout back bit for bit); no undo step."""
        start, started_settle = self._drag_start, self._drag_settle
        self._press, self._dragging, self._drag_start = None, False, None
        live_wraps.set_tool(self._layout_name)
        layout = self._layout()
        if start is None or layout is None:
            return
        pair_live.put_back(layout, start)
        if started_settle:
            self._cancel_settle(context)
        else:
            self._send(context)
        self.report({"INFO"}, "Drag cancelled: the pair is back where it was")
        self._hover(context, mouse)
        self._status(context)

    def _advance_settle(self, context) -> None:
        if self._settle is None:
            return
        if self._dragging and self._settle.worker is None and self._settle.done:
            return  # it waits for the drag's next move (a drag is one undo step: no re-settle step inside it)
        frames = self._settle.frames
        try:
            pair_data.advance_settle(self._settle)
        except Exception as error:  # noqa: BLE001 - the solver failed: undo the re-settle, keep the edits
            self._live_failed(context, error)
            return
        if self._settle.done and not self._dragging:  # during a drag it waits for the next move (one undo step)
            self._finish_settle(context)
        elif self._settle.frames == frames:
            return  # the worker has solved nothing new since the last frame
        self._area.tag_redraw()

    def _finish_settle(self, context) -> None:
        """Keep a running re-settle as it is now (written for good, one undo step)."""
        settle, self._settle = self._settle, None
        if settle is None:
            return
        wrap_session.set_running(settle, running=False)
        result = settle.finish()
        wrap_session.remember_result(result)
        bpy.ops.ed.undo_push(message="Pair Tool: Live Re-settle")
        self._stop_timer(context)
        self._status(context)

    def _cancel_settle(self, context) -> None:
        """Drop a running re-settle, the layout put back bit for bit as it was before it, the anchors as they are."""
        settle, self._settle = self._settle, None
        if settle is None:
            return
        wrap_session.set_running(settle, running=False)
        try:
            pair_live.cancel_keeping_anchors(settle, self._layout() or settle.layout)
        except ReferenceError:  # the layout was deleted under the re-settle: nothing to put back
            pass
        self._stop_timer(context)
        self._status(context)

    def _stop_timer(self, context) -> None:
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
