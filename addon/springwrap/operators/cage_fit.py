"""The subdivision cage fit: ``springwrap.fit_subdivision`` moves the layout so that its Catmull–Clark
subdivision, as Blender's Subdivision Surface modifier computes it, lies on the target.

Everything is computed first (``blender.cage_fit`` and ``core.cage_fit``); the layout is written only when
the fit succeeded, and any problem is reported with the layout left exactly as it was.
"""

import time

import bpy

from .. import property_kinds as props
from ..blender import cage_fit as cage_fit_data
from ..blender import last_run
from ..blender import layout as layout_data
from ..blender import target as target_data
from ..blender.edit_mode import EditModeGuard, object_mode
from ..core import cage_fit
from ..core.errors import ERRORS
from ..properties import max_distance_property
from .base import (
    LayoutOperator,
    check_inputs,
    end_modal_display,
    open_layout,
    operator_values,
    report_storage_precision,
    show_modal_status,
)

_DEFAULTS = cage_fit.fit_defaults()


class SPRINGWRAP_OT_fit_subdivision(LayoutOperator, bpy.types.Operator):
    """Move the layout (the cage) so that its subdivided surface, as the Subdivision Surface modifier computes it, lies on the target instead of shrinking inside it"""

    bl_label = "Fit Subdivision Surface"

    last_outcome = None
    """The last successful fit's ``core.cage_fit.CageFitOutcome`` (for scripts: the distances before and after)."""

    levels: props.integer(
        "Levels",
        "Subdivision level whose surface is fitted (use the same on the Subdivision Surface modifier)",
        cage_fit.DEFAULT_LEVELS,
        soft_min=1,
        soft_max=int(_DEFAULTS["max_levels"]),
    )  # no hard range: Blender would clamp a script's levels=99 silently; the fit refuses it naming the range
    rounds: props.integer(
        "Rounds",
        "Gauss-Newton rounds: each matches the subdivided surface to the target and solves for the cage",
        cage_fit.DEFAULT_ROUNDS,
        min=1,
        max=50,
    )
    boundary_smooth: props.choice(
        "Boundary Smooth",
        "The modifier's Boundary Smooth: how the corners of open borders are subdivided",
        cage_fit.BOUNDARY_ITEMS,
        "ALL",
    )
    smoothness: props.number(
        "Smoothness",
        "How strongly each round's move of the cage is kept smooth (it also carries the fit over holes)",
        float(_DEFAULTS["smoothness"]),
        min=0.0,
        soft_max=10.0,
    )
    max_distance: max_distance_property(
        "Subdivided points farther than this from the target are not pulled to it (0 = unlimited)"
    )
    only_selected: props.flag(
        "Only Selected", "Move the selected vertices only (the others are held, as anchored vertices always are)", False
    )

    def execute(self, context):
        layout = open_layout(self, context, moves_vertices=True)
        if layout is None:
            return {"CANCELLED"}
        start = time.perf_counter()
        try:
            with object_mode(layout):
                extent = check_inputs(context, layout, frozenset({"positions", "anchors"}))
                session = self._session(context, layout).start()
                while not session.done:
                    session.step()
                outcome = session.finish()
                report_storage_precision(self, layout, extent)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        return self._finished(layout, outcome, start)

    def _session(self, context, layout):
        parameters = operator_values(self, cage_fit_data.CageFitParameters, boundary="boundary_smooth")
        target = target_data.read_target(context.evaluated_depsgraph_get(), layout)
        return cage_fit_data.CageFitSession(context, layout, target, parameters)

    def _finished(self, layout, outcome, start: float) -> set:
        type(self).last_outcome = outcome
        milliseconds = (time.perf_counter() - start) * 1000.0
        last_run.remember_fit(layout.name, self.levels, outcome)
        self.report({"INFO"}, cage_fit.summary(outcome, self.levels, milliseconds))
        return {"FINISHED"}

    def invoke(self, context, event):
        """In the interface a fit estimated longer than ``core.cage_fit.MODAL_SECONDS`` runs round by round: the
        progress in the header and the status bar; Esc stops it, inside a round too, with the layout as it was
        before the fit."""
        if bpy.app.background or context.window is None:
            return self.execute(context)
        layout = open_layout(self, context, moves_vertices=True)
        if layout is None:
            return {"CANCELLED"}
        self._start_time = time.perf_counter()
        self._mode = EditModeGuard(layout)
        try:
            self._extent = check_inputs(context, layout, frozenset({"positions", "anchors"}))
            self._fit = self._session(context, layout)
            estimate = cage_fit.fit_size(
                layout_data.read_layout_topology(layout).face_sizes, self.levels
            ).seconds * max(int(self.rounds), 1)
            if estimate <= cage_fit.MODAL_SECONDS:
                self._mode.restore()
                return self.execute(context)
            self._fit.start()
        except ERRORS as error:
            self._mode.restore()
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self._area = context.area
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(0.01, window=context.window)
        window_manager.progress_begin(0, self._fit.run.rounds)
        window_manager.modal_handler_add(self)
        self._show_status(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._fit.cancel()
            self._end(context)
            self.report({"INFO"}, "Fit Subdivision stopped: the layout is as it was")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            self._fit.tick()  # the round's kernel part runs in a worker thread: Esc stops it inside the round
            if not self._fit.done:
                self._show_status(context)
                return {"RUNNING_MODAL"}
            outcome = self._fit.finish()
            report_storage_precision(self, self._fit.layout, self._extent)
        except ERRORS as error:
            self._end(context)
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self._end(context)
        return self._finished(self._fit.layout, outcome, self._start_time)

    def cancel(self, context):
        """Blender ends the modal fit from outside (window closed, file loaded): nothing is written."""
        fit = getattr(self, "_fit", None)
        if fit is not None:
            fit.cancel()
            self._end(context)

    def _show_status(self, context) -> None:
        show_modal_status(self, context, self._fit.status_text(), self._fit.run.round)

    def _end(self, context) -> None:
        end_modal_display(self, context)
        self._mode.restore()


classes = (SPRINGWRAP_OT_fit_subdivision,)
