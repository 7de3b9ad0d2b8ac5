"""A wrap over a frame range, without Blender: the frames to wrap, what each frame did (:class:`FrameOutcome`),
the shape each frame's key holds, the keyframes that show it, the report, and the modal's state machine
(:class:`SequenceLoop`: events in, the operator's return values out). No ``bpy``.

Each frame's target is the target as evaluated at that frame (or a collection's object of that frame); the
first frame is an ordinary wrap, every later one starts from the previous frame's result. A frame that
fails keeps the previous frame's shape and says why.
"""

from typing import NamedTuple

import numpy as np

from .errors import LayoutError
from .wrap_run import modal_action

KEY_PREFIX = "Wrap "
"""The name of a frame's shape key: this, then the frame number in four digits ("Wrap 0012")."""

MAX_FRAMES = 100_000
"""The most frames one sequence wraps."""


def key_name(frame: int) -> str:
    """The shape key of ``frame``."""
    return f"{KEY_PREFIX}{int(frame):04d}"


def is_sequence_key(name: str) -> bool:
    """Whether a shape key of this name was written by a sequence."""
    number = name[len(KEY_PREFIX) :]
    return name.startswith(KEY_PREFIX) and number.lstrip("-").isdigit()


def frame_range(start: int, end: int, step: int = 1) -> list[int]:
    """The frames ``start`` .. ``end`` (both included) every ``step``; raises :class:`LayoutError` on an empty or
    oversized range."""
    start, end, step = int(start), int(end), int(step)
    if step < 1:
        raise LayoutError(f"The frame step must be at least 1, not {step}")
    if end < start:
        raise LayoutError(f"The frame range is empty: it ends at {end}, before its start {start}")
    frames = list(range(start, end + 1, step))
    if len(frames) > MAX_FRAMES:
        raise LayoutError(f"{len(frames)} frames are more than a sequence wraps ({MAX_FRAMES})")
    return frames


def frame_objects(names: list[str], frames: list[int]) -> list[int]:
    """For a collection sequence: the index (in ``names``, sorted by name) of the object of each frame, the i-th
    frame taking the i-th object; raises :class:`LayoutError` when the collection has fewer objects than frames."""
    if len(names) < len(frames):
        raise LayoutError(
            f"The collection has {len(names)} mesh objects for {len(frames)} frames: one object per frame, in the "
            "order of their names (shorten the frame range, or add the missing objects)"
        )
    order = sorted(range(len(names)), key=lambda index: names[index])
    return order[: len(frames)]


def refuse_own_keys(layout_name: str, key_names: list[str], reference: str | None) -> None:
    """Raise :class:`LayoutError` when the layout has shape keys besides its reference key and an earlier
    sequence's keys (which a new sequence replaces): a sequence writes its frames as shape keys."""
    own = [name for name in key_names if name != reference and not is_sequence_key(name)]
    if own:
        raise LayoutError(
            f"Layout '{layout_name}' has shape keys of its own ({', '.join(repr(name) for name in own[:3])}): a "
            "sequence writes its frames as shape keys; wrap a copy of the layout without them"
        )


class FrameOutcome(NamedTuple):
    """What one frame of the sequence did."""

    frame: int
    ok: bool
    seconds: float  # from reading the target to the frame's write
    iterations: int  # 0 for a failed frame
    message: str  # why it failed ("" when it did not)


class SequenceResult(NamedTuple):
    """What a whole sequence did, for the report."""

    layout_name: str
    outcomes: tuple  # FrameOutcome per frame wrapped, in order
    planned: int  # frames in the range
    stopped: bool  # Esc (or a cancel) ended it before the last frame

    @property
    def failed(self) -> list[FrameOutcome]:
        return [outcome for outcome in self.outcomes if not outcome.ok]

    def summary(self) -> str:
        """One line: frames done of the range, time per frame, failures."""
        done = len(self.outcomes)
        later = [outcome.seconds for outcome in self.outcomes[1:] if outcome.ok]
        first = self.outcomes[0].seconds if self.outcomes else 0.0
        timing = f"first frame {first:.2f} s"
        if later:
            timing += f", then {float(np.mean(later)):.2f} s per frame"
        text = f"Wrapped '{self.layout_name}' over {done} of {self.planned} frames ({timing})"
        if self.stopped:
            text += "; stopped: the frames done are kept as shape keys"
        failed = self.failed
        if failed:
            frames = ", ".join(str(outcome.frame) for outcome in failed[:8])
            more = "…" if len(failed) > 8 else ""
            text += f"; {len(failed)} failed and keep the previous frame's shape (frames {frames}{more})"
        return text


def key_positions(outcomes, shapes: dict, before: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """(frame, local positions) of each frame's key: its own result, or for a failed frame the last shape before
    it (``before``, the layout as it was, when the first frame failed)."""
    keys, last = [], before
    for outcome in outcomes:
        if outcome.ok:
            last = shapes[outcome.frame]
        keys.append((outcome.frame, last))
    return keys


def key_values(frames: list[int]) -> list[list[tuple[int, float]]]:
    """Per frame, the (frame, value) keyframes of its key: 1 on its frame, 0 on its neighbours' frames (linear
    between, so a subframe blends the two frames around it); the first key holds before the range, the last after."""
    plan = []
    for index, frame in enumerate(frames):
        points = []
        if index > 0:
            points.append((frames[index - 1], 0.0))
        points.append((frame, 1.0))
        if index + 1 < len(frames):
            points.append((frames[index + 1], 0.0))
        plan.append(points)
    return plan


class SequenceLoop:
    """The modal sequence's state machine: a timer event wraps the next frame, Esc (or right-click) stops and
    keeps the frames done; ``handle`` returns ``'RUNNING_MODAL'``, ``'PASS_THROUGH'`` or ``'FINISHED'``
    (the result in :attr:`result`). ``run`` is the sequence (``advance()``, ``done``, ``finish(stopped)``)."""

    def __init__(self, run):
        self.run = run
        self.result: SequenceResult | None = None
        self.state = "RUNNING_MODAL"

    def handle(self, event_type: str, event_value: str = "NOTHING") -> str:
        if self.state == "FINISHED":
            return self.state
        action = modal_action(event_type, event_value)
        if action == "PASS":
            return "PASS_THROUGH"
        if action == "CANCEL":
            return self.stop()
        if action == "STEP":
            self.run.advance()
            if self.run.done:
                self.result = self.run.finish(stopped=False)
                self.state = "FINISHED"
        return self.state

    def stop(self) -> str:
        """End now, keeping the frames done."""
        if self.state == "RUNNING_MODAL":
            self.result = self.run.finish(stopped=True)
            self.state = "FINISHED"
        return self.state
