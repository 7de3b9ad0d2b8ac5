"""A wrap in progress on one layout, without any UI (:class:`WrapSession`): read and check everything, build
the kernel's ``WrapSolver``, step it, write frames, then finish (one write) or cancel (put back bit for
bit). The wrap operator, the mirror and the headless scripts all run it.
"""

import time
from collections.abc import Callable

import bpy

import numpy as np

import springwrap_kernel

from ..core import anchors, follow, input_policy, layout_state, parts, proposals, subdivision, transforms, wrap_inputs
from ..core.errors import LayoutError
from ..core.target import Target
from ..core.wrap_run import FramePacer, SolveWorker, WrapResult, status_line
from . import anchors as anchor_data
from . import attributes, wrap_reads
from . import curves as curve_data
from . import layout as layout_data
from . import parts as part_data
from . import quality as quality_data
from . import shape_keys as shape_key_data
from .live_wraps import forget_results as forget_results  # the live wraps and results the panel shows
from .live_wraps import forget_results_on_load as forget_results_on_load
from .live_wraps import last_result as last_result
from .live_wraps import remember_result as remember_result
from .live_wraps import running_session as running_session
from .live_wraps import set_running as set_running

FRAME_RATE = 30.0
"""Redraws per second the modal wrap aims for when the display is fast (``core.wrap_run.FramePacer``)."""
SOLVER_SHARE = 0.6
"""Share of each frame the modal wrap solves when the display is slow (its redraws cost more than a frame)."""
MAX_SOLVE_SECONDS = 4.0
"""Longest a frame of the modal wrap solves before it writes the layout and lets Blender redraw (and see Esc)."""
SYNCHRONOUS_CHUNK = 100
"""Iterations per kernel call when the wrap runs to the end at once."""
_settled: dict = {}
"""Per layout (its full name), the ``core.wrap_inputs.settled_key`` of the result its last wrap wrote."""


class WrapSession:
    """A wrap in progress on one layout, without any UI: read, step, write frames, then finish or cancel.

    The constructor reads and checks everything and builds the solver; it writes nothing (an error
    is raised as one of ``core.errors.ERRORS`` and the scene is untouched). The layout must be in
    object mode for the whole session (the operator sees to it). ``parameters`` is an
    ``core.wrap_inputs.WrapParameters``. ``adjust_inputs`` (optional) takes the prepared
    ``core.wrap_inputs.WrapInputs`` and returns them changed (the mirror's pins and plane).
    ``display_seconds`` (optional) is what a redraw is known to cost before the first frame (the
    viewport's measured draw time): the first frame's solve time is paced from it. ``shape_keys``:
    ``'TRANSFER'`` wraps the basis (the reference key) and carries the other keys over when it finishes
    (frames move them along), ``'REFUSE'`` refuses a layout with shape keys. ``target`` (optional): the
    target already read (a sequence's frame object); None reads the layout's target. ``reads`` (optional): the
    layout and target as the caller read (and checked) them (``blender.wrap_reads``); None reads them here. ``region`` (optional, (N,)
    bool): re-settle only these vertices, every other one held where it is and written back as it was
    (``core.follow``: the solver then works on the faces around the region alone); ``template_share``: the
    template's share in the rest shape of the vertices re-settled there (``core.follow.blended_rest``);
    ``from_template``: the ``region`` starts again from the template's shape, as a wrap from the template starts
    it, its springs resting in the template's shape (``core.follow.restarted``).
    """

    def __init__(
        self,
        context,
        layout: bpy.types.Object,
        parameters,
        adjust_inputs=None,
        display_seconds: float | None = None,
        shape_keys: str = "TRANSFER",
        target: Target | None = None,
        region: np.ndarray | None = None,
        reads: wrap_reads.WrapReads | None = None,
        template_share: float = 0.0,
        from_template: bool = False,
    ):
        self.start_time = time.perf_counter()
        self.layout = layout
        self.parameters = parameters
        wrap_inputs.check_wrap_parameters(parameters)
        shape_key_data.refuse(layout, shape_keys, shape_key_data.REFUSED)
        self.shape_keys = shape_key_data.read(layout)  # as they were: frames follow them, finish carries them
        settings = layout.springwrap
        if reads is None:
            reads = wrap_reads.read(context, layout, target)
        arrays = reads.arrays
        if not transforms.is_invertible(arrays.matrix_world):
            raise LayoutError(
                f"Layout '{layout.name}' has zero scale: the wrap's world positions cannot be written back"
            )
        self.matrix_world = arrays.matrix_world
        self.target = reads.target
        self.layout_topology = reads.topology
        self.anchors, anchor_resolution = anchors.resolve(reads.anchors, self.target, settings.anchors_signature)
        unreliable = wrap_reads.unreliable_triangles(context, settings, self.target)
        curve_constraints = curve_data.resolve_curve_constraints(
            context.evaluated_depsgraph_get(), layout, reads.curves
        )
        # The input policy on what the solver gets (the operators check before; the mirror and the scripts
        # come here too): the layout, the anchors and the curves as resolved on the current target.
        extent = self.target.extent
        input_policy.check_layout_points(layout.name, transforms.world_positions(arrays), extent)
        input_policy.check_anchor_points(self.anchors.vertex_indices, self.anchors.locations, extent)
        input_policy.check_curve_points(curve_constraints, extent)
        # The template's shape as made: stored at the first change of the layout, else as it is now.
        self.rest = arrays.positions if reads.rest is None else reads.rest
        self.read_arrays = (arrays.positions, reads.rest is not None)  # finish() writes over them, not read back
        inputs, resolution = wrap_inputs.prepare_wrap(
            arrays,
            self.target,
            settings.target_signature,
            proposals.used_by_wrap(self.anchors),
            unreliable,
            curve_constraints,
            self.rest,
            soft_proposals=True,
        )
        inputs = wrap_reads.read_vertex_groups(inputs, layout, parameters)
        self.parts, self.follower = part_data.plan_wrap_parts(
            layout, arrays, self.layout_topology, self.target, self.anchors, curve_constraints
        )
        self.placed_pieces = ()  # the rigid pieces the result placed by their skin on the target (the report)
        inputs = part_data.free_parts(inputs, self.parts)
        wrap_inputs.check_something_pulled(
            layout.name, inputs.free_vertices, getattr(parameters, "free_group", "") or settings.free_group
        )
        if adjust_inputs is not None:
            inputs = adjust_inputs(inputs)
        self.restriction = None
        self.anchors_movable = adjust_inputs is None and region is None and inputs.soft_pair_vertices is None
        self.whole_inputs = inputs  # the mirror's plane in the layout's own numbering, for the parts' seam
        if region is not None:
            warm = inputs.positions
            restart = region if from_template else None
            if from_template:
                inputs = follow.restarted(inputs, region, self.layout_topology.edges)
            inputs = follow.held(inputs, region, template_share, restart, warm)
        if int(parameters.spring_resolution) == 1:
            # The solver works without the parts (they take no part in the surface's wrap) and, with a region,
            # on the faces around it alone.
            cut = parts.cut_out(self.layout_topology, inputs, self.parts, arrays.positions, region)
            if cut is None and region is not None:
                cut = follow.restrict(self.layout_topology, inputs, region, arrays.positions)
            if cut is not None:
                self.restriction, inputs = cut
        structure = layout_data.make_layout_structure(
            self.layout_topology if self.restriction is None else self.restriction.topology
        )
        # The layout as its last wrap left it (one stage, nothing re-settled by region): re-settled from where it is.
        key = wrap_inputs.settled_key(self.target.signature, arrays.positions, self.rest, parameters, inputs)
        single = region is None and self.restriction is None and int(parameters.spring_resolution) == 1
        settled = single and wrap_inputs.is_settled_start(
            _settled.get(layout.name_full), key, adjust_inputs is not None
        )
        restart = from_template and region is not None and not region.all()  # a region started again, the rest held
        self.solver = wrap_inputs.make_wrap_solver(self.target, structure, inputs, parameters, settled, restart)
        self.inputs = inputs
        # Coarse to fine: with a spring resolution above 1 the layout is relaxed first, then a grid
        # of its faces cut k x k (its own vertices first) takes over; the layout's vertices are read
        # back from it.
        self.stage = "coarse" if int(parameters.spring_resolution) > 1 else "fine"
        self.coarse_iterations = 0
        self.snapshot = attributes.take_snapshot(layout)
        # What finish() writes on the object besides the mesh, to put back when it fails half-way.
        self.settings_snapshot = (
            settings.target_signature,
            reads.anchors,
            settings.active_anchor_index,
            settings.anchors_signature,
        )
        self.vertex_count = arrays.positions.shape[0]
        self.unreliable_count = 0 if unreliable is None else int(unreliable.sum())
        self.topology = (resolution.detached_count, resolution.reattached_count, anchor_resolution.detached_count)
        self.pacer = FramePacer(FRAME_RATE, SOLVER_SHARE, MAX_SOLVE_SECONDS, display_seconds=display_seconds)
        self.last_report = None
        self.kernel_seconds = 0.0
        self.frames = 0
        self.events = {"landed": 0, "folded": 0}
        self._frame_end: float | None = None
        self.worker: SolveWorker | None = None
        self.threaded = False  # solving in a worker (start_worker): an edit after it ended starts another
        self.cancel_flag = springwrap_kernel.CancelFlag()  # set by cancel(): the step in progress stops at once
        self.anchors_moved = False  # anchors moved since the last step: the wrap is not done
        self.anchors_edited = None  # the anchors last given to move_anchors (kept by cancel), None: not moved
        self.stop_seconds = 0.0  # how long the last stop of the worker waited for it (Esc's share in the solver)
        self.written_positions: np.ndarray | None = None  # the local positions finish() wrote

    @property
    def stage_iterations(self) -> int:
        """Iterations run so far by the current stage's solver."""
        return 0 if self.last_report is None else self.last_report.total_iterations

    @property
    def total_iterations(self) -> int:
        """Iterations run so far, both stages."""
        return self.coarse_iterations + self.stage_iterations

    @property
    def done(self) -> bool:
        """The last stage converged, or reached the iteration limit (each stage has it)."""
        if self.last_report is None or self.stage != "fine" or self.anchors_moved:
            return False
        return self.last_report.converged or self.stage_iterations >= self.parameters.max_iterations

    def step(self, iterations: int):
        """Run up to ``iterations`` kernel iterations (within the limit); the kernel's ``StepReport``.

        When the coarse stage ends, the next call starts the fine one.
        """
        self._refine_if_due()
        iterations = min(int(iterations), self.parameters.max_iterations - self.stage_iterations)
        start = time.perf_counter()
        report = self.solver.step(max(iterations, 0), cancel=self.cancel_flag)
        self.anchors_moved = False
        self.kernel_seconds += time.perf_counter() - start
        for name in self.events:
            self.events[name] += getattr(report, name)
        self.last_report = report
        return report

    def _refine_if_due(self) -> bool:
        """Start the fine stage when the coarse one has ended (converged or at the limit); whether it started."""
        if (
            self.stage == "coarse"
            and self.last_report is not None
            and (self.last_report.converged or self.stage_iterations >= self.parameters.max_iterations)
        ):
            self.refine()
            return True
        return False

    def refine(self) -> None:
        """End the coarse stage: a solver on the layout's faces cut k x k, started where the coarse one ended."""
        start = time.perf_counter()
        fine = subdivision.subdivide(self.layout_topology, int(self.parameters.spring_resolution))
        self._check_cancelled()
        inputs = wrap_inputs.refine_wrap_inputs(
            self.inputs, fine, self.solver.positions(), self.solver.states(), self.target
        )
        structure = layout_data.make_layout_structure(fine.topology)
        inputs = part_data.refine_free(inputs, fine, self.vertex_count)
        self._check_cancelled()
        self.solver = wrap_inputs.make_wrap_solver(self.target, structure, inputs, self.parameters)
        self.kernel_seconds += time.perf_counter() - start
        self.coarse_iterations = self.stage_iterations
        self.fine_vertex_count = fine.topology.vertex_count
        self.last_report = None
        self.stage = "fine"

    def advance(self, max_seconds: float | None = None):
        """One frame of the interactive wrap; returns the last ``StepReport`` (None before the worker's first).

        Without a worker (:meth:`start_worker`) the frame solves here for its share of time, then writes the layout:
        the time since the previous frame's write ended (Blender's redraw and event handling) is the display's
        measured cost, from which the pacer sizes this frame's solve time (at most ``max_seconds`` when given); the
        kernel is called in chunks until that time is used or the wrap is done. With a worker the frame writes the
        newest positions the worker solved, if there are new ones, and solves nothing; an error of the worker is
        raised here. Either way it writes positions and state into the layout mesh (no undo step).
        """
        if self.worker is not None:
            return self._present()
        begin = time.perf_counter()
        if self._frame_end is not None:
            self.pacer.record_display(begin - self._frame_end)
        seconds = self.pacer.solve_seconds()
        report = self._solve_for(seconds if max_seconds is None else min(seconds, max_seconds))
        self.write_frame()
        self._frame_end = time.perf_counter()
        self.frames += 1
        return report

    def _solve_for(self, seconds: float):
        """Call the kernel in chunks sized by the pacer for about ``seconds`` (at least one iteration, or the start of
        the next stage); the last ``StepReport``."""
        deadline = time.perf_counter() + seconds
        report = None
        while report is None or not self.done:
            if self._refine_if_due():
                self.pacer.new_stage()  # the fine stage's iterations cost more: measured again from one
            now = time.perf_counter()
            remaining = self.parameters.max_iterations - self.stage_iterations
            count = self.pacer.next_count(remaining, deadline - now)
            if count == 0:
                if report is not None:
                    break
                count = min(remaining, 1)  # every frame runs at least one iteration (or starts the next stage)
            report = self.step(count)
            self.pacer.record_step(report.iterations, time.perf_counter() - now)
            if self.stage == "fine" and report.iterations == 0:
                break  # nothing left to run in this stage (the limit): done says so
        return report

    def _check_cancelled(self) -> None:
        """Raise the kernel's ``CancelledError`` once :meth:`cancel` set the flag (between the pieces of the fine
        stage's start, which the kernel's step cannot see)."""
        if self.cancel_flag.cancelled:
            raise springwrap_kernel.CancelledError("wrap step cancelled")

    def can_move_anchors(self, anchor_list) -> bool:
        """Whether :meth:`move_anchors` takes ``anchor_list`` (see there); asks nothing of the solver."""
        used = proposals.used_by_wrap(anchor_list)
        return self.anchors_movable and not (used.confidences > 0.0).any() and self.restriction is None

    def move_anchors(self, anchor_list) -> bool:
        """Move the wrap's anchors to ``anchor_list`` (an ``core.anchors.Anchors`` resolved on the current target)
        while it runs, without starting it anew: with a worker the change is queued and applied by its thread
        between two iterations (a move not applied yet is replaced: the newest wins), else here. The points stay
        where they are and the solver's schedule starts again from them (``WrapSolver.set_anchors``); :meth:`finish`
        writes these anchors, and :meth:`cancel` keeps them (an edit made while it ran). False (nothing changed) when
        this session cannot take them so: a mirror's pins, a re-settled region, or soft pairs (accepted proposals)
        in the wrap or in ``anchor_list``: the caller finishes it and starts another."""
        if not self.can_move_anchors(anchor_list):
            return False
        used = proposals.used_by_wrap(anchor_list)
        arrays = wrap_inputs.wrap_anchor_arrays(used, self.vertex_count, self.inputs.origin)

        def apply() -> None:  # in the worker's thread when there is one: the solver is its own there
            self.solver.set_anchors(*arrays)
            names = ("anchor_vertices", "anchor_triangles", "anchor_barycentrics", "anchor_positions")
            self.inputs = self.inputs._replace(**dict(zip(names, arrays, strict=True)))
            self.anchors = anchor_list
            self.anchors_moved = True

        self.anchors_edited = anchor_list  # what cancel() writes back, whether or not applied by then
        had_worker = self.worker is not None
        if had_worker and self.worker.submit(apply, key="anchors"):
            return True
        self.stop_worker()  # it had ended (done): the solver is this thread's
        apply()
        if had_worker or self.threaded:
            self.start_worker()
        return True

    def start_worker(self) -> None:
        """Solve the rest of the wrap in a worker thread (``core.wrap_run.SolveWorker``): from now on :meth:`advance`
        only writes what it solved, and the solver is not touched here until :meth:`stop_worker` (which
        :meth:`finish` and :meth:`cancel` call). Each of its chunks solves about one frame's time. What runs in the
        worker (:meth:`step`, the fine stage's start, :meth:`current_layout`) reads and writes no Blender data."""
        if self.worker is None and not self.done:
            self.threaded = True
            self.worker = SolveWorker(
                self._solve_for,
                self.current_layout,
                lambda: self.done,
                self.pacer.frame_seconds,
                interrupt=self.cancel_flag.cancel,
                interrupted_error=springwrap_kernel.CancelledError,
            )

    def stop_worker(self, raise_error: bool = True, interrupt: bool = False) -> None:
        """Stop the worker (the solver is then this thread's again); raise what it raised unless ``raise_error`` is
        False. It stops after its iteration in progress, edits it had not applied yet applied here; with
        ``interrupt`` the step in progress is cancelled at once and the solver is not to be stepped again (for
        :meth:`cancel`). Nothing without a worker."""
        worker, self.worker = self.worker, None
        if worker is None:
            return
        self.stop_seconds = worker.stop(interrupt=interrupt)
        if worker.error is not None and raise_error:
            raise worker.error
        if not interrupt and worker.error is None:
            for edit in worker.pending():
                edit()

    def _present(self):
        """A frame with a worker: write its newest positions and state; raise its error when it failed."""
        frame = self.worker.take()
        if frame is not None:
            self._write_frame(*frame)
            self.frames += 1
        if not self.worker.running:
            self.stop_worker()
        return self.last_report

    def run(self, progress: Callable | None = None, chunk: int = SYNCHRONOUS_CHUNK):
        """Step to the end at once (converged or the limit), writing nothing; ``progress(report)`` after each chunk."""
        while not self.done:
            report = self.step(chunk)
            if progress is not None:
                progress(report)
        return self.last_report

    def current_layout(self, final: bool = False):
        """(local positions float32 (N, 3), ``LayoutState``) of the solver now. ``final``: the parts follow only the
        surface held on the target (its face points, ``core.parts.follow``), else all of it (a frame, cheaper)."""
        count = self.vertex_count  # a fine grid numbers the layout's own vertices first
        if self.restriction is not None:
            count = self.restriction.kept.size
        world = wrap_inputs.from_frame(self.inputs, self.solver.positions()[:count])
        states, triangles, barycentrics = (np.array(array[:count]) for array in self.solver.states())
        positions = transforms.to_local(self.matrix_world, world)
        state = layout_state.normalized_state(states, triangles, barycentrics)
        if self.restriction is not None:
            positions, state = follow.scatter(self.restriction, positions, state)
        if self.follower is not None:  # the parts: moved by the surface, off the target
            world = transforms.transform_points(self.matrix_world, positions)
            placed = []
            world = part_data.follow_surface(
                self.follower, self.parts, world, state, self.whole_inputs, final, self.target.mesh, placed
            )
            if final:
                self.placed_pieces = tuple(placed)
            positions = transforms.to_local(self.matrix_world, world)
            state.states[self.parts.parts] = layout_state.SPACE_POINT
            state.faces[self.parts.parts] = layout_state.NO_FACE
        return positions, state

    def write_frame(self) -> None:
        """Write the solver's current positions and state into the layout (an intermediate frame)."""
        self._write_frame(*self.current_layout())

    def _write_frame(self, positions, state) -> None:
        attributes.write_wrap_frame(self.layout, positions, state)
        shape_key_data.follow(self.layout, self.shape_keys, positions)
        if self.shape_keys is None:  # the mesh now holds these (with keys, finish() puts the keys back first)
            self.read_arrays = (np.asarray(positions, dtype=np.float32).reshape(-1, 3), self.read_arrays[1])

    def finish(self, measure: bool = True) -> WrapResult:
        """Write the result for good: positions, state, the target signature and the resolved anchors, and (with
        ``measure``) the quality read-out; without it the read-out stays as it was (a sequence's later frame). A
        worker is stopped first, after its iteration in progress."""
        self.stop_worker()
        if self.last_report is None:
            self.step(0)
        positions, state = self.current_layout(final=True)
        readout = None
        if measure:
            readout = quality_data.measure_layout(
                self.layout, self.target, positions, self.rest, self.layout_topology, state
            )
        shape_key_data.restore(self.layout, self.shape_keys)  # carried from the keys as they were, not a frame
        mesh_positions, has_rest = self.read_arrays
        now = layout_data.MeshNow(mesh_positions, has_rest, self.layout_topology, self.shape_keys)
        layout_data.write_layout(self.layout, positions, state, rest=self.rest, now=now)
        self.written_positions = positions  # what the operator's storage check needs, not read back
        key = wrap_inputs.settled_key(self.target.signature, positions, self.rest, self.parameters, self.inputs)
        _settled[self.layout.name_full] = key
        settings = self.layout.springwrap
        settings.target_signature = self.target.signature
        if len(settings.anchors):
            anchor_data.write_anchors(self.layout, self.anchors, -1, self.target.signature)
        if readout is not None:
            quality_data.write_readout(self.layout, readout)  # the quality read-out, in the same undo step
        part_data.write_parts(self.layout, self.parts)
        report = self.last_report
        face_points, space_points = layout_state.point_counts(state.states)
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
            held_back=int(report.held_back),
            energy_decrease=float(report.energy_decrease),
            anchor_count=anchors.anchor_count(proposals.used_by_wrap(self.anchors)),
            unreliable_triangles=self.unreliable_count,
            topology_detached_count=detached,
            topology_reattached_count=reattached,
            anchors_detached_count=anchors_detached,
            readout=parts.surface_readout(readout, self.parts.parts),
            parts=parts.report_text(self.parts, self.placed_pieces),
        )

    def cancel(self) -> None:
        """Put the layout back exactly as it was at the start: positions, state attributes, rest shape, read-out,
        and what :meth:`finish` writes on the object (target signature, anchors), the shape keys; also after a
        failed finish (a worker is stopped first, its step in progress cancelled: Esc is answered at once). Anchors
        moved while it ran (:meth:`move_anchors`: edits made meanwhile) stay as last moved."""
        self.stop_worker(raise_error=False, interrupt=True)
        shape_key_data.restore(self.layout, self.shape_keys)
        attributes.restore_snapshot(self.layout, self.snapshot)
        target_signature, anchor_list, active_index, anchors_signature = self.settings_snapshot
        settings = self.layout.springwrap
        if settings.target_signature != target_signature:
            settings.target_signature = target_signature
        if self.anchors_edited is not None:
            anchor_data.write_anchors(self.layout, self.anchors_edited, -1, self.target.signature)
        elif len(settings.anchors) or anchors.anchor_count(anchor_list):
            anchor_data.write_anchors(self.layout, anchor_list, active_index, anchors_signature)

    def status_text(self) -> str:
        """The progress line shown in the status bar (``core.wrap_run.status_line``)."""
        return status_line(self.layout.name, self.last_report, self.parameters, self.stage)
