"""The GUI lane's drag during a wrap (``gui_pair_tool.py`` runs it, the pair tool on the body): the Wrap button's
live wrap started as a button press does, a pair's target end dragged along the scan with simulated mouse events
while it runs, then the checks: the running wrap took the drag (the pair's vertex went past the pair's old end
toward its new one, and reached it, before the wrap ended), the wrap ended by itself with the pair as dragged, and
Ctrl+Z steps back as the user guide says (each edit one undo step, the wrap one): over the wrap (the pair as
dragged), then over the drag (the layout and its pairs as before the wrap, bit for bit). Redraws per second during
the wrap are counted.

The wrap's iterations are slowed here (:data:`ITERATION_SECONDS` each, as the add-on tests slow theirs): the
body's wrap from where it is takes a few dozen iterations, about a second on a quiet machine, less than the
software-drawn window's redraw (1 to 5 s); every move of a drag starts the wrap's schedule again, so the slowed
wrap outlasts the drag on any machine and ends by itself after it.
"""

import sys
import time

import bpy

import numpy as np
from gui_layout_data import anchors_of, snapshot, world_of

ITERATION_SECONDS = 1.0
"""What each of the wrap's iterations costs at least during these steps: a schedule of some twenty iterations then
outlasts the time between two mouse moves (a redraw of the software-drawn window or more on a loaded machine)."""
MOVES = 10
"""Mouse moves of the drag."""
MOVE_PIXELS = 8.0
"""Pixels of each move, away from the pair's vertex."""
FOLLOWED = 0.5
"""How far the pair's vertex must have gone from the pair's old end toward its new one, as a share of the way,
while the wrap still runs (only the drag takes it past the old end)."""
TURN = 75
"""Degrees the drag may turn from straight away from the pair's vertex to stay over the target: still away from it,
so only the drag takes the vertex past the pair's old end."""
ARRIVED = 0.1
"""How near the pair's new end the vertex must come (a share of the drag's length) while the wrap still runs."""
WAIT_SECONDS = 600.0
"""Longest the wrap may take (a loaded machine)."""


def slowed(session_class):
    """Make every ``WrapSession.step`` of ``session_class`` take at least :data:`ITERATION_SECONDS` per iteration;
    the function that puts it back."""
    original = session_class.step

    def step(self, iterations):
        time.sleep(ITERATION_SECONDS * max(int(iterations), 1))
        return original(self, iterations)

    session_class.step = step
    return lambda: setattr(session_class, "step", original)


def steps(tool, pair: int):
    """The steps (``tool``: ``gui_pair_tool.PairToolSteps``, the pair tool running; ``pair``: the index of a pair
    whose two ends are apart on the screen)."""
    wf, check, ui = tool.workflow, tool.workflow.check, tool.ui
    wrap_session = sys.modules["springwrap.blender.wrap_session"]
    layout = bpy.data.objects["Body"]
    layout.springwrap.pair_live = False  # with a wrap running, edits go to it either way
    with ui.override():
        bpy.ops.ed.undo_push(message="GUI lane: before the wrap")
    before = snapshot(layout)
    vertex = layout.springwrap.anchors[pair].vertex_index
    start = np.array(layout.springwrap.anchors[pair].location)
    # Drag away from the vertex: the running wrap pulls it toward the pair's old end until the drag reaches it, so
    # only the drag can take it past that end toward the new one.
    away = tool.pixel(start) - tool.pixel(world_of(layout)[vertex])
    away = away.normalized() if away.length > 1.0 else away.orthogonal().normalized()
    step = tool.drag_on_target(layout.springwrap.target, tool.pixel(start), away, MOVES, MOVE_PIXELS, TURN)
    # The Wrap button's defaults: Blender remembers the properties of the lane's earlier wraps.
    properties = bpy.ops.springwrap.wrap.get_rna_type().properties
    defaults = {name: properties[name].default for name in ("spring_resolution", "tolerance", "max_iterations")}
    handle = bpy.types.SpaceView3D.draw_handler_add(tool.count_draw, (), "WINDOW", "POST_PIXEL")
    restore = slowed(wrap_session.WrapSession)
    try:
        tool.draws, started = 0, time.perf_counter()
        outcome = ui.call(bpy.ops.springwrap.wrap, **defaults)
        check(outcome == {"RUNNING_MODAL"}, f"the wrap did not go modal: {outcome}")
        session = wrap_session.running_session(layout)
        check(session is not None and session.worker is not None, "the wrap does not solve in a worker thread")
        # The press and the drag's first move at once (Blender handles them before its next redraw).
        pixel, drag_started = tool.pixel(start), time.perf_counter()
        tool.event("MOUSEMOVE", "NOTHING", pixel)
        tool.event("LEFTMOUSE", "PRESS", pixel)
        for _ in range(MOVES):
            pixel = tool.snapped(pixel + step)
            yield from tool.move_by(pixel, 0.05)
            check(wrap_session.running_session(layout) is session, "the wrap ended during the drag")
        tool.event("LEFTMOUSE", "RELEASE", pixel)
        tool.last_mouse = pixel
        yield 0.05
        released = time.perf_counter()
        check(wrap_session.running_session(layout) is session, "the wrap ended at the drag's release")
        released_at = session.total_iterations
        dragged_anchors = anchors_of(layout)
        end = np.array(layout.springwrap.anchors[pair].location)
        along = end - start
        length = float(np.linalg.norm(along))
        check(length > 0.01, f"the drag moved the pair's end {length} m")
        followed = arrived = None  # seconds after the release
        while wrap_session.running_session(layout) is session:
            position = world_of(layout)[vertex]
            progress = float((position - start) @ along) / length**2
            if followed is None and progress > FOLLOWED:
                followed = time.perf_counter() - released
            if arrived is None and np.linalg.norm(position - end) < ARRIVED * length:
                arrived = time.perf_counter() - released
            check(time.perf_counter() - started < WAIT_SECONDS, "the wrap did not end")
            yield 0.02
        seconds = time.perf_counter() - started
    finally:
        restore()
        bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
    check(followed is not None, "the running wrap did not take the vertex past the pair's old end before it ended")
    check(arrived is not None, "the running wrap did not bring the vertex to the pair's new end before it ended")
    result = wrap_session.last_result(layout)
    check(result is not None and result.frames > 1, f"the wrap ended without its frames: {result}")
    check(result.converged, f"the wrap ended at its limit: {result}")
    wrapped = snapshot(layout)
    final = world_of(layout)[vertex]
    check(
        np.linalg.norm(final - end) < 2 * ARRIVED * length,
        f"the wrap ended {np.linalg.norm(final - end)} m off the pair",
    )
    check(layout.springwrap.anchors[pair].vertex_index == vertex, "the wrap changed the pair's vertex")
    check(
        np.linalg.norm(np.array(layout.springwrap.anchors[pair].location) - end) < 1e-5,
        "the wrap did not keep the pair as dragged",
    )
    wf.step(
        "wrap_drag",
        moves=MOVES,
        drag_m=round(length, 4),
        drag_seconds=round(released - drag_started, 3),
        iterations_at_release=released_at,
        followed_after_release_seconds=round(followed, 3),
        arrived_after_release_seconds=round(arrived, 3),
        end_off_pair_m=float(np.linalg.norm(final - end)),
        iterations=result.iterations,
        frames=result.frames,
        wrap_seconds=round(seconds, 3),
        solver_seconds=round(result.kernel_seconds, 3),
        redraws_per_second=round(tool.draws / seconds, 2),
    )
    wf.shot("11-wrap-drag", view=True)

    # Ctrl+Z: over the wrap (one step: the pair as dragged), then over the drag (one step: as before the wrap).
    mouse = tool.last_mouse
    yield from tool.key("Z", mouse, ctrl=True)
    layout = bpy.data.objects["Body"]
    check(anchors_of(layout) == dragged_anchors, "Ctrl+Z over the wrap did not keep the pair as dragged")
    check(snapshot(layout)[0] != wrapped[0], "Ctrl+Z did not undo the wrap")
    yield from tool.key("Z", mouse, ctrl=True)
    layout = bpy.data.objects["Body"]
    check(snapshot(layout) == before, "a second Ctrl+Z did not go back to before the wrap bit for bit")
    check(wrap_session.running_session(layout) is None, "undo left a wrap running")
    wf.step("wrap_drag_undo")
