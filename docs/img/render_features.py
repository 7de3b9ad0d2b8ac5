"""Render the user guide's feature-detection picture (docs/img/guide-features.png) headless.

    .venv/bin/python docs/img/render_features.py [--output-dir docs/img]

A box with rounded edges (half-size 1, blend radius 0.25, 40 x 40 quads a face, with a little
radial noise) goes through ``springwrap.detect_features(scale=0.35)``; the picture shows its
region colours (grey flat, red convex) and the detected ridge curves (dark tubes), with the
Workbench engine and the camera set-up of ``render_guide.py``.
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils import Vector

sys.path.insert(0, str(Path(__file__).resolve().parent))
import render_guide


def rounded_box(half=1.0, radius=0.25, cells=40, noise=0.003, seed=1):
    """Vertices and triangles of a welded box with rounded edges (the offset of a smaller box)."""
    inner = half - radius
    a = -1.0 + 2.0 * np.arange(cells + 1) / cells
    u, v = np.meshgrid(a, a, indexing="ij")
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    quads = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4)
    points, faces = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            normal, s = np.zeros(3), np.zeros(3)
            normal[axis], s[(axis + 1) % 3] = sign, 1.0
            t = np.cross(normal, s)
            faces.append(quads + sum(p.shape[0] for p in points))
            points.append((normal + u.reshape(-1, 1) * s + v.reshape(-1, 1) * t) * half)
    points = np.concatenate(points)
    _keys, first, inverse = np.unique(
        np.round(points * 1e4).astype(np.int64), axis=0, return_index=True, return_inverse=True
    )
    on_cube = points[first]
    center = np.clip(on_cube, -inner, inner)
    outward = (on_cube - center) / np.linalg.norm(on_cube - center, axis=1, keepdims=True)
    vertices = center + outward * radius
    vertices += outward * np.random.default_rng(seed).uniform(-noise, noise, (vertices.shape[0], 1))
    return vertices, inverse.reshape(-1)[np.concatenate(faces)]


def run(output_dir: Path) -> None:
    import addon_utils

    bpy.ops.wm.read_homefile(use_empty=True)
    addon_utils.enable("springwrap", default_set=True, handle_error=None)
    vertices, quads = rounded_box()
    mesh = bpy.data.meshes.new("Part")
    mesh.from_pydata(vertices.tolist(), [], quads.tolist())
    mesh.update()
    part = bpy.data.objects.new("Part", mesh)
    bpy.context.scene.collection.objects.link(part)
    bpy.context.view_layer.objects.active = part
    assert bpy.ops.springwrap.detect_features(scale=0.35) == {"FINISHED"}
    scene = bpy.context.scene
    render_guide.setup_render(scene, part)
    scene.render.resolution_x, scene.render.resolution_y = render_guide.RESOLUTION
    camera = scene.camera
    camera.location = Vector((3.4, -4.2, 3.0))
    camera.rotation_euler = (Vector((0.0, 0.0, -0.1)) - camera.location).to_track_quat("-Z", "Y").to_euler()
    tubes = []
    for curve in bpy.data.collections["Springwrap Features"].objects:
        curve.data.bevel_depth = 0.018
        curve.data.bevel_resolution = 2
        evaluated = curve.evaluated_get(bpy.context.evaluated_depsgraph_get())
        tube = bpy.data.objects.new(curve.name + " tube", bpy.data.meshes.new_from_object(evaluated))
        scene.collection.objects.link(tube)
        render_guide.paint(tube, (0.05, 0.05, 0.05, 1.0))
        tubes.append(tube)
        curve.hide_render = True  # the tube stands in for it
    # The feature colours are the part's active colour already; Workbench shows the render colour.
    path = output_dir / "guide-features.png"
    render_guide.render(scene, [part, *tubes], path)


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
