"""Render the user guide's shape keys picture (docs/img/guide-shape-keys.png) headless.

    .venv/bin/python docs/img/render_shape_keys.py [--output-dir docs/img]

The layout is a quad sphere of radius 1 (a cube cut 16 x 16 a side, pushed onto the sphere) with a key
"Bump": a smooth bump on the cap facing the camera and the right, 0.25 high at its centre. It is snapped and wrapped
(``springwrap.snap``, ``springwrap.wrap``, the keys carried over) onto an ellipsoid twice its size (semi-axes
2.2, 2.0, 1.8). Left: the template with the key at 1; right: the wrapped layout with the key at 1; both
coloured by the key's offset (white none, red the largest of each). Workbench engine, the set-up of
``render_guide.py``. Prints the bump's height on both.
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import bmesh
import numpy as np
from mathutils import Matrix, Vector

sys.path.insert(0, str(Path(__file__).resolve().parent))
import render_guide

SEMI_AXES = (2.2, 2.0, 1.8)
BUMP_HEIGHT = 0.25
BUMP_ANGLE = 40.0  # degrees around BUMP_AXIS
BUMP_AXIS = (0.8, -0.6, 0.0)
"""Where the bump points: towards the camera and to the right, so that it shows in the outline."""
TEMPLATE_X = -3.7
"""Where the template's copy stands (the wrapped layout is at the origin)."""


def quad_sphere(name: str, cuts: int) -> bpy.types.Object:
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    obj = bpy.context.active_object
    obj.name = name
    editable = bmesh.new()
    editable.from_mesh(obj.data)
    bmesh.ops.subdivide_edges(editable, edges=editable.edges[:], cuts=cuts - 1, use_grid_fill=True)
    for vertex in editable.verts:
        vertex.co = vertex.co.normalized()
    editable.to_mesh(obj.data)
    editable.free()
    return obj


def frozen(obj: bpy.types.Object, name: str, offset: float) -> tuple[bpy.types.Object, np.ndarray]:
    """A mesh of ``obj`` as shown (its keys' mix), moved by ``offset`` along x, coloured by the key's offset;
    and that offset per vertex."""
    mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    mesh.name = name
    for attribute_name in [a.name for a in mesh.attributes if a.name.startswith("springwrap_")]:
        mesh.attributes.remove(mesh.attributes[attribute_name])
    shown = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", shown)
    basis = np.empty_like(shown)
    obj.data.shape_keys.reference_key.data.foreach_get("co", basis)
    offsets = np.linalg.norm((shown - basis).reshape(-1, 3), axis=1)
    copy = bpy.data.objects.new(name, mesh)
    copy.matrix_world = Matrix.Translation((offset, 0.0, 0.0))
    bpy.context.scene.collection.objects.link(copy)
    weight = (offsets / max(float(offsets.max()), 1e-12))[:, None]
    white, red = np.array([0.92, 0.92, 0.92, 1.0]), np.array([0.85, 0.1, 0.05, 1.0])
    render_guide.paint(copy, (1.0 - weight) * white + weight * red)
    return copy, offsets


def run(output_dir: Path) -> None:
    import addon_utils

    bpy.ops.wm.read_homefile(use_empty=True)
    addon_utils.enable("springwrap", default_set=True, handle_error=None)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=96, ring_count=48, radius=1.0)
    target = bpy.context.active_object
    target.name = "Ellipsoid"
    points = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
    target.data.vertices.foreach_get("co", points)
    target.data.vertices.foreach_set("co", (points.reshape(-1, 3) * SEMI_AXES).astype(np.float32).ravel())
    target.data.update()

    layout = quad_sphere("Layout", 16)
    rest = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
    layout.data.vertices.foreach_get("co", rest)
    normals = rest.reshape(-1, 3).astype(np.float64)
    cosine = normals @ np.array(BUMP_AXIS)
    floor = np.cos(np.radians(BUMP_ANGLE))
    bump = BUMP_HEIGHT * np.clip((cosine - floor) / (1.0 - floor), 0.0, 1.0) ** 2
    layout.shape_key_add(name="Basis")
    key = layout.shape_key_add(name="Bump", from_mix=False)
    key.data.foreach_set("co", (normals * (1.0 + bump[:, None])).astype(np.float32).ravel())
    key.value = 1.0
    layout.springwrap.target = target
    bpy.context.view_layer.objects.active = layout
    before, before_offsets = frozen(layout, "Template", TEMPLATE_X)
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    assert bpy.ops.springwrap.wrap(max_iterations=400) == {"FINISHED"}
    after, after_offsets = frozen(layout, "Wrapped", 0.0)
    print(f"bump height: template {before_offsets.max():.4f}, wrapped {after_offsets.max():.4f}")

    scene = bpy.context.scene
    render_guide.setup_render(scene, target)
    scene.render.resolution_x, scene.render.resolution_y = render_guide.RESOLUTION[0], 400
    camera = scene.camera
    look_at = Vector((TEMPLATE_X / 2.0 + 0.5, 0.0, 0.0))
    camera.location = Vector((TEMPLATE_X / 2.0 + 0.5, -13.5, 3.0))
    camera.rotation_euler = (look_at - camera.location).to_track_quat("-Z", "Y").to_euler()
    render_guide.render(scene, [before, after], output_dir / "guide-shape-keys.png")


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
