"""The snap as an artist runs it, for ``snap_throughput.py``: ``springwrap.snap`` through the operator on a quad
layout over the target, its quality read-out included (measured, and written with the layout), and Blender's
Shrinkwrap modifier (``NEAREST_SURFACEPOINT``) on the same layout, in the same run.

The read-out's share is timed inside the operator (``blender.quality.measure_layout`` and ``write_readout``), by
the wall clock and by the process's processor time over all its threads (which other work on a busy machine
skews far less);
each figure is the best of ``repeat`` snaps, each from the layout detached again. The same snaps are timed with
the read-out in separate steps (the world positions and rest shape made in numpy, then the kernel's
``layout_readout`` and ``surface_distances``: ``core.quality.measure``), alternating with the one-call read-out
(``core.quality.measure_placed``), so both see the same load. Shrinkwrap's time is its depsgraph evaluation plus
reading the positions back, after a first evaluation that built Blender's BVH.
"""

from __future__ import annotations

import time

import _worker
import numpy as np
from _noisy_torus import torus_layout

LAYOUT_SEED = 2


def _timed(module, name: str, spent: dict) -> None:
    """Wrap ``module.name`` so that its time adds up in ``spent['readout']`` (its processor time in
    ``spent['readout_cpu']``)."""
    original = getattr(module, name)

    def timed(*arguments, **options):
        start, start_cpu = time.perf_counter(), _worker.cpu_seconds()
        try:
            return original(*arguments, **options)
        finally:
            spent["readout"] += time.perf_counter() - start
            spent["readout_cpu"] += _worker.cpu_seconds() - start_cpu

    setattr(module, name, timed)


def _separate_steps(local_positions, local_rest, matrix_world, topology, mesh, state=None):
    """``core.quality.measure_placed`` in separate steps: the world positions and rest shape made in numpy, then
    ``core.quality.measure`` (the kernel's ``layout_readout``, then the target's ``surface_distances``)."""
    from springwrap.core import quality, transforms

    world = transforms.transform_points(matrix_world, np.asarray(local_positions, dtype=np.float32).astype(np.float64))
    rest = None if local_rest is None else np.asarray(local_rest, dtype=np.float32)
    return quality.measure(world, quality.world_rest_or_none(matrix_world, rest, world.shape[0]), topology, mesh, state)


def measure(bpy, vertices, triangles, quads: int, repeat: int) -> dict:
    """Snap a ~``quads``-quad layout onto the target through the operator and with Shrinkwrap: the seconds of
    each (best of ``repeat``), the read-out's seconds within the operator's, and the layout's size."""
    import addon_utils

    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        raise RuntimeError("addon_utils.enable('springwrap') failed: run `make setup` first")
    from springwrap.blender import quality as quality_data
    from springwrap.core import quality

    layout_vertices, layout_quads = torus_layout(quads, seed=LAYOUT_SEED)
    target = _worker.mesh_object(bpy, "OperatorTarget", vertices, triangles)
    layout = _worker.mesh_object(bpy, "OperatorLayout", layout_vertices, layout_quads)
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    spent = {"readout": 0.0, "readout_cpu": 0.0}
    measure_layout, write_readout = quality_data.measure_layout, quality_data.write_readout
    _timed(quality_data, "measure_layout", spent)
    _timed(quality_data, "write_readout", spent)
    one_call = quality.measure_placed
    ways = {"separate_steps": _separate_steps, "one_call": one_call}  # the one call last: its read-out is kept
    try:
        if bpy.ops.springwrap.snap(mode="SURFACE") != {"FINISHED"}:  # the target read and cached once
            raise RuntimeError("springwrap.snap failed")
        runs = {way: [] for way in ways}
        for _ in range(repeat):
            for way, measure_placed in ways.items():
                quality.measure_placed = measure_placed
                bpy.ops.springwrap.detach()
                spent["readout"] = spent["readout_cpu"] = 0.0
                start, start_cpu = time.perf_counter(), _worker.cpu_seconds()
                if bpy.ops.springwrap.snap(mode="SURFACE") != {"FINISHED"}:
                    raise RuntimeError("springwrap.snap failed")
                runs[way].append(
                    (
                        time.perf_counter() - start,
                        spent["readout"],
                        _worker.cpu_seconds() - start_cpu,
                        spent["readout_cpu"],
                    )
                )
    finally:
        quality_data.measure_layout, quality_data.write_readout = measure_layout, write_readout
        quality.measure_placed = one_call
    seconds, readout_seconds, cpu_seconds, readout_cpu_seconds = min(runs["one_call"])
    steps_seconds, steps_readout_seconds, steps_cpu_seconds, steps_readout_cpu_seconds = min(runs["separate_steps"])
    readout = quality_data.read_readout(layout)

    shrinkwrapped = _worker.mesh_object(bpy, "OperatorShrinkwrap", layout_vertices, layout_quads)
    modifier = shrinkwrapped.modifiers.new("Shrinkwrap", "SHRINKWRAP")
    modifier.wrap_method = "NEAREST_SURFACEPOINT"
    modifier.target = target
    positions = np.empty(len(layout_vertices) * 3, dtype=np.float32)

    def evaluate() -> None:
        shrinkwrapped.data.update()  # the modifier runs again on the next evaluation
        evaluated = shrinkwrapped.evaluated_get(bpy.context.evaluated_depsgraph_get())
        evaluated.data.vertices.foreach_get("co", positions)

    evaluate()  # builds Blender's BVH of the target
    shrinkwrap_seconds = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        evaluate()
        shrinkwrap_seconds = min(shrinkwrap_seconds, time.perf_counter() - start)
    return {
        "layout_vertices": len(layout_vertices),
        "layout_faces": len(layout_quads),
        "seconds": seconds,
        "readout_seconds": readout_seconds,
        "readout_share": readout_seconds / seconds,
        "cpu_seconds": cpu_seconds,
        "readout_cpu_seconds": readout_cpu_seconds,
        "readout_cpu_share": readout_cpu_seconds / cpu_seconds if cpu_seconds > 0 else float("nan"),
        "shrinkwrap_seconds": shrinkwrap_seconds,
        "separate_steps": {
            "seconds": steps_seconds,
            "readout_seconds": steps_readout_seconds,
            "readout_share": steps_readout_seconds / steps_seconds,
            "cpu_seconds": steps_cpu_seconds,
            "readout_cpu_seconds": steps_readout_cpu_seconds,
            "readout_cpu_share": (
                steps_readout_cpu_seconds / steps_cpu_seconds if steps_cpu_seconds > 0 else float("nan")
            ),
        },
        "flipped": int(readout.flipped.sum()),
        "distance_max": float(readout.distances.max()),
    }
