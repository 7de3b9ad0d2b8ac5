"""The GUI lane's drag during a wrap (``gui_pair_tool.py`` runs it, the pair tool on the body): the Wrap button's
live wrap started as a button press does, a pair's target end dragged along the scan with simulated mouse events
while it runs, then the checks: the running wrap took the drag (the pair's vertex moved toward the pair's new end
before the wrap ended), the wrap ended by itself with the pair as dragged, and Ctrl+Z steps back as the user guide
says (each edit one undo step, the wrap one): over the wrap (the pair as dragged), then over the drag (the layout
and its pairs as before the wrap, bit for bit). Redraws per second during the wrap are counted.
"""

import sys
import time

import bpy

import numpy as np
from gui_layout_data import anchors_of, snapshot, world_of

WRAP = {"tolerance": 1e-9, "max_iterations": 300}
"""The Wrap button's settings for a wrap long enough to drag a pair during it (a tolerance it never meets: it runs
to the iteration limit, several seconds on the 13,380-vertex body)."""
MOVES = 10
"""Mouse moves of the drag."""
MOVE_PIXELS = (-6.0, -5.0)
"""Pixels of each move."""
FOLLOWED = 0.5
"""Share of its distance to the pair's new end the vertex must have covered while the wrap still runs."""
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
        before_drag = world_of(layout)[vertex]
        yield from tool.drag(tool.pixel(start), steps=MOVES, step=MOVE_PIXELS)
        released = time.perf_counter()
        check(wrap_session.running_session(layout) is session, "the wrap ended before the drag's release")
        dragged_anchors = anchors_of(layout)
        end = np.array(layout.springwrap.anchors[pair].location)
        gap = float(np.linalg.norm(before_drag - end))
        check(np.linalg.norm(end - start) > 0.01, f"the drag moved the pair's end {np.linalg.norm(end - start)} m")
        followed = None  # seconds after the release when the vertex had covered FOLLOWED of the gap
        while wrap_session.running_session(layout) is session:
            left = float(np.linalg.norm(world_of(layout)[vertex] - end))
            if followed is None and left < (1.0 - FOLLOWED) * gap:
                followed = time.perf_counter() - released
            check(time.perf_counter() - started < WAIT_SECONDS, "the wrap did not end")
            yield 0.02
        seconds = time.perf_counter() - started
    finally:
        bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
    result = wrap_session.last_result(layout)
    check(result is not None and result.frames > 1, f"the wrap ended without its frames: {result}")
    check(
        followed is not None,
        f"the running wrap did not follow the drag: the vertex was {gap:.4f} m from the pair's new end",
    )
    wrapped = snapshot(layout)
    final = world_of(layout)[vertex]
    check(np.linalg.norm(final - end) < 0.1 * gap, f"the wrap ended {np.linalg.norm(final - end)} m off the pair")
    check(layout.springwrap.anchors[pair].vertex_index == vertex, "the wrap changed the pair's vertex")
    check(
        np.linalg.norm(np.array(layout.springwrap.anchors[pair].location) - end) < 1e-5,
        "the wrap did not keep the pair as dragged",
    )
    wf.step(
        "wrap_drag",
        moves=MOVES,
        gap_m=round(gap, 4),
        followed_after_release_seconds=round(followed, 3),
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
