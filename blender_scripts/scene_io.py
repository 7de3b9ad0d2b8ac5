"""What the retarget and mirror scripts share inside Blender: a mesh file (or a .blend's object) read into
the scene, the wrap's defaults from the kernel, distances to the target, timing laps, an operator run with
its error blamed on the input, and the outputs written all or nothing. (``headless.py`` holds what every
script shares and needs no ``bpy`` at its top.)"""

import argparse
import json
import re
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import ScriptError, addon_module, enable_addon, finite_number, signed_axis, write_all_or_nothing
from mesh_files import MESH_SUFFIXES, MeshFileError, check_blend_file, check_coordinates, check_mesh_file

if TYPE_CHECKING:
    import numpy as np
    from mathutils import Matrix

INPUT_SUFFIXES = (*MESH_SUFFIXES, ".blend")
"""What the scripts read: a mesh file, or an object of a .blend."""

GLTF_TO_BLENDER = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
"""What Blender's glTF importer always does to a file's coordinates (glTF is +Y up): (x, y, z) -> (x, -z, y).
Undone after the import, so that a glTF file is read in the same convention as every other file."""


def wrap_defaults_module():
    """The add-on's ``core.defaults``: the wrap's defaults and ranges in one place (the iteration limit, the
    kernel's ``WrapSettings()``), the add-on enabled first so that its kernel can be imported."""
    return addon_module("core.defaults")


WEIGHT_OPTIONS = (
    ("fairness", "weight of the second differences along the grid lines, 0 to 1"),
    ("arc_length", "weight of the edges against the template's: the spacing along grid lines, 0 to 1"),
    ("thin_plate", "weight of the smoothness at points no grid line runs through, 0 to 0.5"),
    ("constraint", "pull of the layout onto the target, 0 to 1"),
    ("folding", "how far off the surface the layout is still drawn onto it, 0 to 1"),
)
"""The wrap's weights as command-line options: (setting, help)."""


def add_wrap_options(parser: argparse.ArgumentParser, weights: bool) -> None:
    """``--max-iterations`` and ``--tolerance`` (and with ``weights`` the energy's five weights), their defaults
    the add-on's ``core.defaults`` (the kernel's for the settings)."""
    module = wrap_defaults_module()
    defaults = module.wrap_defaults()
    parser.add_argument(
        "--max-iterations", type=int, default=module.MAX_ITERATIONS, help="wrap iteration limit (default %(default)s)"
    )
    parser.add_argument(
        "--tolerance",
        type=finite_number,
        default=defaults.tolerance,
        help="each stiffness level of the wrap ends once an iteration lowers the energy by less than this fraction "
        "(default %(default)s)",
    )
    for name, text in WEIGHT_OPTIONS if weights else ():
        parser.add_argument(
            "--" + name.replace("_", "-"),
            type=finite_number,
            default=getattr(defaults, name),
            help=f"{text} (default %(default)s)",
        )


def frame_matrix(up_axis: str, forward_axis: str) -> "Matrix":
    """The 4x4 rotation from the mesh files' frame (``--up-axis``, ``--forward-axis``) to Blender's (Z up,
    Y forward): the one convention every mesh file is read in; outputs are written back with its inverse."""
    from bpy_extras.io_utils import axis_conversion

    return axis_conversion(from_forward=signed_axis(forward_axis), from_up=signed_axis(up_axis)).to_4x4()


def _import_file(path: Path) -> "Matrix":
    """Run the importer for ``path``'s format with no axis conversion of its own (the coordinates as written,
    whatever the importer's default); the rotation the importer applied anyway (glTF's), to be undone."""
    import addon_utils
    from mathutils import Matrix

    suffix = path.suffix.lower()
    as_written = {"forward_axis": "Y", "up_axis": "Z"}
    if suffix == ".obj":
        bpy.ops.wm.obj_import(filepath=str(path), **as_written)
    elif suffix == ".ply":
        if bpy.app.version >= (4, 0, 0):
            bpy.ops.wm.ply_import(filepath=str(path), **as_written)
        else:  # the Python importer of Blender 3.x applies no conversion
            addon_utils.enable("io_mesh_ply", default_set=True, handle_error=None)
            bpy.ops.import_mesh.ply(filepath=str(path))
    elif suffix == ".stl":
        if bpy.app.version >= (4, 2, 0):
            bpy.ops.wm.stl_import(filepath=str(path), **as_written)
        else:
            addon_utils.enable("io_mesh_stl", default_set=True, handle_error=None)
            bpy.ops.import_mesh.stl(filepath=str(path), axis_forward="Y", axis_up="Z")
    elif suffix in (".glb", ".gltf"):
        addon_utils.enable("io_scene_gltf2", default_set=True, handle_error=None)
        bpy.ops.import_scene.gltf(filepath=str(path))
        return Matrix(GLTF_TO_BLENDER).to_4x4()
    else:
        raise ScriptError(f"{path}: not a mesh file ({', '.join(INPUT_SUFFIXES)})")
    return Matrix.Identity(4)


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


_APPENDED: dict[tuple[str, str], "bpy.types.Object"] = {}
"""The objects a .blend's object brought along when it was appended (a layout's target comes with the layout,
through its pointer), by (file, their name there): the same file named again for one of them gives that object,
not a second copy."""


def _appended_from(path: Path, object_name) -> list:
    """The objects of the .blend ``path`` (the one named ``object_name``, or all) appended to this file, or the one
    an earlier append brought along."""
    key = (str(path.resolve()), object_name)
    earlier = _APPENDED.get(key)
    if earlier is not None:
        try:
            if bpy.data.objects.get(earlier.name) == earlier:
                return [earlier]
        except ReferenceError:  # removed since
            pass
    before = set(bpy.data.objects)
    try:
        with bpy.data.libraries.load(str(path), link=False) as (source, loaded):
            loaded.objects = [name for name in source.objects if object_name is None or name == object_name]
    except (OSError, RuntimeError) as error:
        raise ScriptError(f"{path}: cannot read: {str(error).strip().splitlines()[0]}") from None
    requested = [obj for obj in loaded.objects if obj is not None]
    for obj in set(bpy.data.objects) - before - set(requested):  # what they point to, by their names there
        _APPENDED[(key[0], obj.name)] = obj
    return requested


def open_blend(path: Path | None) -> None:
    """The add-on enabled and, given a ``path``, that .blend opened (checked before Blender reads it)."""
    enable_addon()
    if path is None:
        return
    check_blend_file(path)
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()))
    except RuntimeError as error:
        raise ScriptError(f"{path}: cannot read: {str(error).strip().splitlines()[0]}") from None


def find_mesh(name: str, what: str) -> "bpy.types.Object":
    """The mesh object called ``name`` (the ``what`` of the script's run); raises naming the mesh objects there
    are."""
    obj = bpy.data.objects.get(name)
    if obj is None or obj.type != "MESH":
        meshes = ", ".join(sorted(o.name for o in bpy.data.objects if o.type == "MESH")) or "none"
        raise ScriptError(f"no mesh object '{name}' for the {what} (mesh objects: {meshes})")
    return obj


def load_mesh(path: Path, object_name, role: str, frame: "Matrix") -> "bpy.types.Object":
    """The mesh object of ``path`` (a mesh file, or a .blend's object), linked into the scene, named ``role``.

    A mesh file is checked before its importer sees it (``mesh_files.check_mesh_file``), read with its
    coordinates as written and placed by ``frame`` (:func:`frame_matrix`: the files' convention into
    Blender's), the same for every format; a .blend's object keeps its place (it is in Blender's frame).
    Its world coordinates are then refused when not finite or absurdly large."""
    if path.suffix.lower() == ".blend":
        check_blend_file(path)
        objects = _appended_from(path, object_name)
        placement = None
    else:
        check_mesh_file(path)
        before = set(bpy.data.objects)
        try:
            applied = _import_file(path)
        except RuntimeError as error:
            message = importer_message(str(error))
            raise ScriptError(f"{path}: cannot read: {message}") from None
        objects = [obj for obj in bpy.data.objects if obj not in before]
        bpy.context.view_layer.update()  # world matrices of an imported hierarchy (glTF nodes)
        placement = applied.inverted()
    chosen = _only_mesh(objects, path, object_name)
    world = chosen.matrix_world.copy()
    for obj in objects:  # keep only the chosen mesh in the scene
        if obj is not chosen:
            bpy.data.objects.remove(obj)
    if chosen.name not in bpy.context.scene.collection.objects and not chosen.users_collection:
        bpy.context.scene.collection.objects.link(chosen)
    parent = chosen.parent if placement is None else None
    while parent is not None:  # a .blend's object keeps its parents: appended with it, linked so they are saved
        if not parent.users_collection:
            bpy.context.scene.collection.objects.link(parent)
        parent = parent.parent
    if placement is not None:  # a mesh file: its coordinates as written, in the files' frame
        chosen.parent = None
        chosen.matrix_world = frame @ placement @ world
        bpy.context.view_layer.update()
    if len(chosen.data.vertices) == 0:
        raise ScriptError(f"{path}: the mesh has no vertices")
    if role == "Target" and len(chosen.data.polygons) == 0:
        raise ScriptError(f"{path}: the mesh has no faces to retarget onto")
    check_world_coordinates(chosen, path)
    chosen.name = role
    return chosen


def importer_message(text: str) -> str:
    """The line that says why an importer failed: a Python importer's exception (``AttributeError: ...``) out
    of the traceback it reports, else its last line, without the ``Location: .../ops.py`` it ends with."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip() and not line.startswith("Location:")]
    exceptions = [line for line in lines if re.match(r"^[A-Za-z_.]*(Error|Exception)\b: ", line)]
    return (exceptions[-1] if exceptions else lines[-1] if lines else "unknown error").removeprefix("Error: ")


def check_world_coordinates(obj, path: Path) -> None:
    """Refuse an object whose vertices, placed in the world, are not finite or are absurdly large (what an
    importer made of a file, or a .blend's object); the error names the file and the vertex."""
    import numpy as np

    positions = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", positions)
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    with np.errstate(all="ignore"):
        world = positions.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    try:
        check_coordinates(world, lambda index: f"vertex {index} (world space, as imported)")
    except MeshFileError as error:
        raise ScriptError(f"{path}: {error}") from None


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


def to_file_frame(frame: "Matrix", matrix) -> list:
    """A 4x4 transform of Blender's world (nested lists or a Matrix) as the same transform of the files' frame."""
    from mathutils import Matrix

    return [list(row) for row in frame.inverted() @ Matrix(matrix) @ frame]


def write_outputs(arguments: argparse.Namespace, layout, report: dict, extra=()) -> None:
    """Write every requested output to temporary files, then rename them all (nothing half-written); the OBJ
    in the files' frame (``--up-axis``, ``--forward-axis``), the .blend in Blender's. ``extra``: further
    ``(path, write(temporary path))`` outputs written and renamed with them."""

    def save_blend(path: Path) -> None:
        if bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, copy=True) != {"FINISHED"}:
            raise ScriptError(f"{path}: could not save")

    def export_obj(path: Path) -> None:
        for obj in bpy.context.view_layer.objects:
            obj.select_set(obj == layout)
        bpy.ops.wm.obj_export(
            filepath=str(path),
            export_selected_objects=True,
            export_materials=False,
            forward_axis=arguments.forward_axis,
            up_axis=arguments.up_axis,
        )

    def write_report(path: Path) -> None:
        path.write_text(json.dumps(report, indent=2) + "\n")

    write_all_or_nothing(
        [
            (arguments.output_blend, save_blend),
            (arguments.output_obj, export_obj),
            (arguments.report, write_report),
            *extra,
        ]
    )
