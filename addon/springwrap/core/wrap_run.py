"""Running a wrap, without Blender: what it did (:class:`WrapResult`), how many iterations fit in a
frame (:class:`IterationPacer`) and the modal's state machine (:class:`WrapLoop`: events in, the
operator's return values out), so tests drive them directly. No ``bpy``.
"""

import math
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


class IterationPacer:
    """How many wrap iterations to run per redraw so that the viewport keeps about ``frame_rate`` redraws/s.

    The cost of one iteration and of writing a frame are measured as the wrap runs (smoothed);
    each frame gets what is left of the frame time after the write, at least one iteration, and
    at most four times the previous count (so a fast first guess cannot overshoot by much).
    """

    def __init__(self, frame_rate: float = 30.0, max_count: int = 10_000):
        if frame_rate <= 0.0:
            raise ValueError("frame_rate must be positive")
        self.frame_seconds = 1.0 / frame_rate
        self.max_count = max_count
        self.iteration_seconds: float | None = None
        self.write_seconds = 0.0
        self.last_count = 1

    def next_count(self, remaining: int) -> int:
        """Iterations for the next frame (at most ``remaining``, at least 1 when any remain)."""
        if remaining <= 0:
            return 0
        if self.iteration_seconds is None:
            count = 1
        else:
            budget = max(self.frame_seconds - self.write_seconds, 0.25 * self.frame_seconds)
            count = int(budget / max(self.iteration_seconds, 1e-7))
            count = min(count, 4 * self.last_count)
        count = max(1, min(count, self.max_count, remaining))
        self.last_count = count
        return count

    def record(self, iterations: int, step_seconds: float, write_seconds: float) -> None:
        """Account for a frame: ``iterations`` took ``step_seconds``, the write ``write_seconds``."""
        if iterations > 0:
            per_iteration = step_seconds / iterations
            if self.iteration_seconds is None:
                self.iteration_seconds = per_iteration
            else:
                self.iteration_seconds = 0.5 * self.iteration_seconds + 0.5 * per_iteration
        self.write_seconds = 0.5 * self.write_seconds + 0.5 * write_seconds


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
