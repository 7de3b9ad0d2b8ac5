"""What the retarget and mirror scripts share inside Blender: a mesh file (or a .blend's object) read into
the scene, the wrap's defaults from the kernel, distances to the target, timing laps, an operator run with
its error blamed on the input, and the outputs written all or nothing. (``headless.py`` holds what every
script shares and needs no ``bpy`` at its top.)"""

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import ScriptError, enable_addon, write_all_or_nothing

if TYPE_CHECKING:
    import numpy as np

MESH_SUFFIXES = (".obj", ".ply", ".glb", ".gltf", ".blend")


def kernel_wrap_defaults():
    """``springwrap_kernel.WrapSettings()``: the wrap's defaults, defined once, in the kernel.

    The kernel comes with the add-on (the legacy zip carries it in the add-on's folder), so the
    add-on is enabled first when the kernel cannot be imported by itself.
    """
    try:
        import springwrap_kernel
    except ImportError:
        enable_addon()
        import springwrap_kernel
    return springwrap_kernel.WrapSettings()


def _import_file(path: Path) -> None:
    """Run the importer for ``path``'s format."""
    import addon_utils

    suffix = path.suffix.lower()
    if suffix == ".obj":
        bpy.ops.wm.obj_import(filepath=str(path))
    elif suffix == ".ply":
        if bpy.app.version >= (4, 0, 0):
            bpy.ops.wm.ply_import(filepath=str(path))
        else:
            addon_utils.enable("io_mesh_ply", default_set=True, handle_error=None)
            bpy.ops.import_mesh.ply(filepath=str(path))
    elif suffix in (".glb", ".gltf"):
        addon_utils.enable("io_scene_gltf2", default_set=True, handle_error=None)
        bpy.ops.import_scene.gltf(filepath=str(path))
    else:
        raise ScriptError(f"{path}: not a mesh file ({', '.join(MESH_SUFFIXES)})")


def _only_mesh(objects: list, path: Path, object_name) -> "bpy.types.Object":
    meshes = [obj for obj in objects if obj.type == "MESH" and (object_name is None or obj.name == object_name)]
    if object_name is not None and not meshes:
        found = ", ".join(sorted(obj.name for obj in objects if obj.type == "MESH")) or "none"
        raise ScriptError(f"{path}: no mesh object '{object_name}' (mesh objects: {found})")
    if not meshes:
        raise ScriptError(f"{path}: holds no mesh")
    if len(meshes) > 1:
        found = ", ".join(sorted(obj.name for obj in meshes))
        raise ScriptError(f"{path}: several mesh objects ({found}): name one with --template-object / --target-object")
    return meshes[0]


def load_mesh(path: Path, object_name, role: str) -> "bpy.types.Object":
    """The mesh object of ``path`` (a mesh file, or a .blend's object), linked into the scene, named ``role``."""
    if not path.is_file():
        raise ScriptError(f"{path}: no such file")
    if path.suffix.lower() == ".blend":
        try:
            with bpy.data.libraries.load(str(path), link=False) as (source, loaded):
                loaded.objects = [name for name in source.objects if object_name is None or name == object_name]
        except (OSError, RuntimeError) as error:
            raise ScriptError(f"{path}: cannot read: {str(error).strip().splitlines()[0]}") from None
        objects = [obj for obj in loaded.objects if obj is not None]
    else:
        before = set(bpy.data.objects)
        try:
            _import_file(path)
        except RuntimeError as error:
            # The importer's last line, without the "Location: .../ops.py" a Python importer's error ends with.
            lines = [line for line in str(error).strip().splitlines() if not line.startswith("Location:")]
            message = (lines[-1] if lines else "unknown error").removeprefix("Error: ")
            raise ScriptError(f"{path}: cannot read: {message}") from None
        objects = [obj for obj in bpy.data.objects if obj not in before]
    chosen = _only_mesh(objects, path, object_name)
    for obj in objects:  # keep only the chosen mesh in the scene
        if obj is not chosen:
            bpy.data.objects.remove(obj)
    if chosen.name not in bpy.context.scene.collection.objects and not chosen.users_collection:
        bpy.context.scene.collection.objects.link(chosen)
    if len(chosen.data.vertices) == 0:
        raise ScriptError(f"{path}: the mesh has no vertices")
    if role == "Target" and len(chosen.data.polygons) == 0:
        raise ScriptError(f"{path}: the mesh has no faces to retarget onto")
    chosen.name = role
    return chosen


def world_vertices(obj) -> "np.ndarray":
    """(N, 3) float64 world positions of an object's evaluated mesh, and its (M, 3) triangles."""
    import numpy as np

    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", positions)
        mesh.calc_loop_triangles()
        triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.uint32)
        mesh.loop_triangles.foreach_get("vertices", triangles)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    world = positions.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    return world, triangles.reshape(-1, 3)


def distances_to_target(layout, target) -> dict:
    """Distances of the layout's vertices to the target surface (world space): mean, max, RMS."""
    import numpy as np

    import springwrap_kernel

    layout_points, _ = world_vertices(layout)
    target_points, triangles = world_vertices(target)
    mesh = springwrap_kernel.TargetMesh(np.ascontiguousarray(target_points, dtype=np.float32), triangles)
    hits = mesh.closest_points(np.ascontiguousarray(layout_points, dtype=np.float32))
    distances = np.asarray(hits.distances, dtype=np.float64)
    size = float(np.linalg.norm(target_points.max(axis=0) - target_points.min(axis=0)))
    return {
        "mean_distance": float(distances.mean()),
        "max_distance": float(distances.max()),
        "rms_distance": float(np.sqrt((distances**2).mean())),
        "target_diagonal": size,
    }


class Laps:
    """Seconds per named step of a run, each counted from the end of the one before (``timings``)."""

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}
        self._clock = time.perf_counter()

    def __call__(self, step: str) -> None:
        now = time.perf_counter()
        self.timings[step] = round(now - self._clock, 4)
        self._clock = now


def run_operator(blame: str, name: str, **properties) -> None:
    """Run ``springwrap.<name>``; its error (it names the object: Template, Target, Retargeted) prefixed by ``blame``."""
    try:
        result = getattr(bpy.ops.springwrap, name)(**properties)
    except RuntimeError as error:
        message = str(error).strip().removeprefix("Error: ").splitlines()[0]
        raise ScriptError(f"{blame}: springwrap.{name}: {message}") from None
    if result != {"FINISHED"}:
        raise ScriptError(f"{blame}: springwrap.{name} returned {sorted(result)}")


def write_outputs(arguments: argparse.Namespace, layout, report: dict) -> None:
    """Write every requested output to temporary files, then rename them all (nothing half-written)."""

    def save_blend(path: Path) -> None:
        if bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, copy=True) != {"FINISHED"}:
            raise ScriptError(f"{path}: could not save")

    def export_obj(path: Path) -> None:
        for obj in bpy.context.view_layer.objects:
            obj.select_set(obj == layout)
        bpy.ops.wm.obj_export(filepath=str(path), export_selected_objects=True, export_materials=False)

    def write_report(path: Path) -> None:
        path.write_text(json.dumps(report, indent=2) + "\n")

    write_all_or_nothing(
        [(arguments.output_blend, save_blend), (arguments.output_obj, export_obj), (arguments.report, write_report)]
    )
