"""Screenshot the quality read-out's heat-map (docs/img/guide-readout-*.png): the overlay is drawn with ``gpu``
in a 3D view, which a background Blender does not have, so this runs in Blender *with its interface*, under a
virtual X server:

    LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1280x900x24" blender --factory-startup \
        --enable-event-simulate --python docs/img/render_heatmap.py [-- --output-dir docs/img]

(Debian's blender 3.4 with software OpenGL, as the GUI lane runs it.) The add-on is
imported from this checkout and the kernel from ``.venv`` (the abi3 wheel imports in Blender's Python 3.11). It
builds the demo scene (``blender_scripts/demo.py``: Suzanne subdivided and displaced with a hole in the forehead,
Suzanne's quads moved and scaled as the template), detaches, anchors and wraps, turns the heat-map on and
screenshots the 3D view for each kind, then quits. It prints the read-out's numbers.
"""

import argparse
import sys
import tempfile
from pathlib import Path

import bpy

REPOSITORY = Path(__file__).resolve().parents[2]
KINDS = {"DISTANCE": "guide-readout-distance.png", "STRETCH": "guide-readout-stretch.png"}


def _paths() -> None:
    """The add-on from this checkout, ``demo.py``, and the kernel from .venv (only it: Blender has its numpy)."""
    kernels = sorted(REPOSITORY.glob(".venv/lib/python3*/site-packages/springwrap_kernel"))
    if not kernels:
        raise SystemExit("render_heatmap: no springwrap_kernel in .venv (make setup)")
    folder = Path(tempfile.mkdtemp(prefix="springwrap-kernel-"))
    (folder / "springwrap_kernel").symlink_to(kernels[0])
    for path in (folder, REPOSITORY / "addon", REPOSITORY / "blender_scripts"):
        sys.path.insert(0, str(path))


def _arguments():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(description="screenshot the quality heat-map")
    parser.add_argument("--output-dir", type=Path, default=REPOSITORY / "docs" / "img")
    return parser.parse_args(argv)


def _scene():
    import demo

    import springwrap
    from springwrap.blender import quality as quality_data
    from springwrap.core import quality

    springwrap.register()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    target, _hole, _cut = demo.build_target()
    layout = demo.build_layout(target)
    demo.wrap_with_auto_anchors(layout, target, "EXEC_DEFAULT")
    print("render_heatmap: read-out", quality.summary(quality_data.read_readout(layout)))
    layout.springwrap.show_anchors = False
    target.hide_set(True)  # the layout alone: its own faces, coloured
    return layout, target


def _view(target):
    window = bpy.context.window_manager.windows[0]
    area = max((area for area in window.screen.areas if area.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    space = area.spaces.active
    space.show_region_ui = space.show_region_toolbar = space.show_region_header = False
    space.overlay.show_floor = space.overlay.show_axis_x = space.overlay.show_axis_y = False
    space.overlay.show_ortho_grid = False
    space.overlay.show_text = space.overlay.show_cursor = False
    space.shading.type = "SOLID"
    from mathutils import Vector

    view = space.region_3d  # where docs/img/render_guide.py puts its camera: in front of the face, a little aside
    look_at = target.matrix_world @ Vector((0.12, 0.0, -0.02))
    eye = target.matrix_world @ Vector((1.0, -4.9, 0.9))
    view.view_perspective = "PERSP"
    view.view_rotation = (look_at - eye).to_track_quat("-Z", "Y")
    region = next(region for region in area.regions if region.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_selected()
    view.view_distance *= 0.75
    return window, area


def _crop(path: Path, rectangle, output: Path) -> None:
    """Save the ``(x, y, width, height)`` part (window pixels, from the bottom left) of a screenshot."""
    import numpy as np

    x, y, width, height = rectangle
    image = bpy.data.images.load(str(path))
    pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    part = pixels.reshape(image.size[1], image.size[0], 4)[y : y + height, x : x + width]
    cropped = bpy.data.images.new(output.stem, width, height)
    cropped.pixels.foreach_set(np.ascontiguousarray(part, dtype=np.float32).reshape(-1))
    cropped.filepath_raw = str(output)
    cropped.file_format = "PNG"
    cropped.save()
    bpy.data.images.remove(cropped)
    bpy.data.images.remove(image)


def palette(path: Path) -> None:
    """``render_guide.shrink``: a 256-colour palette when Pillow is importable (Blender 3.4's Python may lack it:
    then ``.venv/bin/python -c "import runpy; runpy.run_path('docs/img/render_heatmap.py', run_name='palette')"``
    does it for the pictures in docs/img)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import render_guide

    render_guide.shrink(path)


def _steps(arguments):
    _paths()
    window = bpy.context.window_manager.windows[0]
    for value in ("PRESS", "RELEASE"):  # close the splash screen (needs --enable-event-simulate)
        window.event_simulate(type="ESC", value=value, x=window.width // 2, y=window.height // 2)
    yield 1.0
    layout, target = _scene()
    window, area = _view(target)
    layout.springwrap.show_heatmap = True
    for kind, name in KINDS.items():
        layout.springwrap.heatmap_kind = kind
        area.tag_redraw()
        yield 0.5
        whole = Path(tempfile.mkdtemp(prefix="springwrap-shot-")) / "window.png"
        with bpy.context.temp_override(window=window, area=area):
            bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
            bpy.ops.screen.screenshot(filepath=str(whole))
        _crop(whole, (area.x, area.y, area.width, area.height), arguments.output_dir / name)
        palette(arguments.output_dir / name)
        print(f"render_heatmap: wrote {arguments.output_dir / name}")
    bpy.ops.wm.quit_blender()


def main() -> None:
    steps = _steps(_arguments())

    def tick():
        try:
            return next(steps)
        except StopIteration:
            return None
        except BaseException as error:  # noqa: BLE001 - say it and leave, do not hang the X server
            print(f"render_heatmap: FAILED: {error!r}")
            import traceback

            traceback.print_exc()
            bpy.ops.wm.quit_blender()
            return None

    bpy.app.timers.register(tick, first_interval=1.0)


if __name__ == "palette":
    for picture in KINDS.values():
        palette(REPOSITORY / "docs" / "img" / picture)
else:
    main()
