"""What the benchmarks' worker processes share: this process's memory (``/proc/self``) and processor time, and a
mesh object built from arrays in the ``bpy`` module."""

from __future__ import annotations


def status_kilobytes(field_name: str) -> int:
    """A field of ``/proc/self/status`` in kB (``VmRSS``: resident now, ``VmHWM``: its peak)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(field_name + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field_name}")


def cpu_seconds() -> float:
    """This process's processor time so far, every thread's, user and system."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def reset_peak() -> None:
    """Start ``VmHWM`` again from the resident set now."""
    with open("/proc/self/clear_refs", "w") as clear_refs:
        clear_refs.write("5")


def mesh_object(bpy, name: str, vertices, polygons=None):
    """A new object in the scene holding a mesh of ``vertices`` and equal-size ``polygons`` ((F, k) corner indices;
    None: points only)."""
    import numpy as np

    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    if polygons is not None:
        polygons = np.ascontiguousarray(polygons, dtype=np.int32)
        mesh.loops.add(polygons.size)
        mesh.loops.foreach_set("vertex_index", polygons.ravel())
        mesh.polygons.add(len(polygons))
        mesh.polygons.foreach_set("loop_start", np.arange(0, polygons.size, polygons.shape[1], dtype=np.int32))
    mesh.update(calc_edges=polygons is not None)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj
