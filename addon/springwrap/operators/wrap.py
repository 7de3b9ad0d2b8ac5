"""The wrap (paper, section 2.5): the whole layout drawn onto the target, keeping the template's shape.

``springwrap.wrap`` hands the layout (its faces, edges and seams, its face-point state and world
positions), its anchors and the evaluated target to the kernel's ``WrapSolver`` (one energy whose weights
are the paper's: fairness, arc length, thin plate, constraint, folding) and steps it until its stiffness
schedule ends or it reaches the iteration limit.

- Interactively (``invoke`` in a window) it is a modal operator. The first frame solves in ``invoke``
  itself, paced from the viewport's measured draw time (``ui.frame_clock``, ``core.wrap_run.FramePacer``):
  a wrap that fits in it finishes there, with no redraw in between. The rest solves in a worker thread
  (``WrapSession.start_worker``); each timer event writes the newest positions it solved into the layout
  mesh, so the viewport shows it settling (paper, Figure 12) at the display's own rate, and shows the
  progress in the status bar and the panel. Esc or right-click stops the worker after its iteration in
  progress and puts positions and state back bit for bit; finishing keeps the result as one undo step.
  With the pair tool running on the layout, its clicks and keys (and Esc or right-click during its drag) are let
  through to it: the pairs it edits go to the running solver (``WrapSession.move_anchors``) and stay as edited.
- In background mode, or with ``EXEC_DEFAULT`` (scripts), it runs to the end at once and writes once.

The logic is in two plain classes that need no window or events: ``blender.wrap_session.WrapSession``
(read, step, write frames, finish, cancel) and ``core.wrap_run.WrapLoop`` (the modal's state machine:
events in, operator results out), so tests drive them directly.
"""

import bpy

from .. import property_kinds as props
from ..blender import live_wraps, wrap_reads, wrap_session
from ..blender.edit_mode import EditModeGuard, object_mode
from ..blender.wrap_session import WrapSession
from ..core import defaults, input_policy, mirror_seam, mirroring, quality, transforms
from ..core.errors import ERRORS
from ..core.transforms import matrix_array
from ..core.wrap_inputs import WrapParameters
from ..core.wrap_run import WrapLoop, WrapResult
from ..properties import (
    WRAP_DEFAULTS,
    WRAP_RANGES,
    WRAP_SCHEDULE_ITEMS,
    max_iterations_property,
    retired_solver_property,
    shape_keys_property,
    tolerance_property,
    wrap_weight_property,
)
from ..ui import frame_clock
from .base import (
    LayoutOperator,
    check_inputs,
    end_modal_display,
    layout_problem,
    report_retired_solver,
    report_storage_precision,
    show_modal_status,
)

TIMER_SECONDS = 0.01
"""Interval of the modal's timer: a frame starts as soon as the previous one is drawn."""


class SPRINGWRAP_OT_wrap(LayoutOperator, bpy.types.Operator):
    """Wrap the layout onto the target: its anchors and the surface draw it on, keeping the template's shape (Esc cancels)"""

    bl_label = "Wrap"

    max_iterations: max_iterations_property("Stop after this many iterations if it has not converged by then")
    tolerance: tolerance_property()
    fairness: wrap_weight_property(
        "fairness",
        "Fairness",
        "Weight of the second differences along the layout's grid lines (the paper's alpha): higher keeps the "
        "template's bends and steps closer, 0 to 1",
    )
    arc_length: wrap_weight_property(
        "arc_length",
        "Arc Length",
        "Weight of the edges' lengths and directions against the template's (the paper's beta): the spacing along "
        "the grid lines, 0 to 1",
    )
    thin_plate: wrap_weight_property(
        "thin_plate",
        "Thin Plate",
        "Weight of the smoothness at points no grid line runs straight through (poles, triangles): the surface "
        "continues smoothly around them, 0 to 0.5",
    )
    constraint: wrap_weight_property(
        "constraint",
        "Constraint",
        "Pull of the layout onto the target (the energy's data term): higher fits the surface closer, lower keeps "
        "the template's shape, 0 to 1",
    )
    folding: wrap_weight_property(
        "folding",
        "Folding",
        "How far off the surface the layout is still drawn onto it (the data term's reach); 0 draws nothing on, 0 to 1",
    )
    solver: retired_solver_property()
    schedule: props.choice("Schedule", "How the wrap's stiffness relaxes", WRAP_SCHEDULE_ITEMS, WRAP_DEFAULTS.schedule)
    spring_resolution: bpy.props.IntProperty(
        name="Spring Resolution",
        description="Above 1: relax the layout, then relax again with every quad cut into this many by this many "
        "springs (coarse to fine), and read the layout's vertices back",
        default=defaults.SPRING_RESOLUTION,
        **WRAP_RANGES["spring_resolution"].keywords(),
    )
    stiffness_group: props.text(
        "Stiffness Group",
        "Layout vertex group of per-vertex stiffness (weight 0 follows the target freely, 0.5 as the others, 1 "
        "keeps the template's shape); empty: the layout's Stiffness setting",
    )
    free_group: props.text(
        "Free Group",
        "Layout vertex group without a pull toward the target (sockets, teeth); empty: the layout's Free setting",
    )
    hold_plane: props.choice(
        "Hold on Plane",
        "Keep the vertices that lie on this plane of the layout (or of the panel's Mirror Object) on it "
        "during the wrap: surface one half of a symmetric model with its midline on the plane, then Mirror",
        (
            ("NONE", "None", "No plane: every vertex is free"),
            ("X", "X", "The plane x = 0 of the layout (or of the Mirror Object)"),
            ("Y", "Y", "The plane y = 0 of the layout (or of the Mirror Object)"),
            ("Z", "Z", "The plane z = 0 of the layout (or of the Mirror Object)"),
        ),
        "NONE",
    )
    shape_keys: shape_keys_property(
        "A layout with shape keys: wrap its basis and carry the other keys over onto the wrapped shape, or refuse it"
    )

    def parameters(self):
        """The operator's properties as ``wrap_inputs.WrapParameters``.

        The kernel checks the settings here: a value out of its range raises
        ``springwrap_kernel.InvalidArgumentError`` naming it.
        """
        names = (
            "tolerance",
            "fairness",
            "arc_length",
            "thin_plate",
            "constraint",
            "folding",
            "schedule",
        )
        return WrapParameters(
            max_iterations=self.max_iterations,
            settings=WRAP_DEFAULTS.replace(**{name: getattr(self, name) for name in names}),
            spring_resolution=self.spring_resolution,
            stiffness_group=self.stiffness_group,
            free_group=self.free_group,
        )

    def _find_midline(self, layout, reads) -> None:
        """Without Hold on Plane, remember the plane of the layout (or its Mirror Object) its open border lies on, if
        any (a half's midline), to say after the wrap what Hold on Plane is for."""
        self._midline = None
        topology = reads.topology
        if self.hold_plane != "NONE" or topology.face_sizes.size == 0:
            return
        owner = layout.springwrap.mirror_object or layout
        open_edges = mirror_seam.border_edges(mirror_seam.face_edges(topology.face_corners, topology.face_sizes))
        if open_edges.size == 0:
            return
        matrix = matrix_array(owner.matrix_world)
        if not transforms.is_invertible(matrix):
            return
        world = transforms.world_positions(reads.arrays)
        planes = [(axis, mirroring.plane_from_matrix(matrix, axis)) for axis in mirroring.AXES]
        self._midline = mirror_seam.midline_plane(
            world, open_edges, topology.edges, planes, mirroring.DEFAULT_WELD_FRACTION
        )

    def _plane_holder(self, layout, reads, extent):
        """``adjust_inputs`` for :class:`WrapSession` holding the midline on ``hold_plane``; None without one."""
        if self.hold_plane == "NONE":
            return None
        owner = layout.springwrap.mirror_object or layout
        plane = mirroring.plane_from_matrix(matrix_array(owner.matrix_world), self.hold_plane)
        input_policy.check_plane(plane.point, plane.normal, owner.name, extent)
        world = transforms.world_positions(reads.arrays)
        edges = reads.topology.edges
        return lambda inputs: mirroring.held_on_plane(inputs, world, edges, plane)

    # A string: typing's cache would keep Optional[WrapSession] (and through it this module) alive until
    # after Python finalizes, and the PyPI bpy 4.2 module then crashes on exit freeing the operator class.
    def _start(self, context, display_seconds: float | None = None) -> "WrapSession | None":
        """Check, then build the session (in object mode); None after reporting why not."""
        problem = layout_problem(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return None
        try:
            layout = context.active_object
            live_wraps.take_over(context, layout)  # one wrap per layout: the pair tool's re-settle kept, or refused
            reads = wrap_reads.read(context, layout)  # once: checked here, then handed to the session
            extent = check_inputs(
                context, layout, arrays=reads.arrays, target=reads.target, anchors=reads.anchors, curves=reads.curves
            )
            self._find_midline(layout, reads)
            return WrapSession(
                context,
                layout,
                self.parameters(),
                reads=reads,
                adjust_inputs=self._plane_holder(layout, reads, extent),
                display_seconds=display_seconds,
                shape_keys=self.shape_keys,
            )
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return None

    def execute(self, context):
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            self.report({"ERROR"}, layout_problem(context) or "No active mesh object (the layout)")
            return {"CANCELLED"}
        with object_mode(layout):
            session = self._start(context)
            if session is None:
                return {"CANCELLED"}
            try:
                session.run()
                result = session.finish()
            except Exception as error:  # noqa: BLE001 - restore whatever was written, then report
                session.cancel()
                self.report({"ERROR"}, f"The wrap failed: {error}")
                return {"CANCELLED"}
            report_storage_precision(self, layout, session.target.extent, session.written_positions)
        self._report_result(result, session)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        layout = context.active_object
        if layout is None or layout.type != "MESH":
            return self.execute(context)  # reports why
        self._mode = EditModeGuard(layout)
        session = self._start(context, display_seconds=frame_clock.display_seconds())
        if session is None:
            self._restore_mode()
            return {"CANCELLED"}
        self._loop = WrapLoop(session)
        outcome = self._loop.handle("TIMER")  # the first frame, before any redraw: it may be the whole wrap
        if outcome != "RUNNING_MODAL":
            self._restore_mode()
            return self._ended(outcome)
        session.start_worker()  # the rest solves off the main thread, which only draws and answers events
        self._area = context.area  # the header to write in; events may come with another area as context
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(TIMER_SECONDS, window=context.window)
        window_manager.progress_begin(0, session.parameters.max_iterations)
        window_manager.modal_handler_add(self)
        wrap_session.set_running(session)
        self._show_status(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type != "TIMER" and live_wraps.tool_takes(self._loop.session.layout, event.type, event.value):
            return {"PASS_THROUGH"}  # the pair tool edits the anchors while the wrap runs (it hands them over)
        frames = self._loop.session.frames
        outcome = self._loop.handle(event.type, event.value)
        if outcome == "RUNNING_MODAL":
            if event.type == "TIMER" and self._loop.session.frames != frames:  # a new frame was written
                self._show_status(context)
            return {"RUNNING_MODAL"}
        if outcome == "PASS_THROUGH":
            return {"PASS_THROUGH"}
        self._end(context)
        return self._ended(outcome)

    def _ended(self, outcome: str) -> set:
        """Report how the wrap ended (``'FINISHED'`` or ``'CANCELLED'``) and return the operator's result."""
        if outcome == "FINISHED":
            session = self._loop.session
            report_storage_precision(self, session.layout, session.target.extent, session.written_positions)
            self._report_result(self._loop.result, session)
            return {"FINISHED"}
        if self._loop.error is not None:
            self.report({"ERROR"}, f"The wrap failed and was undone: {self._loop.error}")
        else:
            self.report({"INFO"}, "Wrap cancelled: the layout is back as it was")
        return {"CANCELLED"}

    def cancel(self, context):
        """Blender ends the modal wrap from outside (window closed, file loaded): restore the layout."""
        loop = getattr(self, "_loop", None)
        if loop is not None and loop.state == "RUNNING_MODAL":
            loop.cancel()
            try:
                self._end(context)
            except RuntimeError:  # the context may no longer allow a mode switch; the data is restored
                pass

    def _show_status(self, context) -> None:
        session = self._loop.session
        show_modal_status(self, context, session.status_text(), session.total_iterations)
        screen = context.screen
        if screen is not None:
            for area in screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()

    def _end(self, context) -> None:
        """Remove the timer, the status text and the progress, and go back to edit mode if the layout was in it."""
        loop = getattr(self, "_loop", None)
        if loop is not None:
            wrap_session.set_running(loop.session, running=False)
            if loop.session.pacer.display_seconds is not None:  # the next wrap starts from the whole redraw's cost
                frame_clock.record(loop.session.pacer.display_seconds)
        end_modal_display(self, context)
        live_wraps.refresh_tool()  # the pair tool's status, in the header the wrap's progress cleared
        self._restore_mode()

    def _restore_mode(self) -> None:
        mode = getattr(self, "_mode", None)
        if mode is not None:
            mode.restore()

    def _report_result(self, result: WrapResult, session: WrapSession) -> None:
        """Report ``result`` (what ``session`` wrote); warn when the retired spring solver was asked for."""
        wrap_session.remember_result(result)
        report_midline(self, session)
        self.report({"INFO"} if result.converged else {"WARNING"}, result.summary())
        if result.readout is not None:
            self.report({"INFO"}, quality.report_line(result.readout))
        if result.parts:
            self.report({"INFO"}, result.parts)
        detached, reattached = result.topology_detached_count, result.topology_reattached_count
        if detached or reattached or result.anchors_detached_count:
            self.report(
                {"WARNING"},
                f"Target topology changed: {detached} face-points and {result.anchors_detached_count} face anchors "
                f"lost their target face and became space-points, {reattached} face-points re-attached",
            )
        report_retired_solver(self, bpy.data.objects.get(result.layout_name))


def report_midline(operator, session: WrapSession) -> None:
    """Say how far the wrap moved a half's midline off its plane (``operator._midline``, found before the wrap) and
    what Hold on Plane is for; from the positions ``session`` wrote (nothing read back)."""
    midline = getattr(operator, "_midline", None)
    if midline is None or session.written_positions is None:
        return
    axis, plane, vertices = midline
    world = transforms.transform_points(session.matrix_world, session.written_positions)
    drift = float(abs(mirroring.signed_distances(world[vertices], plane)).max())
    operator.report(
        {"INFO"},
        f"The layout's open border lies on its {axis} plane ({vertices.size} vertices: a half's midline?); the wrap "
        f"moved it up to {drift:.3g} off the plane. To mirror this half, wrap it with Hold on Plane {axis}: the "
        "midline then stays on the plane (Mirror also brings it back onto the plane and re-settles the border)",
    )


classes = (SPRINGWRAP_OT_wrap,)
