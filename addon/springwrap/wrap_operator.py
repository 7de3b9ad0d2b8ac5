"""The wrap (paper, section 2.5): springs pull the whole layout onto the target like a rubber sheet.

``springwrap.wrap`` hands the layout (its faces, edges and seams, its face-point state and world
positions), its anchors and the evaluated target to the kernel's ``WrapSolver`` and steps it until
it converges or reaches the iteration limit.

- Interactively (``invoke`` in a window) it is a modal operator: a timer steps the solver a few
  iterations at a time (as many as keep about 30 redraws per second), writes every frame into the
  layout mesh so the viewport shows it settling (paper, Figure 12), and shows its progress in the
  status bar. Esc or right-click cancels and puts positions and state back bit for bit; finishing
  keeps the result as one undo step.
- In background mode, or with ``EXEC_DEFAULT`` (scripts), it runs to the end at once and writes once.

The logic is in two plain classes that need no window or events: :class:`WrapSession` (read,
step, write frames, finish, cancel) and :class:`WrapLoop` (the modal's state machine: events in,
operator results out), so tests drive them directly.
"""

import math
import time
from typing import Callable, NamedTuple, Optional

import bpy
import numpy as np

from .operators import layout_problem
from .properties import WRAP_DEFAULTS, WRAP_SOLVER_ITEMS, max_iterations_property, tolerance_property

FRAME_RATE = 30.0
"""Redraws per second the modal wrap aims for."""
TIMER_SECONDS = 0.01
"""Interval of the modal's timer: a frame starts as soon as the previous one is drawn."""
SYNCHRONOUS_CHUNK = 100
"""Iterations per kernel call when the wrap runs to the end at once."""

CANCEL_EVENTS = frozenset({"ESC", "RIGHTMOUSE"})
"""Events (pressed) that cancel a modal wrap."""
NAVIGATION_EVENTS = frozenset(
    {
        "MIDDLEMOUSE",
        "WHEELUPMOUSE",
        "WHEELDOWNMOUSE",
        "WHEELINMOUSE",
        "WHEELOUTMOUSE",
        "MOUSEMOVE",
        "INBETWEEN_MOUSEMOVE",
        "TRACKPADPAN",
        "TRACKPADZOOM",
        "MOUSEROTATE",
        "MOUSESMARTZOOM",
        "NDOF_MOTION",
        "NUMPAD_0",
        "NUMPAD_1",
        "NUMPAD_2",
        "NUMPAD_3",
        "NUMPAD_4",
        "NUMPAD_5",
        "NUMPAD_6",
        "NUMPAD_7",
        "NUMPAD_8",
        "NUMPAD_9",
        "NUMPAD_PERIOD",
        "NUMPAD_PLUS",
        "NUMPAD_MINUS",
    }
)
"""Events a modal wrap lets through, so the view can be turned while it settles."""


def modal_action(event_type: str, event_value: str) -> str:
    """What the modal wrap does with an event: ``'CANCEL'``, ``'STEP'``, ``'PASS'`` (navigation) or ``'BLOCK'``."""
    if event_type in CANCEL_EVENTS and event_value == "PRESS":
        return "CANCEL"
    if event_type == "TIMER":
        return "STEP"
    if event_type in NAVIGATION_EVENTS:
        return "PASS"
    return "BLOCK"


class WrapResult(NamedTuple):
    """What a finished wrap did, for the report."""

    layout_name: str
    vertex_count: int
    iterations: int
    converged: bool
    max_displacement: float  # of the last iteration, fraction of the layout's size
    seconds: float  # wall time from the start of the wrap to its final write
    kernel_seconds: float  # time spent in the kernel's step
    frames: int  # frames written while it ran (0 when it ran at once)
    face_points: int
    space_points: int
    landed: int  # points that landed on their anchors or curve constraints (spring solver)
    folded: int  # points that folded onto the surface (spring solver) or landed at the end (energy solver)
    lifted: int
    solver: str  # 'SPRINGS' or 'ENERGY'
    fold_tolerance: float  # the annealed folding tolerance at the end, radians (spring solver)
    held_back: int  # points whose last step was shortened so that no face turned (energy solver)
    energy_decrease: float  # how much the last step lowered the energy, relative (energy solver; NaN otherwise)
    anchor_count: int
    unreliable_triangles: int
    topology_detached_count: int  # face-points whose target face was gone, made space-points
    topology_reattached_count: int
    anchors_detached_count: int  # face anchors whose target face was gone, made space anchors

    def summary(self) -> str:
        """One line: iterations, time, face / space points and what changed state."""
        ending = "converged" if self.converged else "stopped at the iteration limit"
        if self.solver == "ENERGY":
            details = f"{self.folded} landed at the end, {self.held_back} held back by the last step"
            if math.isfinite(self.energy_decrease):
                details += f", which lowered the energy by {100.0 * self.energy_decrease:.2g} %"
        else:
            details = (
                f"{self.landed} landed on anchors or curves, {self.folded} folded, {self.lifted} lifted off borders; "
                f"fold tolerance {math.degrees(self.fold_tolerance):.1f}°"
            )
        return (
            f"Wrapped '{self.layout_name}' in {self.iterations} iterations ({ending}), {self.seconds:.2f} s: "
            f"{self.face_points} face-points, {self.space_points} space-points ({details})"
        )


class WrapSession:
    """A wrap in progress on one layout, without any UI: read, step, write frames, then finish or cancel.

    The constructor reads and checks everything and builds the solver; it writes nothing (an error
    is raised as one of ``bridge.ERRORS`` and the scene is untouched). The layout must be in
    object mode for the whole session (the operator sees to it). ``parameters`` is an
    ``operations.WrapParameters``. ``adjust_inputs`` (optional) takes the prepared
    ``operations.WrapInputs`` and returns them changed (the mirror's pins and plane).
    """

    def __init__(self, context, layout: bpy.types.Object, parameters, adjust_inputs=None):
        from . import anchors, bridge, layout_state, operations

        self._bridge, self._operations, self._layout_state = bridge, operations, layout_state
        self.start_time = time.perf_counter()
        self.layout = layout
        self.parameters = parameters
        operations.check_wrap_parameters(parameters)
        if bridge.has_shape_keys(layout):
            raise layout_state.LayoutError(f"Layout '{layout.name}' has shape keys; Springwrap cannot move its vertices")
        settings = layout.springwrap
        arrays = bridge.read_layout(layout)
        if not layout_state.is_invertible(arrays.matrix_world):
            raise layout_state.LayoutError(
                f"Layout '{layout.name}' has zero scale: the wrap's world positions cannot be written back"
            )
        self.matrix_world = arrays.matrix_world
        self.target = bridge.read_target(context.evaluated_depsgraph_get(), layout)
        self.layout_topology = bridge.read_layout_topology(layout)
        structure = bridge.make_layout_structure(self.layout_topology)
        self.anchors, anchor_resolution = anchors.resolve(
            bridge.read_anchors(layout), self.target, settings.anchors_signature
        )
        unreliable = None
        if settings.unreliable_group:
            weights = bridge.read_vertex_group_weights(context, settings.target, settings.unreliable_group)
            if weights.shape[0] != self.target.mesh.vertex_count:
                raise layout_state.LayoutError(
                    f"Vertex group '{settings.unreliable_group}' has {weights.shape[0]} weights for a target of "
                    f"{self.target.mesh.vertex_count} vertices"
                )
            unreliable = operations.unreliable_triangles(self.target.mesh.triangles(), weights)
        curve_constraints = bridge.resolve_curve_constraints(
            context.evaluated_depsgraph_get(), layout, bridge.read_curve_constraints(layout)
        )
        # The template's shape as made: stored at the first change of the layout, else as it is now.
        rest = bridge.read_rest(layout)
        self.rest = arrays.positions if rest is None else rest
        inputs, resolution = operations.prepare_wrap(
            arrays, self.target, settings.target_signature, self.anchors, unreliable, curve_constraints, self.rest
        )
        inputs = self._vertex_groups(inputs, layout, parameters)
        if adjust_inputs is not None:
            inputs = adjust_inputs(inputs)
        self.solver = bridge.make_wrap_solver(self.target, structure, inputs, parameters)
        self.inputs = inputs
        # Coarse to fine: with a spring resolution above 1 the layout is relaxed first, then a grid
        # of its faces cut k x k (its own vertices first) takes over; the layout's vertices are read
        # back from it.
        self.stage = "coarse" if int(parameters.spring_resolution) > 1 else "fine"
        self.coarse_iterations = 0
        self.snapshot = bridge.take_snapshot(layout)
        self.vertex_count = arrays.positions.shape[0]
        self.unreliable_count = 0 if unreliable is None else int(unreliable.sum())
        self.topology = (resolution.detached_count, resolution.reattached_count, anchor_resolution.detached_count)
        self.pacer = operations.IterationPacer(FRAME_RATE)
        self.last_report = None
        self.kernel_seconds = 0.0
        self.frames = 0
        self.events = {"landed": 0, "folded": 0, "lifted": 0}
        self._frame_end: Optional[float] = None

    @property
    def stage_iterations(self) -> int:
        """Iterations run so far by the current stage's solver."""
        return 0 if self.last_report is None else self.last_report.total_iterations

    def _vertex_groups(self, inputs, layout, parameters):
        """``inputs`` with the Stiffness and Free groups (the operator's, else the layout's settings) read in."""
        settings = layout.springwrap
        stiffness_group = getattr(parameters, "stiffness_group", "") or settings.stiffness_group
        free_group = getattr(parameters, "free_group", "") or settings.free_group
        if not stiffness_group and not free_group:
            return inputs
        solver = WRAP_DEFAULTS.solver if parameters.settings is None else parameters.settings.solver
        if solver != "ENERGY":
            raise self._layout_state.LayoutError(
                "The Stiffness and Free groups need the Energy solver (the Springs solver has no per-vertex stiffness)"
            )
        if int(parameters.spring_resolution) > 1:
            raise self._layout_state.LayoutError("The Stiffness and Free groups need Spring Resolution 1")
        if stiffness_group:
            weights, member = self._bridge.read_layout_group(layout, stiffness_group)
            inputs = inputs._replace(stiffness=self._operations.group_stiffness(weights, member))
        if free_group:
            weights, member = self._bridge.read_layout_group(layout, free_group)
            inputs = inputs._replace(free_vertices=np.ascontiguousarray(member & (weights > 0.0)))
        return inputs

    @property
    def total_iterations(self) -> int:
        """Iterations run so far, both stages."""
        return self.coarse_iterations + self.stage_iterations

    @property
    def done(self) -> bool:
        """The last stage converged, or reached the iteration limit (each stage has it)."""
        if self.last_report is None or self.stage != "fine":
            return False
        return self.last_report.converged or self.stage_iterations >= self.parameters.max_iterations

    def step(self, iterations: int):
        """Run up to ``iterations`` kernel iterations (within the limit); the kernel's ``StepReport``.

        When the coarse stage ends, the next call starts the fine one.
        """
        if self.stage == "coarse" and self.last_report is not None and (
            self.last_report.converged or self.stage_iterations >= self.parameters.max_iterations
        ):
            self.refine()
        iterations = min(int(iterations), self.parameters.max_iterations - self.stage_iterations)
        start = time.perf_counter()
        report = self.solver.step(max(iterations, 0))
        self.kernel_seconds += time.perf_counter() - start
        for name in self.events:
            self.events[name] += getattr(report, name)
        self.last_report = report
        return report

    def refine(self) -> None:
        """End the coarse stage: a solver on the layout's faces cut k x k, started where the coarse one ended."""
        from . import subdivision

        start = time.perf_counter()
        fine = subdivision.subdivide(self.layout_topology, int(self.parameters.spring_resolution))
        inputs = self._operations.refine_wrap_inputs(
            self.inputs, fine, self.solver.positions(), self.solver.states(), self.target
        )
        structure = self._bridge.make_layout_structure(fine.topology)
        self.solver = self._bridge.make_wrap_solver(self.target, structure, inputs, self.parameters)
        self.kernel_seconds += time.perf_counter() - start
        self.coarse_iterations = self.stage_iterations
        self.fine_vertex_count = fine.topology.vertex_count
        self.last_report = None
        self.stage = "fine"

    def advance(self):
        """One frame of the interactive wrap: as many iterations as the frame allows, then write them.

        Writes positions and state into the layout mesh (no undo step). Returns the ``StepReport``.
        """
        begin = time.perf_counter()
        overhead = 0.0 if self._frame_end is None else min(begin - self._frame_end, 1.0)
        count = self.pacer.next_count(self.parameters.max_iterations - self.stage_iterations)
        report = self.step(count)
        stepped = time.perf_counter()
        self.write_frame()
        self._frame_end = time.perf_counter()
        self.pacer.record(report.iterations, stepped - begin, self._frame_end - stepped + overhead)
        self.frames += 1
        return report

    def run(self, progress: Optional[Callable] = None, chunk: int = SYNCHRONOUS_CHUNK):
        """Step to the end at once (converged or the limit), writing nothing; ``progress(report)`` after each chunk."""
        while not self.done:
            report = self.step(chunk)
            if progress is not None:
                progress(report)
        return self.last_report

    def current_layout(self):
        """(local positions float32 (N, 3), ``LayoutState``) of the solver now."""
        count = self.vertex_count  # a fine grid numbers the layout's own vertices first
        positions = self._operations.to_local(self.matrix_world, self.solver.positions()[:count])
        states, triangles, barycentrics = self.solver.states()
        return positions, self._layout_state.normalized_state(
            states[:count], triangles[:count], barycentrics[:count]
        )

    def write_frame(self) -> None:
        """Write the solver's current positions and state into the layout (an intermediate frame)."""
        positions, state = self.current_layout()
        self._bridge.write_wrap_frame(self.layout, positions, state)

    def finish(self) -> WrapResult:
        """Write the result for good: positions, state, the target signature and the resolved anchors."""
        if self.last_report is None:
            self.step(0)
        positions, state = self.current_layout()
        self._bridge.write_layout(self.layout, positions, state, rest=self.rest)
        settings = self.layout.springwrap
        settings.target_signature = self.target.signature
        if len(settings.anchors):
            self._bridge.write_anchors(self.layout, self.anchors, -1, self.target.signature)
        report = self.last_report
        face_points, space_points = self._layout_state.point_counts(state.states)
        detached, reattached, anchors_detached = self.topology
        return WrapResult(
            layout_name=self.layout.name,
            vertex_count=self.vertex_count,
            iterations=self.total_iterations,
            converged=bool(report.converged),
            max_displacement=float(report.max_displacement),
            seconds=time.perf_counter() - self.start_time,
            kernel_seconds=self.kernel_seconds,
            frames=self.frames,
            face_points=face_points,
            space_points=space_points,
            landed=self.events["landed"],
            folded=self.events["folded"],
            lifted=self.events["lifted"],
            solver=self.solver.settings.solver,
            fold_tolerance=float(report.fold_tolerance),
            held_back=int(report.held_back),
            energy_decrease=float(report.energy_decrease),
            anchor_count=int(self.anchors.vertex_indices.shape[0]),
            unreliable_triangles=self.unreliable_count,
            topology_detached_count=detached,
            topology_reattached_count=reattached,
            anchors_detached_count=anchors_detached,
        )

    def cancel(self) -> None:
        """Put the layout's positions and state attributes back exactly as they were at the start."""
        self._bridge.restore_snapshot(self.layout, self.snapshot)

    def status_text(self) -> str:
        """The progress line shown in the status bar."""
        report = self.last_report
        if report is None:
            return f"Springwrap: wrapping '{self.layout.name}'...  Esc / right-click: cancel"
        stage = ""
        if int(self.parameters.spring_resolution) > 1:
            stage = "coarse, " if self.stage == "coarse" else f"fine {self.parameters.spring_resolution}x, "
        return (
            f"Springwrap: {stage}iteration {report.total_iterations} / {self.parameters.max_iterations}, "
            f"{report.face_points} face-points, {report.space_points} space-points, "
            f"last move {report.max_displacement:.2e}  —  Esc / right-click: cancel"
        )


class WrapLoop:
    """The modal wrap's state machine: each event in, the operator's return value out.

    ``handle`` returns ``'RUNNING_MODAL'``, ``'PASS_THROUGH'``, ``'FINISHED'`` (the result is in
    :attr:`result`) or ``'CANCELLED'`` (by the user, or by an error kept in :attr:`error`); the
    layout is restored bit for bit on cancel and on any error. It needs no window.
    """

    def __init__(self, session: WrapSession):
        self.session = session
        self.result: Optional[WrapResult] = None
        self.error: Optional[BaseException] = None
        self.state = "RUNNING_MODAL"

    def handle(self, event_type: str, event_value: str = "NOTHING") -> str:
        """React to one event."""
        if self.state in ("FINISHED", "CANCELLED"):
            return self.state
        action = modal_action(event_type, event_value)
        if action == "PASS":
            return "PASS_THROUGH"
        if action == "CANCEL":
            return self.cancel()
        if action == "STEP":
            try:
                self.session.advance()
                if self.session.done:
                    self.result = self.session.finish()
                    self.state = "FINISHED"
                    return self.state
            except Exception as error:  # noqa: BLE001 - any failure mid-way must restore the layout
                self.error = error
                return self.cancel()
        return "RUNNING_MODAL"

    def cancel(self) -> str:
        """Stop a running wrap and restore the layout; a finished or cancelled one stays as it is."""
        if self.state == "RUNNING_MODAL":
            self.state = "CANCELLED"
            self.session.cancel()
        return self.state


def _error_types():
    from . import bridge

    return bridge.ERRORS


class SPRINGWRAP_OT_wrap(bpy.types.Operator):
    """Wrap the layout onto the target: springs with anchors pull it on like a rubber sheet (Esc cancels)"""

    bl_idname = "springwrap.wrap"
    bl_label = "Wrap"
    bl_options = {"REGISTER", "UNDO"}

    max_iterations: max_iterations_property("Stop after this many iterations if it has not converged by then")
    tolerance: tolerance_property(
        "Converged when no point moves more than this fraction of the layout's size in an iteration"
    )
    fairness: bpy.props.FloatProperty(
        name="Fairness",
        description="Straightens the layout's grid lines (paper's alpha), 0 to 1",
        default=WRAP_DEFAULTS.fairness,
        soft_min=0.0,
        soft_max=1.0,
    )
    arc_length: bpy.props.FloatProperty(
        name="Arc Length",
        description="Evens the spacing along the grid lines (paper's beta), 0 to 1",
        default=WRAP_DEFAULTS.arc_length,
        soft_min=0.0,
        soft_max=1.0,
    )
    thin_plate: bpy.props.FloatProperty(
        name="Thin Plate",
        description="Space-points continue the curvature of the surface around them (over holes), 0 to 0.5",
        default=WRAP_DEFAULTS.thin_plate,
        soft_min=0.0,
        soft_max=0.5,
    )
    constraint: bpy.props.FloatProperty(
        name="Constraint",
        description="Pull of anchored points toward their targets, 0 to 1",
        default=WRAP_DEFAULTS.constraint,
        soft_min=0.0,
        soft_max=1.0,
    )
    folding: bpy.props.FloatProperty(
        name="Folding",
        description="Pull of space-points next to face-points onto the surface, 0 to 1",
        default=WRAP_DEFAULTS.folding,
        soft_min=0.0,
        soft_max=1.0,
    )
    rest: bpy.props.EnumProperty(
        name="Rest Shape",
        description="What the springs consider relaxed",
        items=(
            ("TEMPLATE", "Template", "Keep the template's own spacing and curvature (its shape before the first snap, "
             "projection or wrap, or as set by Set Rest Shape)"),
            ("EVEN", "Even", "Straight, evenly spaced grid lines (Krishnamurthy & Levoy's springs)"),
        ),
        default=WRAP_DEFAULTS.rest,
    )
    solver: bpy.props.EnumProperty(
        name="Solver",
        description="The wrap's algorithm",
        items=WRAP_SOLVER_ITEMS,
        default=WRAP_DEFAULTS.solver,
    )
    spring_resolution: bpy.props.IntProperty(
        name="Spring Resolution",
        description="Above 1: relax the layout, then relax again with every quad cut into this many by this many "
        "springs (coarse to fine), and read the layout's vertices back",
        default=1,
        min=1,
        max=8,
    )
    stiffness_group: bpy.props.StringProperty(
        name="Stiffness Group",
        description="Layout vertex group of per-vertex stiffness (Energy solver: weight 0 follows the target freely, "
        "0.5 as the others, 1 keeps the template's shape); empty: the layout's Stiffness setting",
        default="",
    )
    free_group: bpy.props.StringProperty(
        name="Free Group",
        description="Layout vertex group without a pull toward the target (Energy solver: sockets, teeth); empty: the "
        "layout's Free setting",
        default="",
    )
    hold_plane: bpy.props.EnumProperty(
        name="Hold on Plane",
        description="Keep the vertices that lie on this plane of the layout (or of the panel's Mirror Object) on it "
        "during the wrap: surface one half of a symmetric model with its midline on the plane, then Mirror",
        items=(
            ("NONE", "None", "No plane: every vertex is free"),
            ("X", "X", "The plane x = 0 of the layout (or of the Mirror Object)"),
            ("Y", "Y", "The plane y = 0 of the layout (or of the Mirror Object)"),
            ("Z", "Z", "The plane z = 0 of the layout (or of the Mirror Object)"),
        ),
        default="NONE",
    )

    @classmethod
    def poll(cls, context):
        problem = layout_problem(context)
        if problem is not None:
            cls.poll_message_set(problem)
            return False
        return True

    def parameters(self):
        """The operator's properties as ``operations.WrapParameters``.

        The kernel checks the settings here: a value out of its range raises
        ``springwrap_kernel.InvalidArgumentError`` naming it.
        """
        from .operations import WrapParameters

        names = ("tolerance", "fairness", "arc_length", "thin_plate", "constraint", "folding", "rest", "solver")
        return WrapParameters(
            max_iterations=self.max_iterations,
            settings=WRAP_DEFAULTS.replace(**{name: getattr(self, name) for name in names}),
            spring_resolution=self.spring_resolution,
            stiffness_group=self.stiffness_group,
            free_group=self.free_group,
        )

    def _plane_holder(self, layout):
        """``adjust_inputs`` for :class:`WrapSession` holding the midline on ``hold_plane``; None without one."""
        if self.hold_plane == "NONE":
            return None
        from . import bridge, mirroring, operations

        owner = layout.springwrap.mirror_object or layout
        plane = mirroring.plane_from_matrix(bridge.matrix_array(owner.matrix_world), self.hold_plane)
        world = operations.world_positions(bridge.read_layout(layout))
        edges = bridge.read_layout_topology(layout).edges
        return lambda inputs: mirroring.held_on_plane(inputs, world, edges, plane)

    # A string: typing's cache would keep Optional[WrapSession] (and through it this module) alive until
    # after Python finalizes, and the PyPI bpy 4.2 module then crashes on exit freeing the operator class.
    def _start(self, context) -> "Optional[WrapSession]":
        """Check, then build the session (in object mode); None after reporting why not."""
        problem = layout_problem(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return None
        try:
            errors = _error_types()
        except ImportError as error:
            self.report({"ERROR"}, f"The Springwrap kernel is not available: {error}")
            return None
        try:
            layout = context.active_object
            return WrapSession(context, layout, self.parameters(), adjust_inputs=self._plane_holder(layout))
        except errors as error:
            self.report({"ERROR"}, str(error))
            return None

    def execute(self, context):
        from . import bridge

        layout = context.active_object
        if layout is None or layout.type != "MESH":
            self.report({"ERROR"}, layout_problem(context) or "No active mesh object (the layout)")
            return {"CANCELLED"}
        with bridge.object_mode(layout):
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
        self._report_result(result)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        from . import bridge

        layout = context.active_object
        if layout is None or layout.type != "MESH":
            return self.execute(context)  # reports why
        self._was_editing = bridge.leave_edit_mode(layout)
        session = self._start(context)
        if session is None:
            self._restore_mode()
            return {"CANCELLED"}
        self._loop = WrapLoop(session)
        self._area = context.area  # the header to write in; events may come with another area as context
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(TIMER_SECONDS, window=context.window)
        window_manager.progress_begin(0, session.parameters.max_iterations)
        window_manager.modal_handler_add(self)
        self._show_status(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        outcome = self._loop.handle(event.type, event.value)
        if outcome == "RUNNING_MODAL":
            if event.type == "TIMER":
                self._show_status(context)
            return {"RUNNING_MODAL"}
        if outcome == "PASS_THROUGH":
            return {"PASS_THROUGH"}
        self._end(context)
        if outcome == "FINISHED":
            self._report_result(self._loop.result)
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
        text = session.status_text()
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        if self._area is not None:
            self._area.header_text_set(text)
        context.window_manager.progress_update(session.total_iterations)
        screen = context.screen
        if screen is not None:
            for area in screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()

    def _end(self, context) -> None:
        """Remove the timer, the status text and the progress, and go back to edit mode if the layout was in it."""
        window_manager = context.window_manager
        if getattr(self, "_timer", None) is not None:
            window_manager.event_timer_remove(self._timer)
            self._timer = None
        window_manager.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        if getattr(self, "_area", None) is not None:
            self._area.header_text_set(None)
            self._area = None
        self._restore_mode()

    def _restore_mode(self) -> None:
        if getattr(self, "_was_editing", False):
            from . import bridge

            self._was_editing = False
            bridge.enter_edit_mode()

    def _report_result(self, result: WrapResult) -> None:
        self.report({"INFO"} if result.converged else {"WARNING"}, result.summary())
        detached, reattached = result.topology_detached_count, result.topology_reattached_count
        if detached or reattached or result.anchors_detached_count:
            self.report(
                {"WARNING"},
                f"Target topology changed: {detached} face-points and {result.anchors_detached_count} face anchors "
                f"lost their target face and became space-points, {reattached} face-points re-attached",
            )


classes = (SPRINGWRAP_OT_wrap,)
