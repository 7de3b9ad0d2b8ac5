"""Running a wrap, without Blender: what it did (:class:`WrapResult`), how long each
frame of the live wrap solves (:class:`FramePacer`), the live wrap's solve in a worker thread (:class:`SolveWorker`)
and the modal's state machine (:class:`WrapLoop`: events in, the operator's return values out), so tests drive them
directly. No ``bpy``.
"""

import math
import threading
import time
from collections.abc import Callable
from typing import NamedTuple

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


TOOL_EVENTS = frozenset({"LEFTMOUSE", "X", "DEL"})
"""Events a modal wrap lets through to a tool editing the layout's anchors while it runs (the pair tool)."""


def tool_event(event_type: str, event_value: str, dragging: bool) -> bool:
    """Whether a modal wrap lets an event through to a tool editing the layout's anchors: its clicks and removal
    keys, and Esc or right-click pressed while it drags (they cancel the drag, not the wrap)."""
    if event_type in TOOL_EVENTS:
        return True
    return dragging and event_type in CANCEL_EVENTS and event_value == "PRESS"


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
    landed: int  # anchored points on the surface at the landing
    folded: int  # free points that landed on the surface at the end
    held_back: int  # points whose last step was shortened so that no face turned
    energy_decrease: float  # how much the last step lowered the energy, relative (NaN for a level's first step)
    anchor_count: int
    unreliable_triangles: int
    topology_detached_count: int  # face-points whose target face was gone, made space-points
    topology_reattached_count: int
    anchors_detached_count: int  # face anchors whose target face was gone, made space anchors
    readout: object = None  # the quality read-out written with the result (core.quality.Readout)
    parts: str = ""  # which pieces followed the surface as parts, and how (core.parts.report_text); "" none

    def summary(self) -> str:
        """One line: iterations, time, face / space points and what changed state."""
        ending = "converged" if self.converged else "stopped at the iteration limit"
        details = f"{self.folded} landed at the end, {self.held_back} held back by the last step"
        if math.isfinite(self.energy_decrease):
            details += f", which lowered the energy by {100.0 * self.energy_decrease:.2g} %"
        elif self.converged:  # the last level ended on its first step: it barely moved the points
            details += ", which barely moved the points"
        timing = f"{self.seconds:.2f} s"
        if self.frames:  # the live wrap: how much of its time was solving, over how many redraws
            timing += f" ({self.kernel_seconds:.2f} s solving, {self.frames} frame{'s' if self.frames > 1 else ''})"
        return (
            f"Wrapped '{self.layout_name}' in {self.iterations} iterations ({ending}), {timing}: "
            f"{self.face_points} face-points, {self.space_points} space-points ({details})"
        )


class FramePacer:
    """How long the live wrap solves in each frame, from what the display really costs.

    A frame of the modal wrap is: solve for a while, write the layout, then let Blender redraw and
    handle events until the next timer event. The redraw is not ours to shorten, so its cost is
    measured (``record_display``: the time from the end of a frame's write to the start of the next
    frame, or the viewport's draw time before the first frame) and the solver gets a share of each
    frame from it: ``solver_share`` of the frame when redraws are slow (a 1 s software-OpenGL
    redraw gets 1.5 s of solving at the default 0.6), and the rest of a ``1 / frame_rate`` frame
    when they are fast (a 5 ms redraw on a GPU leaves 28 ms at 30 frames per second). One frame
    never solves longer than ``max_solve_seconds``, so Esc is answered within about that plus a
    redraw.

    Within a frame the kernel is called in chunks (:meth:`next_count`) sized from the measured cost
    of one iteration (smoothed), until the frame's solve time is used; the first chunk of a wrap is
    one iteration, to measure it.
    """

    def __init__(
        self,
        frame_rate: float = 30.0,
        solver_share: float = 0.6,
        max_solve_seconds: float = 4.0,
        display_seconds: float | None = None,
        max_count: int = 10_000,
    ):
        if frame_rate <= 0.0:
            raise ValueError("frame_rate must be positive")
        if not 0.0 < solver_share < 1.0:
            raise ValueError("solver_share must be within (0, 1)")
        if max_solve_seconds <= 0.0:
            raise ValueError("max_solve_seconds must be positive")
        self.frame_seconds = 1.0 / frame_rate
        self.solver_share = solver_share
        self.max_solve_seconds = max_solve_seconds
        self.max_count = max_count
        self.display_seconds = display_seconds if display_seconds is None else max(float(display_seconds), 0.0)
        self.iteration_seconds: float | None = None

    def solve_seconds(self) -> float:
        """How long the next frame solves: the frame time left after the display, or the solver's share of a
        frame with the display's measured cost, whichever is longer, at most ``max_solve_seconds``."""
        display = self.display_seconds or 0.0
        share = self.solver_share / (1.0 - self.solver_share) * display
        return min(max(self.frame_seconds - display, share, 0.25 * self.frame_seconds), self.max_solve_seconds)

    def next_count(self, remaining: int, seconds_left: float) -> int:
        """Iterations for the next kernel call of a frame with ``seconds_left`` of solve time: 1 while the cost
        of an iteration is unknown, 0 when none remain or the time is used, else what fits (at least 1)."""
        if remaining <= 0 or (self.iteration_seconds is not None and seconds_left <= 0.0):
            return 0
        if self.iteration_seconds is None:
            return 1
        count = int(seconds_left / max(self.iteration_seconds, 1e-7))
        return max(1, min(count, self.max_count, remaining))

    def record_step(self, iterations: int, seconds: float) -> None:
        """Account for a kernel call: ``iterations`` took ``seconds`` (smoothed into the cost of one)."""
        if iterations > 0:
            per_iteration = seconds / iterations
            if self.iteration_seconds is None:
                self.iteration_seconds = per_iteration
            else:
                self.iteration_seconds = 0.5 * self.iteration_seconds + 0.5 * per_iteration

    def new_stage(self) -> None:
        """Forget the cost of an iteration: the next stage's iterations (a finer spring mesh) cost another amount,
        measured again from one iteration."""
        self.iteration_seconds = None

    def record_display(self, seconds: float) -> None:
        """Account for the display between two frames (redraw and events), smoothed; the first one counts whole."""
        seconds = max(float(seconds), 0.0)
        if self.display_seconds is None:
            self.display_seconds = seconds
        else:
            self.display_seconds = 0.5 * self.display_seconds + 0.5 * seconds


class SolveWorker:
    """The live wrap's solve in a worker thread, so that Blender's main thread only draws and handles events.

    The thread calls ``step(seconds)`` (run about ``seconds`` of iterations, at least one) and then
    ``snapshot()`` (what the main thread draws, computed from the solver in this thread), and publishes the
    snapshot, until ``done()`` or :meth:`stop`. The kernel releases the GIL while it steps. Nothing else may touch
    the solver while the thread runs: the main thread reads only :meth:`take` (the newest snapshot not yet taken),
    hands changes over with :meth:`submit` (applied by the thread between two steps), and reaches the solver again
    after :meth:`stop`. ``stop()`` waits for the iteration in progress (the solver is never left half-stepped);
    ``stop(interrupt=True)`` first calls ``interrupt()`` (which sets the kernel's cancellation flag), so the step in
    progress ends within a piece of an iteration, raising an ``interrupted_error``: that ends the thread quietly.
    Any other exception in the thread ends it and is kept in :attr:`error`.
    """

    def __init__(
        self,
        step: Callable,
        snapshot: Callable,
        done: Callable,
        chunk_seconds: float,
        interrupt: Callable | None = None,
        interrupted_error: type[BaseException] | tuple = (),
    ):
        self._step, self._snapshot, self._done = step, snapshot, done
        self._interrupt, self._interrupted_error = interrupt, interrupted_error
        self.chunk_seconds = chunk_seconds
        self.error: BaseException | None = None
        self.interrupted = False  # whether a step was cut short by stop(interrupt=True)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._latest = None
        self._serial = 0
        self._taken = 0
        self._edits: list[tuple[str | None, Callable]] = []  # (key, edit), in the order submitted
        self._closed = False  # the thread takes no more edits (it ended or is about to)
        self._thread = threading.Thread(target=self._run, name="springwrap live wrap", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                self._apply_edits()
                if self._done():
                    with self._lock:
                        if not self._edits:  # else an edit came after the last look: apply it, go on
                            self._closed = True
                            return
                    continue
                self._step(self.chunk_seconds)
                snapshot = self._snapshot()
                with self._lock:
                    self._latest = snapshot
                    self._serial += 1
        except BaseException as error:  # noqa: BLE001 - handed to the main thread, raised there
            if self._stop.is_set() and isinstance(error, self._interrupted_error):
                self.interrupted = True
            else:
                self.error = error
        finally:
            with self._lock:
                self._closed = True

    def _apply_edits(self) -> None:
        """Apply the edits submitted since the last look, in order, in this thread."""
        with self._lock:
            edits, self._edits = self._edits, []
        for _key, edit in edits:
            edit()

    def submit(self, edit: Callable, key: str | None = None) -> bool:
        """Hand ``edit`` (a callable changing the solver) to the thread, which calls it before its next step (and
        solves on if it was done); False when the thread has ended or is ending: the caller applies it itself.
        With ``key``, an edit of the same key not applied yet is replaced (the newest wins: a drag's mouse moves
        faster than the solver's steps do not pile up)."""
        with self._lock:
            if self._closed or self._stop.is_set():
                return False
            if key is not None:
                for place, (pending_key, _edit) in enumerate(self._edits):
                    if pending_key == key:
                        self._edits[place] = (key, edit)
                        return True
            self._edits.append((key, edit))
            return True

    def pending(self) -> list[Callable]:
        """The submitted edits the thread did not apply (after :meth:`stop`), in order; taken from it."""
        with self._lock:
            edits, self._edits = self._edits, []
        return [edit for _key, edit in edits]

    @property
    def running(self) -> bool:
        """Whether the thread is still solving."""
        return self._thread.is_alive()

    def take(self):
        """The newest snapshot the thread published since the last call, None when there is none."""
        with self._lock:
            if self._serial == self._taken:
                return None
            self._taken = self._serial
            return self._latest

    def stop(self, interrupt: bool = False) -> float:
        """Ask the thread to stop and wait for it; the seconds waited. Without ``interrupt`` it stops after the
        iteration in progress; with it the step in progress is cancelled (``interrupt()``), the solver then unusable
        (the caller drops it). Edits not yet applied are left for :meth:`pending`."""
        start = time.perf_counter()
        with self._lock:
            self._stop.set()
        if interrupt and self._interrupt is not None and self._thread.is_alive():
            self._interrupt()
        self._thread.join()
        return time.perf_counter() - start


class WrapLoop:
    """The modal wrap's state machine: each event in, the operator's return value out.

    ``handle`` returns ``'RUNNING_MODAL'``, ``'PASS_THROUGH'``, ``'FINISHED'`` (the result is in
    :attr:`result`) or ``'CANCELLED'`` (by the user, or by an error kept in :attr:`error`); the
    layout is restored bit for bit on cancel and on any error. It needs no window.
    """

    def __init__(self, session):
        self.session = session
        self.result: WrapResult | None = None
        self.error: BaseException | None = None
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


def status_line(layout_name: str, report, parameters, stage: str) -> str:
    """A wrap's progress line for the status bar: its iteration (of the limit), face- and space-points and last
    move from ``report`` (the last ``StepReport``, None before the first), the stage when it has two (``'coarse'``
    or the fine one)."""
    if report is None:
        return f"Springwrap: wrapping '{layout_name}'...  Esc / right-click: cancel"
    label = ""
    if int(parameters.spring_resolution) > 1:
        label = "coarse, " if stage == "coarse" else f"fine {parameters.spring_resolution}x, "
    return (
        f"Springwrap: {label}iteration {report.total_iterations} / {parameters.max_iterations}, "
        f"{report.face_points} face-points, {report.space_points} space-points, "
        f"last move {report.max_displacement:.2e}  —  Esc / right-click: cancel"
    )
