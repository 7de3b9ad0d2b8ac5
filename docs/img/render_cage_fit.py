"""Render the user guide's subdivision cage fit picture (docs/img/guide-cage-fit.png) headless.

    .venv/bin/python docs/img/render_cage_fit.py [--output-dir docs/img]

The target is the feature picture's box with rounded edges (half-size 1, blend radius 0.25, no noise). The
cage is a cube of 4 x 4 quads a side snapped onto it, as a wrap leaves a layout. Left: its level-2
Subdivision Surface as Blender computes it, coloured by the distance to the target (blue on it, red
``HEAT_SCALE`` or more away), with the cage's wires: it cuts the box's edges and corners short. Right: the
same after ``springwrap.fit_subdivision(levels=2)``: the cage has moved out and its surface lies on the box.
Workbench engine, the camera set-up of ``render_guide.py``.
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils import Matrix, Vector

sys.path.insert(0, str(Path(__file__).resolve().parent))
import render_features
import render_guide

HEAT_SCALE = 0.06
"""Distance (model units, the box is 2 across) shown red."""
SHIFT = 1.45
"""Half the distance between the two copies, along x."""


def subdivided_copy(layout: bpy.types.Object, name: str, target_mesh, offset: float) -> bpy.types.Object:
    """A frozen mesh of ``layout``'s level-2 Subdivision Surface, painted by its distance to the target, moved
    by ``offset`` along x."""
    modifier = layout.modifiers.new("Subdivision", "SUBSURF")
    modifier.levels = 2
    evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = bpy.data.meshes.new_from_object(evaluated)
    layout.modifiers.remove(modifier)
    mesh.name = name
    points = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", points)
    distances = np.asarray(target_mesh.closest_points(points.reshape(-1, 3)).distances)
    copy = bpy.data.objects.new(name, mesh)
    copy.matrix_world = Matrix.Translation((offset, 0.0, 0.0))
    bpy.context.scene.collection.objects.link(copy)
    render_guide.paint(copy, render_guide.heat_colours(distances * (render_guide.HEAT_SCALE / HEAT_SCALE)))
    print(f"{name}: distance to the target mean {distances.mean():.4f}, max {distances.max():.4f}")
    return copy


def cage_wires(layout: bpy.types.Object, name: str, offset: float) -> bpy.types.Object:
    wires = render_guide.wire_copy(layout, name, render_guide.DARK_WIRE_COLOUR)
    wires.modifiers["Wires"].thickness = 0.02
    wires.matrix_world = Matrix.Translation((offset, 0.0, 0.0))
    return wires


def run(output_dir: Path) -> None:
    import addon_utils

    import springwrap_kernel

    bpy.ops.wm.read_homefile(use_empty=True)
    addon_utils.enable("springwrap", default_set=True, handle_error=None)
    vertices, quads = render_features.rounded_box(noise=0.0)
    mesh = bpy.data.meshes.new("Box")
    mesh.from_pydata(vertices.tolist(), [], quads.tolist())
    mesh.update()
    target = bpy.data.objects.new("Box", mesh)
    bpy.context.scene.collection.objects.link(target)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    target_mesh = springwrap_kernel.TargetMesh(
        np.ascontiguousarray(vertices, dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.uint32)
    )

    bpy.ops.mesh.primitive_cube_add(size=1.6)
    layout = bpy.context.active_object
    layout.name = "Cage"
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.subdivide(number_cuts=3)
    bpy.ops.object.mode_set(mode="OBJECT")
    layout.springwrap.target = target
    assert bpy.ops.springwrap.snap(mode="SURFACE") == {"FINISHED"}
    before = subdivided_copy(layout, "Before", target_mesh, -SHIFT)
    before_wires = cage_wires(layout, "BeforeCage", -SHIFT)
    assert bpy.ops.springwrap.fit_subdivision(levels=2) == {"FINISHED"}
    after = subdivided_copy(layout, "After", target_mesh, SHIFT)
    after_wires = cage_wires(layout, "AfterCage", SHIFT)

    scene = bpy.context.scene
    render_guide.setup_render(scene, target)
    scene.render.resolution_x, scene.render.resolution_y = render_guide.RESOLUTION[0], 400
    camera = scene.camera
    camera.location = Vector((0.6, -8.6, 4.0))
    camera.rotation_euler = (Vector((0.0, 0.0, -0.1)) - camera.location).to_track_quat("-Z", "Y").to_euler()
    path = output_dir / "guide-cage-fit.png"
    render_guide.render(scene, [before, before_wires, after, after_wires], path)


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
