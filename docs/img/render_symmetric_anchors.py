"""Render the user guide's symmetric anchors picture (docs/img/guide-symmetric-anchors.png) headless.

    .venv/bin/python docs/img/render_symmetric_anchors.py [--output-dir docs/img]

The demo's scene (``blender_scripts/demo.py``): Suzanne's quads as a template, scaled (not moved), over a
subdivided, cloud-displaced Suzanne with a hole in the forehead. The template is detached, projected and
snapped as in the demo; then ``anchors_auto(symmetric=True)`` across the target's own mirror plane (an
Empty placed with the target's transform, ``symmetry_object``). Markers at the anchors' target points:
red on the side spread (+x of the Empty), blue their mirrored twins, green on the plane, black anchors left
alone. The template's wires in orange. Workbench engine, the camera of ``render_guide.py``. It prints what
the operator reported and how far each twin target is from the reflection of its partner's.
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import bmesh
import numpy as np
from mathutils import Matrix, Vector

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "blender_scripts"))
import demo
import render_guide

SPACING = 0.3
"""The anchors' spacing (world units; the target is about 3 across)."""
COLOURS = {
    "spread": (0.85, 0.05, 0.05, 1.0),
    "twin": (0.05, 0.25, 0.95, 1.0),
    "plane": (0.1, 0.7, 0.15, 1.0),
    "alone": (0.02, 0.02, 0.02, 1.0),
}


def markers(points: np.ndarray, name: str, colour: tuple) -> bpy.types.Object:
    """Small balls at ``points`` (world space), as one object painted ``colour``."""
    bm = bmesh.new()
    for point in points:
        bmesh.ops.create_icosphere(bm, subdivisions=2, radius=0.04, matrix=Matrix.Translation(Vector(point)))
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    render_guide.paint(obj, colour)
    return obj


def run(output_dir: Path) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    demo.enable_addon()
    target, _hole, _cut = demo.build_target()
    layout = demo.build_layout(target, "Template")
    # Centred on the target's mirror plane (the demo moves it 0.15 along x): a layout whose midline lies off the
    # plane by more than a quarter of an edge has no seed for the topological match (see the guide).
    layout.matrix_world = target.matrix_world @ Matrix.Scale(demo.LAYOUT_SCALE, 4)
    layout.springwrap.target = target
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == layout)
    bpy.context.view_layer.objects.active = layout
    operators = bpy.ops.springwrap
    for result in (
        operators.detach(only_selected=False),
        operators.project(direction="NORMAL", both_directions=True, max_distance=demo.PROJECT_MAX_DISTANCE),
        operators.snap(mode="SURFACE", only_selected=False, max_distance=0.0),
    ):
        assert result == {"FINISHED"}, result
    plane = bpy.data.objects.new("Mirror Plane", None)
    bpy.context.scene.collection.objects.link(plane)
    plane.matrix_world = target.matrix_world.copy()
    bpy.context.view_layer.update()
    result = operators.anchors_auto(spacing=SPACING, symmetric=True, symmetry_axis="X", symmetry_object=plane.name)
    assert result == {"FINISHED"}, result

    items = list(layout.springwrap.anchors)
    vertices = np.array([item.vertex_index for item in items])
    twins = np.array([item.twin_vertex for item in items])
    locations = np.array([tuple(item.location) for item in items])
    normal = np.array(plane.matrix_world.to_3x3().inverted().transposed() @ Vector((1.0, 0.0, 0.0)))
    normal /= np.linalg.norm(normal)
    origin = np.array(plane.matrix_world.translation)
    side = (locations - origin) @ normal
    on_plane = twins == vertices
    alone = twins < 0
    paired = ~on_plane & ~alone
    spread, twin = paired & (side > 0), paired & (side <= 0)
    index_of = {int(vertex): index for index, vertex in enumerate(vertices)}
    partners = np.array([index_of[int(vertex)] for vertex in twins[paired]])
    reflected = locations[partners] - 2.0 * np.outer((locations[partners] - origin) @ normal, normal)
    gaps = np.linalg.norm(locations[paired] - reflected, axis=1)
    print(
        f"{len(items)} anchors: {spread.sum()} pairs, {on_plane.sum()} on the plane, {alone.sum()} alone; "
        f"twin target from the partner's reflection: mean {gaps.mean():.4f}, max {gaps.max():.4f}"
    )

    wires = render_guide.wire_copy(layout, "TemplateWires", render_guide.TEMPLATE_WIRE_COLOUR, outside=True)
    shown = [target, wires]
    for kind, mask in (("spread", spread), ("twin", twin), ("plane", on_plane), ("alone", alone)):
        if mask.any():
            shown.append(markers(locations[mask], f"Anchors {kind}", COLOURS[kind]))
    render_guide.paint(target, render_guide.TARGET_COLOUR)
    scene = bpy.context.scene
    render_guide.setup_render(scene, target)
    render_guide.render(scene, shown, output_dir / "guide-symmetric-anchors.png")


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
