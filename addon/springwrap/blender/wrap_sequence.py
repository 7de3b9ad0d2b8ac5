"""A wrap over a frame range (:class:`SequenceRun`), without any UI: for each frame, the target as evaluated at
that frame (its armature, shape-key or modifier animation, a Mesh Sequence Cache) or a collection's object of
that frame, wrapped from the previous frame's result, and at the end one shape key per frame on the layout,
keyed so that playback shows the layout following.

Each frame is one :class:`~.wrap_session.WrapSession` run to the end and finished (so the frame's face-points,
anchors and target signature are what the next frame starts from: a face-point or face anchor keeps its
triangle and weights and so follows its point on the moved surface, and where the target's topology changed
it is found again by the deleted-face rule). The first frame is an ordinary wrap; later frames keep the
previous frame's result (``warm_rest='PREVIOUS'``) and re-wrap only where the target changed, that region
started again from the template's shape as a wrap from the template would start it, with the global-to-local
schedule when the wrap's is Auto and some vertex is held (``core.follow.restart_parameters``; the rest is held and written back bit for
bit; the kernel is told it re-settles a region, ``region_restart``: it leaves out the stiffest level and keeps a
point the safeguard held back without its data term), or
start again from the layout as it was before the sequence (``'TEMPLATE'``: every frame the wrap a single
wrap onto that frame would make, independent of the others). A frame that fails is put back (the layout
keeps the previous frame's shape) and reported. :meth:`SequenceRun.finish` puts the layout back as the first frame left
it and writes the keys and keyframes; the scene's frame is set back.
"""

import time

import numpy as np

from ..core import follow, sequence, transforms
from ..core.errors import ERRORS, LayoutError
from ..core.sequence import FrameOutcome, SequenceResult
from . import anchors as anchor_data
from . import attributes, wrap_reads
from . import layout as layout_data
from . import target as target_data
from .wrap_session import WrapSession

WARM_RESTS = ("PREVIOUS", "TEMPLATE")
"""Where the frames after the first start: the previous frame's result (its shape the springs' rest), or the
layout as it was before the sequence (each frame wrapped anew, as a single wrap of it would be)."""


def collection_objects(collection) -> list:
    """The mesh objects of ``collection`` (its children's too), sorted by name: one per frame."""
    objects = [obj for obj in collection.all_objects if obj.type == "MESH"]
    return [objects[index] for index in sequence.frame_objects([obj.name for obj in objects], objects)]


def _settings_snapshot(layout) -> tuple:
    settings = layout.springwrap
    return (
        settings.target_signature,
        anchor_data.read_anchors(layout),
        settings.active_anchor_index,
        settings.anchors_signature,
    )


def _restore(layout, snapshot: tuple) -> None:
    """Put back a (attributes snapshot, settings snapshot) pair: the layout's mesh and what a wrap writes on it."""
    attributes.restore_snapshot(layout, snapshot[0])
    _restore_settings(layout, snapshot[1])


def _restore_settings(layout, snapshot: tuple) -> None:
    target_signature, anchor_list, active_index, anchors_signature = snapshot
    settings = layout.springwrap
    settings.target_signature = target_signature
    if len(settings.anchors) or len(anchor_list.vertex_indices):
        anchor_data.write_anchors(layout, anchor_list, active_index, anchors_signature)


class SequenceRun:
    """A wrap of ``layout`` over ``frames`` (a list of frame numbers), one frame per :meth:`advance`.

    ``parameters``: the wrap's ``core.wrap_inputs.WrapParameters``. ``collection``: None wraps onto the layout's
    target at each frame; a collection wraps the i-th frame onto its i-th mesh object by name. The constructor
    checks and writes nothing; the first :meth:`advance` (the first frame) raises one of ``ERRORS`` and leaves
    the scene as it was when that frame fails. The layout must stay in object mode throughout.
    """

    def __init__(self, context, layout, parameters, frames, collection=None, warm_rest: str = "PREVIOUS"):
        if warm_rest not in WARM_RESTS:
            raise LayoutError(f"Warm rest must be one of {', '.join(WARM_RESTS)}, not {warm_rest!r}")
        self.context = context
        self.scene = context.scene
        self.layout = layout
        self.parameters = parameters
        self.frames = list(frames)
        self.warm_rest = warm_rest
        self.original_frame = (self.scene.frame_current, self.scene.frame_subframe)
        self.objects = None
        if collection is not None:
            self.objects = collection_objects(collection)
            sequence.frame_objects([obj.name for obj in self.objects], self.frames)  # enough of them
            if layout.name in {obj.name for obj in self.objects}:
                raise LayoutError(f"The layout '{layout.name}' is in the collection of frame targets")
        keys = layout.data.shape_keys
        names = [] if keys is None else [block.name for block in keys.key_blocks]
        reference = None if keys is None or keys.reference_key is None else keys.reference_key.name
        sequence.refuse_own_keys(layout.name, names, reference)
        self.before = layout_data.read_layout(layout).positions.copy()  # local, as it was
        self.initial = None  # 'TEMPLATE': the layout as it was (attributes, settings), where each frame starts
        if warm_rest == "TEMPLATE":
            self.initial = (attributes.take_snapshot(layout), _settings_snapshot(layout))
        self.shapes: dict[int, np.ndarray] = {}
        self.outcomes: list[FrameOutcome] = []
        self.first_snapshot = None
        self.first_result = None  # the first frame's WrapResult
        self.distances = None  # (N,) each vertex's distance to the target of the frame that last settled it
        self.step_seconds: dict[int, dict[str, float]] = {}  # per frame: seconds of each step (see _Clock)
        self.edges = layout_data.read_layout_topology(layout).edges

    @property
    def done(self) -> bool:
        return len(self.outcomes) >= len(self.frames)

    @property
    def next_frame(self) -> int | None:
        return None if self.done else self.frames[len(self.outcomes)]

    def _frame_target(self, index: int):
        """The target of the ``index``-th frame, the scene set to that frame."""
        self.scene.frame_set(self.frames[index])
        depsgraph = self.context.evaluated_depsgraph_get()
        if self.objects is not None:
            return target_data.read_object_target(depsgraph, self.objects[index])
        return target_data.read_target(depsgraph, self.layout)

    def _frame(self, index: int, start: float) -> FrameOutcome:
        """Wrap the ``index``-th frame and write it; its outcome. Raises what went wrong (nothing is written then).

        A later frame with ``warm_rest='PREVIOUS'`` re-wraps only where the target changed (``core.follow``: a
        vertex's surface distance changed since the frame that last settled it, or its face-point moved), that
        region from the template's shape (``core.follow.restarted``), the rest held and written back bit for bit;
        a frame in which nothing changed keeps the previous frame's shape unwrapped."""
        frame = self.frames[index]
        steps = self.step_seconds.setdefault(frame, {})
        clock = _Clock(steps)
        target = self._frame_target(index)
        clock.lap("target")
        region = None
        before = None
        previous = None
        reads = None
        if index > 0 and self.initial is not None:  # 'TEMPLATE': from the layout as it was, as frame 0
            previous = (attributes.take_snapshot(self.layout), _settings_snapshot(self.layout))
            _restore(self.layout, self.initial)
        elif index > 0:
            reads = wrap_reads.read(self.context, self.layout, target)  # the session's reads too: read once
            before = reads.arrays
            world = transforms.world_positions(before)
            same_topology = self.layout.springwrap.target_signature == target.signature
            region, _after = follow.changed_region(
                target, world, before.state, same_topology, self.distances, self.edges, follow.RESTART_RINGS
            )
            clock.lap("region")
            if not region.any():
                return FrameOutcome(frame, True, time.perf_counter() - start, 0, "")
        try:
            session = WrapSession(
                self.context,
                self.layout,
                self.parameters if region is None else follow.restart_parameters(self.parameters, region),
                target=target,
                region=region,
                reads=reads,
                template_share=follow.TEMPLATE_SHARE,
                from_template=region is not None,
            )
        except Exception:
            if previous is not None:
                _restore(self.layout, previous)
            raise
        clock.lap("session")
        try:
            session.run()
            clock.lap("solve")
            result = session.finish(measure=index == 0)  # the first frame's read-out is what the layout keeps
            if region is not None:
                positions = follow.merged(layout_data.read_layout(self.layout).positions, before.positions, region)
                self.layout.data.vertices.foreach_set("co", positions.reshape(-1))
                self.layout.data.update()
        except Exception:
            session.cancel()
            if previous is not None:
                _restore(self.layout, previous)
            raise
        if self.initial is None:  # where each vertex was settled, for the next frame's change ('TEMPLATE': none)
            self._measure(target, region)
        if index == 0:
            self.first_result = result
        clock.lap("write")
        return FrameOutcome(frame, True, time.perf_counter() - start, result.iterations, "")

    def _measure(self, target, region) -> None:
        """Keep each vertex's distance to ``target`` as the frame left it; a vertex held (outside ``region``)
        keeps the distance it was settled at, so that a slow change adds up until it counts."""
        world = transforms.world_positions(layout_data.read_layout(self.layout))
        if region is None:
            self.distances = follow.surface_distances(target, world)
        else:
            self.distances = self.distances.copy()
            self.distances[region] = follow.surface_distances(target, world[region])

    def advance(self) -> FrameOutcome:
        """Wrap the next frame and write it into the layout (its basis, as a wrap does). The first frame's failure is
        raised after putting everything back; a later frame's is kept in its outcome, the layout as it was."""
        index = len(self.outcomes)
        start = time.perf_counter()
        try:
            outcome = self._frame(index, start)
        except Exception as error:  # a frame's failure is reported (the first frame's raised), never half-written
            if index == 0:
                self._restore_frame()
                raise
            outcome = FrameOutcome(self.frames[index], False, time.perf_counter() - start, 0, _message(error))
        if outcome.ok:
            self.shapes[outcome.frame] = layout_data.read_layout(self.layout).positions.copy()
        if index == 0:
            self._clear_old_keys()
            self.first_snapshot = (attributes.take_snapshot(self.layout), _settings_snapshot(self.layout))
        self.outcomes.append(outcome)
        return outcome

    def _clear_old_keys(self) -> None:
        """Remove an earlier sequence's keys (the first frame, an ordinary wrap, carried them over)."""
        if self.layout.data.shape_keys is not None:
            self.layout.shape_key_clear()

    def _restore_frame(self) -> None:
        frame, subframe = self.original_frame
        self.scene.frame_set(frame, subframe=subframe)

    def finish(self, stopped: bool = False) -> SequenceResult:
        """Put the layout back as the first frame left it, write a key per frame done and its keyframes, and set
        the scene's frame back. Without any frame done nothing was written."""
        if self.outcomes:
            _restore(self.layout, self.first_snapshot)
            write_keys(self.layout, sequence.key_positions(self.outcomes, self.shapes, self.before))
        self._restore_frame()
        return SequenceResult(self.layout.name, tuple(self.outcomes), len(self.frames), stopped and not self.done)

    def status_text(self) -> str:
        """The progress line shown in the status bar and the header."""
        done = len(self.outcomes)
        failed = sum(not outcome.ok for outcome in self.outcomes)
        text = f"Springwrap: wrapping '{self.layout.name}' frame {done + 1} of {len(self.frames)}"
        if self.next_frame is not None:
            text += f" (frame {self.next_frame})"
        if failed:
            text += f", {failed} failed"
        return text + "  —  Esc / right-click: stop, keeping the frames done"


class _Clock:
    """The seconds of a frame's steps, each lap into ``steps`` under its name: ``target`` (the frame set, the
    target read and built), ``region`` (where it changed), ``session`` (the wrap's inputs and solver), ``solve``
    (the iterations), ``write`` (the result written, merged and measured)."""

    def __init__(self, steps: dict):
        self.steps = steps
        self.last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.steps[name] = self.steps.get(name, 0.0) + now - self.last
        self.last = now


def _message(error: BaseException) -> str:
    return str(error) if isinstance(error, ERRORS) else f"{type(error).__name__}: {error}"


def write_keys(layout, keys: list) -> None:
    """A reference key (the layout as it is) and one key per (frame, local positions), each keyed 1 on its frame
    and 0 on its neighbours'."""
    if layout.data.shape_keys is None:
        layout.shape_key_add(name="Basis", from_mix=False)
    frames = [frame for frame, _positions in keys]
    blocks = []
    for frame, positions in keys:
        block = layout.shape_key_add(name=sequence.key_name(frame), from_mix=False)
        block.data.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).reshape(-1))
        blocks.append(block)
    for block, points in zip(blocks, sequence.key_values(frames)):
        for frame, value in points:
            block.value = value
            block.keyframe_insert("value", frame=frame)
    key = layout.data.shape_keys
    action = key.animation_data.action if key.animation_data is not None else None
    for curve in _fcurves(action):
        for point in curve.keyframe_points:
            point.interpolation = "LINEAR"
    layout.data.update()


def _fcurves(action) -> list:
    """The F-curves of ``action`` (in Blender 5 they live in the action's layered channel bags)."""
    if action is None:
        return []
    curves = list(getattr(action, "fcurves", None) or [])
    for layer in getattr(action, "layers", ()):
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", ()):
                curves.extend(bag.fcurves)
    return curves
