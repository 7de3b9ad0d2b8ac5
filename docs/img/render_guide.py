"""Render the user guide's pictures (docs/img/guide-*.png) headless, from the demo scene.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python docs/img/render_guide.py [--output-dir docs/img]
    blender -b --factory-startup --python docs/img/render_guide.py -- [--output-dir docs/img]

It builds the scene of ``blender_scripts/demo.py`` (its own functions, imported): a displaced,
subdivided Suzanne with a hole in the forehead as the target, and Suzanne's own quads, moved and
scaled, as the template. Then, through the add-on's operators, one copy of the template is
detached, projected and snapped, another detached, anchored (``anchors_auto``) and wrapped. The
pictures are rendered with the Workbench engine (flat colours from colour attributes, a camera in
front of the target); the layout's edges are drawn by a copy of it with a Wireframe modifier.

Pictures (800 x 600):
    guide-target.png        the target alone (a hole in the forehead)
    guide-before.png        the target (grey) and the template (orange wires) as placed
    guide-anchors.png       the detached template and its automatic anchors (red) on the target
    guide-after.png         the wrapped layout (blue faces, dark wires) alone
    guide-after-target.png  the wrapped layout's wires over the target
    guide-heatmap-snap.png  per-vertex error of snap (closest point), blue 0 to red >= HEAT_SCALE
    guide-heatmap-wrap.png  the same for the wrap

The error of a layout vertex is its distance to a reference point: the same Suzanne vertex on
the target (the base-mesh vertex, moved along its normal onto the evaluated target within
REFERENCE_RAY; where no surface is that close, over the hole, the base-mesh vertex itself).
"""

import argparse
import sys
import time
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

REPOSITORY_ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPOSITORY_ROOT / "blender_scripts"))
import demo  # noqa: E402

from headless import script_arguments  # noqa: E402

RESOLUTION = (800, 600)
HEAT_SCALE = 0.3
"""World units shown as full red in the heat-maps (the target is about 3.3 units wide)."""
REFERENCE_RAY = 0.2
"""How far (target object space) a base-mesh vertex looks along its normal for the evaluated target."""
WIRE_THICKNESS = 0.012
"""Wireframe modifier thickness, layout object space."""

TARGET_COLOUR = (0.62, 0.62, 0.60, 1.0)
TEMPLATE_WIRE_COLOUR = (0.95, 0.42, 0.05, 1.0)
LAYOUT_FACE_COLOUR = (0.55, 0.75, 0.95, 1.0)
DARK_WIRE_COLOUR = (0.05, 0.07, 0.12, 1.0)
ANCHOR_COLOUR = (0.85, 0.05, 0.05, 1.0)


def output_dir_parser(script: str, description: str) -> argparse.ArgumentParser:
    """The arguments every picture script takes: ``--output-dir`` (default: docs/img)."""
    parser = argparse.ArgumentParser(prog=Path(script).name, description=description)
    parser.add_argument(
        "--output-dir",
        type=Path,
        default=Path(__file__).resolve().parent,
        help="where the pictures go (default: docs/img)",
    )
    return parser


def picture_main(run, script: str, description: str, parser: argparse.ArgumentParser | None = None) -> int:
    """A picture script's ``main``: its arguments (after ``--`` under ``blender -b``; ``parser``, else
    :func:`output_dir_parser`), then ``run(arguments)``; any failure is printed and becomes exit code 1 (also
    under ``blender -b``, which would otherwise exit 0)."""
    parser = parser or output_dir_parser(script, description)
    arguments = parser.parse_args(script_arguments(sys.argv, script))
    arguments.output_dir = arguments.output_dir.resolve()
    try:
        run(arguments)
    except Exception:  # noqa: BLE001 - any failure must become a non-zero exit code, also under `blender -b`
        import traceback

        traceback.print_exc()
        print(f"{Path(script).stem}: FAILED", file=sys.stderr)
        return 1
    return 0


def paint(obj: bpy.types.Object, colours: np.ndarray | tuple) -> None:
    """Give ``obj``'s mesh a POINT colour attribute (one RGBA, or (N, 4) per vertex) and make it active."""
    mesh = obj.data
    name = "guide_colour"
    if name in mesh.color_attributes:
        mesh.color_attributes.remove(mesh.color_attributes[name])
    attribute = mesh.color_attributes.new(name, "FLOAT_COLOR", "POINT")
    values = np.broadcast_to(np.asarray(colours, dtype=np.float32), (len(mesh.vertices), 4))
    attribute.data.foreach_set("color", np.ascontiguousarray(values).ravel())
    mesh.color_attributes.active_color = attribute
    mesh.color_attributes.render_color_index = mesh.color_attributes.active_color_index


def wire_copy(layout: bpy.types.Object, name: str, colour: tuple, outside: bool = False) -> bpy.types.Object:
    """A frozen copy of ``layout`` as it is now, drawn as wires (Wireframe modifier) in ``colour``.

    ``outside``: the wires sit on the outer side of the faces (thicker), to show over the target."""
    mesh = layout.data.copy()
    mesh.name = name
    for attribute_name in [a.name for a in mesh.attributes if a.name.startswith("springwrap_")]:
        mesh.attributes.remove(mesh.attributes[attribute_name])
    copy = bpy.data.objects.new(name, mesh)
    copy.matrix_world = layout.matrix_world.copy()
    bpy.context.scene.collection.objects.link(copy)
    wire = copy.modifiers.new("Wires", "WIREFRAME")
    wire.thickness = WIRE_THICKNESS
    wire.use_even_offset = False  # even offset makes spikes at collapsed faces
    wire.use_replace = True
    if outside:
        wire.thickness = 1.5 * WIRE_THICKNESS
        wire.offset = 1.0
    paint(copy, colour)
    return copy


def face_copy(layout: bpy.types.Object, name: str, colours) -> bpy.types.Object:
    """A frozen copy of ``layout`` as it is now, with solid faces in ``colours``."""
    mesh = layout.data.copy()
    mesh.name = name
    copy = bpy.data.objects.new(name, mesh)
    copy.matrix_world = layout.matrix_world.copy()
    bpy.context.scene.collection.objects.link(copy)
    paint(copy, colours)
    return copy


def anchor_markers(layout: bpy.types.Object, name: str) -> bpy.types.Object:
    """Small red balls at the world-space target points of ``layout``'s anchors, as one object."""
    import bmesh

    bm = bmesh.new()
    for anchor in layout.springwrap.anchors:
        bmesh.ops.create_icosphere(bm, subdivisions=2, radius=0.035, matrix=Matrix.Translation(Vector(anchor.location)))
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    markers = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(markers)
    paint(markers, ANCHOR_COLOUR)
    return markers


def heat_colours(errors: np.ndarray) -> np.ndarray:
    """(N, 4) linear RGBA: blue at 0, through green and yellow, to red at HEAT_SCALE and beyond."""
    stops = np.array(
        [[0.02, 0.10, 0.60], [0.00, 0.55, 0.75], [0.10, 0.75, 0.15], [0.95, 0.85, 0.05], [0.85, 0.05, 0.02]]
    )
    position = np.clip(errors / HEAT_SCALE, 0.0, 1.0) * (len(stops) - 1)
    low = np.floor(position).astype(int).clip(0, len(stops) - 2)
    fraction = (position - low)[:, None]
    rgb = stops[low] * (1.0 - fraction) + stops[low + 1] * fraction
    return np.column_stack([rgb, np.ones(len(errors))])


# ---------------------------------------------------------------- the reference (known answer)


def reference_points(target: bpy.types.Object, template_mesh: bpy.types.Mesh) -> np.ndarray:
    """(N, 3) world-space reference point of every template vertex (see the module docstring).

    The template is Suzanne, the target a Suzanne subdivided and displaced: vertex i of the
    template belongs where base vertex i of Suzanne ended up on the evaluated target."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    tree = BVHTree.FromObject(target, depsgraph)  # target object space
    matrix = target.matrix_world
    result = np.empty((len(template_mesh.vertices), 3))
    for index, vertex in enumerate(template_mesh.vertices):
        origin = vertex.co.copy()
        best = None
        for direction in (vertex.normal, -vertex.normal):
            location, _normal, _face, distance = tree.ray_cast(origin, direction, REFERENCE_RAY)
            if location is not None and (best is None or distance < best[1]):
                best = (location, distance)
        result[index] = tuple(matrix @ (best[0] if best is not None else origin))
    return result


# ---------------------------------------------------------------- scene, camera, render


def workbench(scene: bpy.types.Scene, resolution: tuple[int, int] = RESOLUTION) -> None:
    """The pictures' renderer: Workbench at ``resolution``, studio light, colour attributes, white background."""
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "VERTEX"
    shading.show_object_outline = True
    shading.object_outline_color = (0.0, 0.0, 0.0)
    shading.show_cavity = False
    shading.show_backface_culling = True  # the hole shows the white background, not the inside of the head
    shading.show_specular_highlight = False
    world = bpy.data.worlds.new("GuideWorld")
    world.color = (1.0, 1.0, 1.0)
    scene.world = world


def setup_render(scene: bpy.types.Scene, target: bpy.types.Object) -> None:
    """:func:`workbench`, and a camera in front of the target."""
    workbench(scene)
    camera_data = bpy.data.cameras.new("GuideCamera")
    camera_data.lens = 50.0
    camera = bpy.data.objects.new("GuideCamera", camera_data)
    scene.collection.objects.link(camera)
    matrix = target.matrix_world
    look_at = matrix @ Vector((0.12, 0.0, -0.02))
    camera.location = matrix @ Vector((1.0, -4.9, 0.9))
    camera.rotation_euler = (look_at - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera


def render(scene: bpy.types.Scene, visible: list[bpy.types.Object], path: Path, colour_bar: bool = False) -> None:
    """Render only the ``visible`` objects (and the camera) to ``path``; ``colour_bar``: add the heat-maps' scale."""
    for obj in scene.objects:
        obj.hide_render = obj.type == "MESH" and obj not in visible
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    shrink(path, colour_bar)
    print(f"wrote {path} ({path.stat().st_size // 1024} KB)")


def shrink(path: Path, colour_bar: bool = False) -> None:
    """Re-save ``path`` with a 256-colour palette when Pillow is there (it keeps the PNGs under 250 KB).

    ``colour_bar``: first draw the heat-map scale (0 to HEAT_SCALE) in the bottom left corner."""
    try:
        from PIL import Image
    except ImportError:
        print(f"Pillow is not installed: {path.name} stays a full-colour PNG")
        return
    with Image.open(path) as image:
        image = image.convert("RGB")
    if not colour_bar:
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
        return
    # The render's own 256 - COLOUR_BAR_STEPS colours, then the bar's steps exactly.
    render_palette = image.quantize(colors=256 - COLOUR_BAR_STEPS, method=Image.Quantize.MEDIANCUT).getpalette()
    bar = draw_colour_bar(image)
    entries = render_palette[: 3 * (256 - COLOUR_BAR_STEPS)] + [value for colour in bar for value in colour]
    palette = Image.new("P", (1, 1))
    palette.putpalette(entries)
    image.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG).save(path, optimize=True)


COLOUR_BAR_STEPS = 12
"""Steps of the heat-maps' colour bar (each its own palette entry)."""


def draw_colour_bar(image) -> list[tuple[int, int, int]]:
    """The heat-maps' colour scale, 0 to HEAT_SCALE world units, drawn into the Pillow ``image`` in steps.

    Returns the steps' sRGB colours."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(image)
    left, top, step_width, height = 30, image.height - 50, 20, 14
    width = step_width * COLOUR_BAR_STEPS
    values = np.linspace(0.0, HEAT_SCALE, COLOUR_BAR_STEPS)  # first step 0, last HEAT_SCALE
    # The render's view transform is Standard (sRGB): the colours are linear, shown through sRGB.
    linear = heat_colours(values)[:, :3]
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    colours = [tuple(colour) for colour in (srgb * 255).round().astype(int).tolist()]
    for step, colour in enumerate(colours):
        draw.rectangle([left + step * step_width, top, left + (step + 1) * step_width - 1, top + height], fill=colour)
    draw.rectangle([left - 1, top - 1, left + width, top + height + 1], outline=(0, 0, 0))
    draw.text((left, top + height + 4), "0", fill=(0, 0, 0))
    draw.text((left + width - 70, top + height + 4), f">= {HEAT_SCALE:g} units", fill=(0, 0, 0))
    draw.text((left, top - 16), "distance to the reference (flat colours)", fill=(0, 0, 0))
    return colours


def run(output_dir: Path) -> None:
    start = time.perf_counter()
    target, hole_centroid, _cut = demo.new_scene()
    scene = bpy.context.scene
    operators = bpy.ops.springwrap

    def step(result):
        if result != {"FINISHED"}:
            raise RuntimeError(f"an operator returned {result}")

    template = demo.build_layout(target, "Template")
    template_wires = wire_copy(template, "TemplateWires", TEMPLATE_WIRE_COLOUR)
    reference = reference_points(target, template.data)

    snapped = demo.build_layout(target, "Snapped")
    demo.attach_and_activate(snapped, target)
    step(operators.detach(only_selected=False))
    step(
        operators.project(
            direction="NORMAL", only_selected=False, both_directions=True, max_distance=demo.PROJECT_MAX_DISTANCE
        )
    )
    step(operators.snap(mode="SURFACE", only_selected=False, max_distance=0.0))

    wrapped = demo.build_layout(target, "Wrapped")
    demo.attach_and_activate(wrapped, target)
    step(operators.detach(only_selected=False))
    step(operators.anchors_auto(spacing=demo.WRAP_ANCHOR_SPACING, method="CLOSEST", replace=True))
    markers = anchor_markers(wrapped, "AnchorMarkers")
    wrap_start = time.perf_counter()
    step(operators.wrap(max_iterations=demo.WRAP_MAX_ITERATIONS))
    print(f"wrap: {time.perf_counter() - wrap_start:.1f} s, {len(wrapped.springwrap.anchors)} anchors")
    probe = demo.probe_target(target, hole_centroid)
    points = demo.layout_world_positions(wrapped)
    off = np.linalg.norm(points - demo.nearest_target_points(points, probe), axis=1)
    far = np.flatnonzero(off > 0.05)
    print(f"wrap: vertices over 0.05 off the target: {far.tolist()} at {np.round(off[far], 3).tolist()}")

    errors = {}
    for name, layout in (("snap", snapped), ("wrap", wrapped)):
        error = np.linalg.norm(demo.layout_world_positions(layout) - reference, axis=1)
        errors[name] = error
        print(
            f"{name}: error mean {error.mean():.4f}, median {np.median(error):.4f}, max {error.max():.4f}, "
            f"over {HEAT_SCALE:g}: {(error >= HEAT_SCALE).sum()} of {len(error)}"
        )

    paint(target, TARGET_COLOUR)
    for obj in (template, snapped, wrapped):
        obj.hide_render = True
    wrapped_faces = face_copy(wrapped, "WrappedFaces", LAYOUT_FACE_COLOUR)
    wrapped_wires = wire_copy(wrapped, "WrappedWires", DARK_WIRE_COLOUR)
    snap_heat = face_copy(snapped, "SnapHeat", heat_colours(errors["snap"]))
    snap_wires = wire_copy(snapped, "SnapWires", DARK_WIRE_COLOUR)
    wrap_heat = face_copy(wrapped, "WrapHeat", heat_colours(errors["wrap"]))
    after_target_wires = wire_copy(wrapped, "WrappedWiresOrange", TEMPLATE_WIRE_COLOUR, outside=True)

    setup_render(scene, target)
    output_dir.mkdir(parents=True, exist_ok=True)
    render(scene, [target], output_dir / "guide-target.png")
    render(scene, [target, template_wires], output_dir / "guide-before.png")
    render(scene, [target, template_wires, markers], output_dir / "guide-anchors.png")
    render(scene, [wrapped_faces, wrapped_wires], output_dir / "guide-after.png")
    render(scene, [target, after_target_wires], output_dir / "guide-after-target.png")
    scene.display.shading.light = "FLAT"  # heat-maps: the colours as painted, to be read on the bar
    render(scene, [snap_heat, snap_wires], output_dir / "guide-heatmap-snap.png", colour_bar=True)
    render(scene, [wrap_heat, wrapped_wires], output_dir / "guide-heatmap-wrap.png", colour_bar=True)
    print(f"done in {time.perf_counter() - start:.1f} s")


def main() -> int:
    return picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
