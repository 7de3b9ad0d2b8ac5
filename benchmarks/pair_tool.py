"""How fast the pair tool answers on the body: measurements, none of them a test.

The case is ``wrap_speed``'s body: the MakeHuman quad body (13,380 vertices) aligned onto the ``heavy`` body,
voxel-remeshed to ~200k triangles (a scan-like target), with 24 landmark anchors, detached and wrapped once through
the operators. Then, as the pair tool does it (``blender.pair_tool``, no window):

1. **Drag**: a pair's target end dragged across the surface in ``--moves`` mouse moves, each a ray cast on the
   target under a mouse position of a view looking at the pair plus the in-place edit written into the anchor list
   (``place_pair``): edits per second (what a drag costs besides the redraw).
2. **Live re-settle per edit**: after each of ``--edits`` edits (a pair's target end moved 1-2 cm along the
   surface), the Live re-settle: a new ``WrapSession`` from the layout as it is (warm start, the anchors as edited:
   its build time), solved to convergence (the solve time), written (``finish``). Aim: within 0.3 s of solving.
3. **Hover**: the layout vertex under the mouse (``vertex_under_mouse``, the layout's picking surface cached), per
   mouse move.
4. **Live drag**: a pair's target end dragged in ``--live-moves`` mouse moves (60 a second) while a Live re-settle
   runs in its worker thread, each move handed to the running solver (``blender.pair_live.send``, the newest
   wins), the main thread writing frames between the moves as the tool's timer does: the latency from a mouse move
   to the first frame written that the solver computed with that move's anchors (or a later move's), without the
   redraw.

Redraws per second while dragging need a window: the GUI lane (``make test-gui``) measures them under its software
OpenGL and reports them with its pair-tool step.

Run: ``.venv/bin/python benchmarks/pair_tool.py [--edits 8] [--moves 40] [--json out/bench/pair_tool.json]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))

from benchmarks._machine import write_json  # noqa: E402 - after the path is set
from benchmarks.wrap_speed import aligned_template, body_case  # noqa: E402

WIDTH, HEIGHT = 1280, 960
"""The view's region in pixels."""


def looking_at(point, normal, distance=0.6, half_height=0.25):
    """A ``pair_pick.View``: orthographic, from ``distance`` along ``normal`` of ``point``, ``half_height`` metres
    from the centre to the top of the region."""
    from springwrap.core import pair_pick

    forward = -np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
    side = np.cross(forward, [0.0, 0.0, 1.0] if abs(forward[2]) < 0.9 else [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, forward)
    eye = np.asarray(point, dtype=np.float64) - distance * forward
    view = np.eye(4)
    view[:3, :3] = np.stack([side, up, -forward])
    view[:3, 3] = -view[:3, :3] @ eye
    projection = np.diag([HEIGHT / WIDTH / half_height, 1.0 / half_height, -2.0 / 10.0, 1.0])
    return pair_pick.make_view(projection @ view, WIDTH, HEIGHT)


def body_scene(case, vertices, triangles):
    """The target, and the layout aligned, detached, anchored and wrapped once (the operators)."""
    import bpy

    from benchmarks.retarget import baselines

    aligned, landmark_vertices, anchors = aligned_template(case)
    baselines.clear_scene()
    target = baselines.mesh_object("Target", vertices, triangles)
    layout = baselines.mesh_object("Layout", aligned, case.layout_quads)
    layout.springwrap.target = target
    bpy.context.view_layer.update()
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    bpy.ops.springwrap.detach(only_selected=False)
    for vertex, position in zip(landmark_vertices.tolist(), anchors.tolist()):
        bpy.ops.springwrap.anchor_add(vertex_index=int(vertex), location=position, use_location=True)
    bpy.ops.springwrap.wrap()
    return target, layout


def measure(case, vertices, triangles, edits: int, moves: int, live_moves: int) -> dict:
    import bpy

    from springwrap.blender import pair_tool
    from springwrap.core import pair_pick

    target, layout = body_scene(case, vertices, triangles)
    context = bpy.context
    mesh = pair_tool.target_data.read_target(context.evaluated_depsgraph_get(), layout).mesh
    rng = np.random.default_rng(0)
    results = {"layout_vertices": len(layout.data.vertices), "target_triangles": int(len(triangles))}

    # 1. A drag of pair 1's target end, and 3. hovering, in a view looking at it.
    anchor = layout.springwrap.anchors[0]
    start = np.array(anchor.location)
    view = looking_at(start, start - np.mean(mesh.bounding_box(), axis=0))
    centre = pair_pick.project(view, start[None])[0][0]
    path = centre + np.stack([np.linspace(0, 120, moves), 40 * np.sin(np.linspace(0, 3, moves))], axis=1)
    begin = time.perf_counter()
    placed = 0
    for mouse in path:
        point = pair_tool.target_under_mouse(context, layout, view, mouse)
        if point is not None:
            pair_tool.place_pair(context, layout, int(anchor.vertex_index), point)
            placed += 1
    drag_seconds = time.perf_counter() - begin
    results["drag"] = {"moves": moves, "placed": placed, "moves_per_second": moves / drag_seconds}
    pair_tool.vertex_under_mouse(layout, view, centre)  # builds the picking surface once
    begin = time.perf_counter()
    for mouse in path:
        pair_tool.vertex_under_mouse(layout, view, mouse)
    results["hover"] = {"moves": moves, "moves_per_second": moves / (time.perf_counter() - begin)}

    # 2. Live: an edit, then a re-settle from the layout as it is, in the modal's paced frames.
    rows = []
    for edit in range(edits):
        index = int(rng.integers(len(layout.springwrap.anchors)))
        item = layout.springwrap.anchors[index]
        vertex = int(item.vertex_index)
        moved = np.array(item.location) + rng.normal(size=3) * 0.01
        point = mesh.closest_points(moved[None]).positions[0]
        pair_tool.place_pair(context, layout, vertex, point)
        rows.append(settle_row(context, layout, vertex, edit))
    results["settle"] = rows
    results["live_drag"] = live_drag(context, layout, view, path[: max(2, live_moves)])
    for name in ("build_seconds", "first_frame_seconds", "half_way_seconds", "solve_seconds", "total_seconds"):
        results[f"settle_median_{name}"] = float(np.median([row[name] for row in rows]))
    return results


REDRAW_SECONDS = 0.005
"""What a frame's redraw costs the main thread between two frames of the re-settle (a GPU's)."""
MOUSE_SECONDS = 1.0 / 60.0
"""Between two mouse moves of the Live drag."""


def live_drag(context, layout, view, path) -> dict:
    """Pair 1's target end dragged along ``path`` (region pixels) while a Live re-settle runs: per move, the seconds
    from handing it to the solver to the first frame written that was solved with its anchors (or a later move's)."""
    from springwrap.blender import pair_live, pair_tool

    item = layout.springwrap.anchors[0]
    vertex = int(item.vertex_index)
    session = pair_tool.start_settle(context, layout)
    solved_with: dict = {}  # id of a frame's positions -> the anchor list the solver had when it computed them
    current_layout, write_frame = session.current_layout, session._write_frame

    def snapshot():  # in the worker thread
        anchors_then = session.anchors
        positions, state = current_layout()
        solved_with[id(positions)] = anchors_then
        return positions, state

    sent: list = []  # (seconds sent, anchor list object, latency or None) per move
    latencies: list = []

    def write(positions, state):  # in the main thread
        write_frame(positions, state)
        anchors_then = solved_with.pop(id(positions), None)
        now = time.perf_counter()
        newest = next((row for row, (_t, list_, _l) in enumerate(sent) if list_ is anchors_then), -1)
        for row in range(newest + 1):
            if sent[row][2] is None:
                sent[row] = (sent[row][0], sent[row][1], now - sent[row][0])
                latencies.append(now - sent[row][0])

    session.current_layout, session._write_frame = snapshot, write
    pair_tool.advance_settle(session)  # the first frame; the rest in the worker
    for mouse in path:
        point = pair_tool.target_under_mouse(context, layout, view, mouse)
        if point is not None:
            pair_tool.place_pair(context, layout, vertex, point)
            begin = time.perf_counter()
            pair_live.send(session, layout)
            sent.append((begin, session.anchors_edited, None))
        deadline = time.perf_counter() + MOUSE_SECONDS
        while time.perf_counter() < deadline:
            pair_tool.advance_settle(session)
            time.sleep(REDRAW_SECONDS)
    deadline = time.perf_counter() + 5.0
    while any(row[2] is None for row in sent) and time.perf_counter() < deadline and not session.done:
        pair_tool.advance_settle(session)
        time.sleep(REDRAW_SECONDS)
    session.finish()
    answered = np.array(latencies)
    result = {
        "moves": len(sent),
        "answered": int(answered.size),
        "median_seconds": float(np.median(answered)) if answered.size else float("nan"),
        "p90_seconds": float(np.percentile(answered, 90)) if answered.size else float("nan"),
        "max_seconds": float(answered.max()) if answered.size else float("nan"),
        "frames": session.frames,
    }
    print(
        f"live drag: {result['answered']} of {result['moves']} moves answered, a move to its first solved frame: "
        f"median {result['median_seconds'] * 1000:.0f} ms, p90 {result['p90_seconds'] * 1000:.0f} ms, max "
        f"{result['max_seconds'] * 1000:.0f} ms ({session.frames} frames)",
        flush=True,
    )
    return result


def settle_row(context, layout, vertex: int, edit: int) -> dict:
    """One Live re-settle after an edit of ``vertex``'s pair, as the pair tool runs it (paced frames, each written):
    when the layout first moved, when the edited vertex had made half of its way, when it converged."""
    from springwrap.blender import pair_tool

    start_position = layout.matrix_world @ layout.data.vertices[vertex].co
    begin = time.perf_counter()
    session = pair_tool.start_settle(context, layout)
    built = time.perf_counter()
    frames = []
    while not session.done:
        shown = session.frames
        pair_tool.advance_settle(session)
        if session.frames != shown:  # a frame with new positions (the later ones come from the worker thread)
            position = np.array(layout.matrix_world @ layout.data.vertices[vertex].co)
            frames.append((time.perf_counter() - begin, position))
        time.sleep(REDRAW_SECONDS)
    session.finish()
    written = time.perf_counter()
    final = np.array(layout.matrix_world @ layout.data.vertices[vertex].co)
    frames.append((written - begin, final))
    way = float(np.linalg.norm(final - np.array(start_position)))
    half_way = next(
        (seconds for seconds, position in frames if np.linalg.norm(final - position) <= 0.5 * way), frames[-1][0]
    )
    row = {
        "edit": edit,
        "iterations": session.total_iterations,
        "frames": session.frames,
        "converged": bool(session.last_report.converged),
        "vertex_moved_m": way,
        "build_seconds": built - begin,
        "first_frame_seconds": frames[0][0],
        "half_way_seconds": half_way,
        "solve_seconds": session.kernel_seconds,
        "total_seconds": written - begin,
    }
    print(
        f"edit {edit}: build {row['build_seconds']:.3f} s, first frame at {row['first_frame_seconds']:.3f} s, "
        f"vertex half way ({way * 1000:.1f} mm) at {half_way:.3f} s, converged after {row['total_seconds']:.3f} s "
        f"({session.total_iterations} iterations, {session.frames} frames, solving {row['solve_seconds']:.3f} s)",
        flush=True,
    )
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edits", type=int, default=8, help="pair edits each followed by a Live re-settle")
    parser.add_argument("--moves", type=int, default=40, help="mouse moves of the drag")
    parser.add_argument("--live-moves", type=int, default=30, help="mouse moves of the drag during a re-settle")
    parser.add_argument("--json", type=Path, default=REPOSITORY / "out" / "bench" / "pair_tool.json")
    arguments = parser.parse_args(argv)

    import bpy  # noqa: F401  (addon_utils needs bpy imported first)

    import addon_utils

    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        print("pair_tool: the springwrap add-on does not enable: run `make setup`", file=sys.stderr)
        return 1
    load_average = os.getloadavg()
    case, vertices, triangles, _voxel = body_case()
    results = measure(case, vertices, triangles, arguments.edits, arguments.moves, arguments.live_moves)
    results["load_average"] = load_average
    results["load_average_end"] = os.getloadavg()
    print(
        f"pair tool on the body ({results['layout_vertices']} vertices, {results['target_triangles']} triangles): "
        f"drag {results['drag']['moves_per_second']:.0f} moves/s, hover {results['hover']['moves_per_second']:.0f} "
        f"moves/s; Live re-settle per edit (median): session built in {results['settle_median_build_seconds']:.3f} s, "
        f"first frame at {results['settle_median_first_frame_seconds']:.3f} s, edited vertex half way at "
        f"{results['settle_median_half_way_seconds']:.3f} s, converged at {results['settle_median_total_seconds']:.3f} s "
        f"(solving {results['settle_median_solve_seconds']:.3f} s) (aim: follows within 0.3 s)",
        flush=True,
    )
    write_json(arguments.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
