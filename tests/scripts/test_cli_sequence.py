"""``retarget.py --sequence START END``: the template wrapped at every frame of the target's animation (a .blend
target whose shape key stretches it over frames 1 to 3), one keyed shape key per frame in the output .blend."""

import json

from helpers import REPOSITORY, run_script

RETARGET = REPOSITORY / "blender_scripts" / "retarget.py"

MAKE_BLEND = f"""
import sys
sys.path.insert(0, {str(REPOSITORY / "tests" / "addon")!r})
import bpy
from bpy_helpers import animated_target
bpy.ops.wm.read_homefile(use_empty=True)
animated_target()  # a sphere stretched along x by its shape key over frames 1 .. 3
bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.3)
bpy.context.active_object.name = "Template"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1])
"""

READ_KEYS = """
import json, sys, bpy, numpy as np
path = (sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])[0]
bpy.ops.wm.open_mainfile(filepath=path)
layout = next(obj for obj in bpy.data.objects if obj.data.shape_keys is not None and obj.name != "Target")
widths = {}
for frame in (1, 2, 3):
    bpy.context.scene.frame_set(frame)
    mesh = layout.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    xs = np.array([vertex.co.x for vertex in mesh.vertices])
    widths[frame] = float(xs.max() - xs.min())
print(json.dumps({"keys": [block.name for block in layout.data.shape_keys.key_blocks], "widths": widths}))
"""


def test_a_sequence_from_the_command_line(tmp_path):
    maker, reader = tmp_path / "make.py", tmp_path / "read.py"
    maker.write_text(MAKE_BLEND)
    reader.write_text(READ_KEYS)
    scene = tmp_path / "scene.blend"
    made = run_script(maker, scene)
    assert made.returncode == 0, made.stderr[-2000:]
    output, report = tmp_path / "out.blend", tmp_path / "report.json"
    ran = run_script(
        RETARGET,
        *("--template", scene, "--template-object", "Template", "--target", scene, "--target-object", "Target"),
        *("--sequence", 1, 3, "--output-blend", output, "--report", report),
    )
    assert ran.returncode == 0, ran.stderr[-2000:]
    sequence = json.loads(report.read_text())["sequence"]
    assert [frame["frame"] for frame in sequence["frames"]] == [1, 2, 3]
    assert sequence["failed"] == []
    read = run_script(reader, output)
    assert read.returncode == 0, read.stderr[-2000:]
    # The reader prints one JSON line; the blender binary prints "Blender quit" after it.
    [line] = [line for line in read.stdout.splitlines() if line.startswith("{")]
    measured = json.loads(line)
    assert measured["keys"] == ["Basis", "Wrap 0001", "Wrap 0002", "Wrap 0003"]
    widths = {int(frame): width for frame, width in measured["widths"].items()}
    assert widths[3] > 1.3 * widths[1] and widths[1] < widths[2] < widths[3]


def test_a_backward_range_is_refused(tmp_path):
    ran = run_script(RETARGET, "--template", tmp_path / "t.obj", "--target", tmp_path / "m.obj", "--sequence", 3, 1)
    assert ran.returncode == 2 and "END must not come before START" in ran.stderr
