"""The files the README's and the user guide's examples name, made from the demo's scene (``make demo``).

    python tests/docs/docs_scene.py FOLDER

writes into FOLDER (tests/docs/test_doc_blocks.py runs every example there):

- ``scan.blend``: ``Scan`` (the demo's target: Suzanne with a forehead hole, subdivided and displaced) and
  ``Layout`` (Suzanne's quads, moved and scaled: a template) with no Springwrap state and no target set, as
  a newcomer's own file would be;
- ``layout.obj`` (the template) and ``scan.ply`` (the target as evaluated), in Blender's frame (Z up, Y
  forward, the retarget script's default), and ``scans/`` holding ``scan_a.ply`` and ``scan_b.ply`` (the
  target, and the target 5 % larger) for a batch;
- ``half.blend``: ``Layout``, the half of Suzanne's quads on the +x side of its local x = 0 plane, placed
  on the target's own plane of symmetry; ``head.obj`` (the target) for the mirror.
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes bmesh and mathutils importable

# isort: split
import bmesh
from mathutils import Matrix

REPOSITORY = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))
import demo  # noqa: E402 - after the path: the demo's scene


def export_selected(obj, path: Path) -> None:
    """Export ``obj`` alone (as evaluated, in world space) to ``path`` (.obj or .ply), Z up and Y forward."""
    for other in bpy.context.view_layer.objects:
        other.select_set(other == obj)
    bpy.context.view_layer.objects.active = obj
    axes = {"forward_axis": "Y", "up_axis": "Z", "export_selected_objects": True, "apply_modifiers": True}
    if path.suffix == ".obj":
        bpy.ops.wm.obj_export(filepath=str(path), export_materials=False, **axes)
    else:
        bpy.ops.wm.ply_export(filepath=str(path), ascii_format=False, **axes)


def keep_positive_x(layout) -> None:
    """Delete the vertices of ``layout`` on the -x side of its local x = 0 plane (the midline stays)."""
    editable = bmesh.new()
    editable.from_mesh(layout.data)
    doomed = [vertex for vertex in editable.verts if vertex.co.x < -1e-6]
    bmesh.ops.delete(editable, geom=doomed, context="VERTS")
    editable.to_mesh(layout.data)
    editable.free()
    layout.data.update()


def main(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    target, _hole, _cut = demo.new_scene()
    target.name = "Scan"
    layout = demo.build_layout(target, "Layout")
    bpy.context.view_layer.objects.active = layout
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "scan.blend"))
    export_selected(layout, folder / "layout.obj")
    export_selected(target, folder / "scan.ply")
    (folder / "scans").mkdir(exist_ok=True)
    export_selected(target, folder / "scans" / "scan_a.ply")
    target.matrix_world = target.matrix_world @ Matrix.Scale(1.05, 4)
    export_selected(target, folder / "scans" / "scan_b.ply")
    target.matrix_world = demo.TARGET_MATRIX
    export_selected(target, folder / "head.obj")

    bpy.data.objects.remove(layout)
    half = demo.add_monkey("Layout")
    half.matrix_world = target.matrix_world
    keep_positive_x(half)
    bpy.data.objects.remove(target)
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "half.blend"))


if __name__ == "__main__":
    main(Path(sys.argv[-1]))
