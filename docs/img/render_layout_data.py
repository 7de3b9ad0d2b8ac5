"""Render the user guide's picture of what stays on the layout (docs/img/guide-layout-data.png) headless: the
demo's template with a UV grid texture, and the same layout after the wrap, its UVs as they were.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python docs/img/render_layout_data.py [--output-dir docs/img]
    blender -b --factory-startup --python docs/img/render_layout_data.py -- [--output-dir docs/img]

The scene is the demo's (``blender_scripts/demo.py``): Suzanne's quads (with Blender's UV map) as the template
off a displaced, subdivided Suzanne with a hole. Through the add-on's operators the template is detached,
anchored (``anchors_auto``) and wrapped; both are rendered with Blender's generated UV grid through their UV
map (Workbench, texture colour), the template on the left, the wrapped layout on the right. It prints whether
the UV map came through the wrap bit for bit.
"""

import sys
import time
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np

REPOSITORY_ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPOSITORY_ROOT / "blender_scripts"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import demo  # noqa: E402
import render_guide  # noqa: E402

PANEL_SIZE = (480, 420)
"""Each panel's render, width x height."""


def uv_grid_material() -> bpy.types.Material:
    """A material showing Blender's generated UV grid through the mesh's UV map (what Workbench's Texture
    colour draws)."""
    image = bpy.data.images.new("UV Grid", 1024, 1024)
    image.generated_type = "COLOR_GRID"
    material = bpy.data.materials.new("UV Grid")
    material.use_nodes = True
    texture = material.node_tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    material.node_tree.nodes.active = texture
    return material


def uv_coordinates(obj) -> np.ndarray:
    layer = obj.data.uv_layers.active
    values = np.empty(len(layer.data) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", values)
    return values


def run(output_dir: Path) -> None:
    from PIL import Image, ImageDraw

    start = time.perf_counter()
    target, _hole_centroid, _cut = demo.new_scene()
    scene = bpy.context.scene
    template = demo.build_layout(target, "Template")
    wrapped = demo.build_layout(target, "Wrapped")
    uvs_before = uv_coordinates(wrapped)
    material = uv_grid_material()
    for obj in (template, wrapped):
        obj.data.materials.append(material)

    demo.wrap_with_auto_anchors(wrapped, target)
    same = uv_coordinates(wrapped).tobytes() == uvs_before.tobytes()
    print(f"UV map after the wrap: {'bit for bit the same' if same else 'CHANGED'} ({len(uvs_before) // 2} corners)")

    render_guide.setup_render(scene, target)
    scene.render.resolution_x, scene.render.resolution_y = PANEL_SIZE
    scene.display.shading.color_type = "TEXTURE"
    scene.display.shading.light = "FLAT"  # the grid's colours as they are
    scene.display.shading.show_backface_culling = False
    work = output_dir / ".layout-data-panels"
    work.mkdir(parents=True, exist_ok=True)
    panels = []
    for name, obj in (("template", template), ("wrapped", wrapped)):
        for other in scene.objects:
            other.hide_render = other.type == "MESH" and other is not obj
        path = work / f"{name}.png"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        with Image.open(path) as image:
            panels.append(image.convert("RGB"))
        path.unlink()
    work.rmdir()

    caption_height = 24
    width, height = PANEL_SIZE
    sheet = Image.new("RGB", (2 * width, height + caption_height), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    captions = ("the template, its UV map", "wrapped: the same UV map, bit for bit" if same else "wrapped")
    for index, (panel, caption) in enumerate(zip(panels, captions)):
        sheet.paste(panel, (index * width, 0))
        draw.text((index * width + 10, height + 4), caption, fill=(0, 0, 0))
    path = output_dir / "guide-layout-data.png"
    sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1024} KB) in {time.perf_counter() - start:.1f} s")


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
