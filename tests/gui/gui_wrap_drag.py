"""The GUI lane's drag during a wrap (``gui_pair_tool.py`` runs it, the pair tool on the body): the Wrap button's
live wrap started as a button press does, a pair's target end dragged along the scan with simulated mouse events
while it runs, then the checks: the running wrap took the drag (the pair's vertex went past the pair's old end
toward its new one, and reached it, before the wrap ended), the wrap then ended at its iteration limit (brought
down once it had followed: a wrap long enough for a drag on a loaded machine would take minutes to reach its own)
with the pair as dragged, and Ctrl+Z steps back as the user guide says (each edit one undo step, the wrap one):
over the wrap (the pair as dragged), then over the drag (the layout and its pairs as before the wrap, bit for
bit). Redraws per second during the wrap are counted.
"""

import sys
import time

import bpy

import numpy as np
from gui_layout_data import anchors_of, snapshot, world_of

WRAP = {"tolerance": 1e-9, "max_iterations": 50_000}
"""The Wrap button's settings for a wrap that outlasts a drag on any machine (a tolerance it never meets, a limit
it would take minutes to reach); once it has followed the drag, its limit is brought down to a few iterations
more (:data:`LAST_ITERATIONS`), so that it ends by itself as a wrap at its limit does."""
LAST_ITERATIONS = 10
"""Iterations the wrap runs on after it has followed the drag."""
MOVES = 10
"""Mouse moves of the drag."""
MOVE_PIXELS = 8.0
"""Pixels of each move, away from the pair's vertex."""
FOLLOWED = 0.5
"""How far the pair's vertex must have gone from the pair's old end toward its new one, as a share of the way,
while the wrap still runs (only the drag takes it past the old end)."""
ARRIVED = 0.1
"""How near the pair's new end the vertex must come (a share of the drag's length) while the wrap still runs."""
WAIT_SECONDS = 300.0
"""Longest the wrap may take (a loaded machine)."""


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
    handle = bpy.types.SpaceView3D.draw_handler_add(tool.count_draw, (), "WINDOW", "POST_PIXEL")
    try:
        tool.draws, started = 0, time.perf_counter()
        outcome = ui.call(bpy.ops.springwrap.wrap, **WRAP)
        check(outcome == {"RUNNING_MODAL"}, f"the long wrap did not go modal: {outcome}")
        session = wrap_session.running_session(layout)
        check(session is not None and session.worker is not None, "the wrap does not solve in a worker thread")
        yield 0.2
        # Drag away from the vertex: the running wrap pulls it toward the pair's old end until the drag reaches it,
        # so only the drag can take it past that end toward the new one.
        away = tool.pixel(start) - tool.pixel(world_of(layout)[vertex])
        away = away.normalized() if away.length > 1.0 else away.orthogonal().normalized()
        drag_started = time.perf_counter()
        yield from tool.drag(tool.pixel(start), steps=MOVES, step=tuple(MOVE_PIXELS * away))
        released = time.perf_counter()
        check(wrap_session.running_session(layout) is session, "the wrap ended before the drag's release")
        released_at = session.total_iterations
        dragged_anchors = anchors_of(layout)
        end = np.array(layout.springwrap.anchors[pair].location)
        along = end - start
        length = float(np.linalg.norm(along))
        check(length > 0.01, f"the drag moved the pair's end {length} m")
        followed = None  # seconds after the release when the vertex had gone FOLLOWED of the way to the new end
        while True:
            check(wrap_session.running_session(layout) is session, "the wrap ended before it followed the drag")
            position = world_of(layout)[vertex]
            progress = float((position - start) @ along) / length**2
            if followed is None and progress > FOLLOWED:
                followed = time.perf_counter() - released
            if np.linalg.norm(position - end) < ARRIVED * length:
                break
            check(
                time.perf_counter() - started < WAIT_SECONDS,
                f"the running wrap did not follow the drag: the vertex went {progress:.0%} of the way to the new end",
            )
            yield 0.02
        arrived = time.perf_counter() - released
        session.parameters = session.parameters._replace(max_iterations=session.total_iterations + LAST_ITERATIONS)
        while wrap_session.running_session(layout) is session:
            check(time.perf_counter() - started < WAIT_SECONDS, "the wrap did not end at its limit")
            yield 0.02
        seconds = time.perf_counter() - started
    finally:
        bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
    result = wrap_session.last_result(layout)
    check(result is not None and result.frames > 1, f"the wrap ended without its frames: {result}")
    check(not result.converged and result.iterations >= session.parameters.max_iterations, "it ended before its limit")
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
