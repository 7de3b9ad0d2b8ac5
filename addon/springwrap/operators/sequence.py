"""Wrap over a frame range: ``springwrap.wrap_sequence`` wraps the layout onto its target at every frame of a
range (the target as evaluated at that frame, or a collection's object per frame), each frame from the
previous frame's result, and writes one shape key per frame, keyed so that playback shows the layout following.

Interactively (``invoke`` in a window) it is modal: one frame per timer event, the progress in the window
manager's indicator, the status bar and the 3D view's header; Esc or right-click stops after the frame in hand
and keeps the frames done (each frame is written whole or not at all). From scripts and in background mode it
runs to the end at once. Either way the whole sequence is one undo step. The work is in
``blender.wrap_sequence.SequenceRun`` and ``core.sequence.SequenceLoop``.
"""

import bpy

from .. import property_kinds as props
from ..blender import follow, point_cache
from ..blender.edit_mode import EditModeGuard, object_mode
from ..blender.wrap_sequence import SequenceRun
from ..core import sequence
from ..core.errors import ERRORS, LayoutError
from ..core.sequence import SequenceLoop
from ..core.wrap_inputs import WrapParameters
from ..properties import (
    SEQUENCE_SOURCE_ITEMS,
    WRAP_DEFAULTS,
    WRAP_SCHEDULE_ITEMS,
    max_iterations_property,
    retired_solver_property,
)
from .base import (
    LayoutOperator,
    check_inputs,
    end_modal_display,
    layout_problem,
    report_retired_solver,
    show_modal_status,
)
from .wrap import TIMER_SECONDS


class SPRINGWRAP_OT_wrap_sequence(LayoutOperator, bpy.types.Operator):
    """Wrap the layout at each frame of a range, each from the last, one shape key a frame (Esc keeps the frames done)"""

    bl_label = "Wrap Sequence"

    use_scene_range: props.flag("Scene Range", "Wrap the scene's frame range (off: Start and End)", True)
    frame_start: props.integer("Start", "First frame to wrap (with Scene Range off)", 1, min=-1_048_574)
    frame_end: props.integer("End", "Last frame to wrap (with Scene Range off)", 250, min=-1_048_574)
    source: props.choice("Source", "Where each frame's target comes from", SEQUENCE_SOURCE_ITEMS, "TARGET")
    collection: props.text("Collection", "Collection of one mesh object per frame (Source: Collection)")
    warm_rest: props.choice(
        "Later Frames",
        "Where the wrap of each frame after the first starts",
        (
            (
                "PREVIOUS",
                "Previous Frame",
                "Start from the previous frame's result and settle it onto the change alone: quick and steady",
            ),
            (
                "TEMPLATE",
                "Template",
                "Wrap every frame anew from the layout as it was, as a single wrap of that frame would: no frame "
                "depends on another (for frames that do not follow each other), but slower and less steady",
            ),
        ),
        "PREVIOUS",
    )
    max_iterations: max_iterations_property("Stop each frame's wrap after this many iterations")
    solver: retired_solver_property()
    schedule: props.choice("Schedule", "How the wrap's stiffness relaxes", WRAP_SCHEDULE_ITEMS, WRAP_DEFAULTS.schedule)

    def frames(self, scene) -> list[int]:
        start, end = (
            (scene.frame_start, scene.frame_end) if self.use_scene_range else (self.frame_start, self.frame_end)
        )
        return sequence.frame_range(start, end, 1)

    def _collection(self):
        if self.source != "COLLECTION":
            return None
        collection = bpy.data.collections.get(self.collection)
        if collection is None:
            raise LayoutError(f"No collection '{self.collection}': pick the collection of one object per frame")
        return collection

    def _start(self, context) -> SequenceRun | None:
        problem = layout_problem(context, require_target=self.source == "TARGET")
        if problem is not None:
            self.report({"ERROR"}, problem)
            return None
        layout = context.active_object
        try:
            check_inputs(context, layout, with_target=self.source == "TARGET")
            report_retired_solver(self, layout)
            settings = WRAP_DEFAULTS.replace(schedule=self.schedule)
            parameters = WrapParameters(max_iterations=self.max_iterations, settings=settings)
            return SequenceRun(
                context, layout, parameters, self.frames(context.scene), self._collection(), self.warm_rest
            )
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return None

    def _first_frame(self, run: SequenceRun) -> bool:
        """Wrap the first frame (an ordinary wrap); False after reporting why it failed (nothing written)."""
        try:
            run.advance()
        except Exception as error:  # noqa: BLE001 - the first frame failed: nothing was written
            self.report({"ERROR"}, f"The first frame ({run.frames[0]}) failed, nothing was written: {error}")
            return False
        return True

    def execute(self, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            self.report({"ERROR"}, layout_problem(context) or "No active mesh object (the layout)")
            return {"CANCELLED"}
        with object_mode(layout), follow.paused():
            run = self._start(context)
            if run is None or not self._first_frame(run):
                return {"CANCELLED"}
            while not run.done:
                run.advance()
            result = run.finish()
        self._report_result(result)
        return {"FINISHED"}

    def invoke(self, context, event):
        layout = context.active_object
        if bpy.app.background or context.window is None or layout is None or layout.type != "MESH":
            return self.execute(context)  # at once (scripts, background mode), or it reports why not
        mode = EditModeGuard(layout)
        run = self._start(context)
        if run is None:
            mode.restore()
            return {"CANCELLED"}
        self._mode = mode
        self._loop = SequenceLoop(run)
        follow.pause()
        self._area = context.area
        window_manager = context.window_manager
        window_manager.progress_begin(0, len(run.frames))
        show_modal_status(self, context, run.status_text(), 0)
        if not self._first_frame(run):
            self._end(context)
            return {"CANCELLED"}
        if run.done:
            self._loop.handle("TIMER")
            self._end(context)
            return self._finished()
        self._timer = window_manager.event_timer_add(TIMER_SECONDS, window=context.window)
        window_manager.modal_handler_add(self)
        show_modal_status(self, context, run.status_text(), len(run.outcomes))
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        outcome = self._loop.handle(event.type, event.value)
        if outcome == "PASS_THROUGH":
            return {"PASS_THROUGH"}
        if outcome == "RUNNING_MODAL":
            if event.type == "TIMER":
                run = self._loop.run
                show_modal_status(self, context, run.status_text(), len(run.outcomes))
            return {"RUNNING_MODAL"}
        self._end(context)
        return self._finished()

    def cancel(self, context):
        """Blender ends the modal from outside (window closed, file loaded): keep the frames done."""
        loop = getattr(self, "_loop", None)
        if loop is not None and loop.state == "RUNNING_MODAL":
            loop.stop()
            try:
                self._end(context)
            except RuntimeError:
                pass

    def _end(self, context) -> None:
        follow.resume()
        end_modal_display(self, context)
        mode = getattr(self, "_mode", None)
        if mode is not None:
            mode.restore()

    def _finished(self) -> set:
        self._report_result(self._loop.result)
        return {"FINISHED"}

    def _report_result(self, result) -> None:
        self.report({"WARNING"} if result.failed else {"INFO"}, result.summary())
        for outcome in result.failed[:5]:
            self.report({"WARNING"}, f"Frame {outcome.frame} failed: {outcome.message}")


FORMAT_ITEMS = (
    ("ALEMBIC", "Alembic", "An Alembic file (.abc): vertex positions sampled per frame"),
    ("USD", "USD", "A USD file (.usdc): the mesh's points sampled per frame"),
)
"""The point-cache formats Export Point Cache writes (``blender.point_cache.FORMATS``)."""


class SPRINGWRAP_OT_export_sequence(LayoutOperator, bpy.types.Operator):
    """Export the layout's sequence (the frames of its Wrap keys) as an Alembic or USD point cache"""

    bl_label = "Export Point Cache"
    bl_options = {"REGISTER"}  # writes a file, changes nothing in the scene
    requires_target = False

    filepath: props.text("File Path", "Where to write the point cache", subtype="FILE_PATH")
    file_format: props.choice(
        "Format", "The point cache's file format (Blender's own exporter)", FORMAT_ITEMS, "ALEMBIC"
    )

    def execute(self, context):
        layout = context.active_object
        try:
            path, frames = point_cache.export_point_cache(context, layout, self.filepath, self.file_format)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Exported '{layout.name}' over frames {frames[0]}-{frames[-1]} to {path}")
        return {"FINISHED"}

    def invoke(self, context, event):
        layout = context.active_object
        if not self.filepath:
            self.filepath = bpy.path.ensure_ext(bpy.path.clean_name(layout.name), ".abc")
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


classes = (SPRINGWRAP_OT_wrap_sequence, SPRINGWRAP_OT_export_sequence)
