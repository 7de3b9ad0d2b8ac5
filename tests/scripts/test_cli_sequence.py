"""``retarget.py --sequence START END``: the template wrapped at every frame of the target's animation (a .blend
target whose shape key stretches it over frames 1 to 3), one keyed shape key per frame in the output .blend, and
``--point-cache``: the same frames as an Alembic point cache that reads back frame for frame."""

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

READ = """
import json, sys, bpy, numpy as np
path = (sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])[0]
if path.endswith(".blend"):  # the output .blend: its layout with the sequence keys
    bpy.ops.wm.open_mainfile(filepath=path)
    layout = next(obj for obj in bpy.data.objects if obj.data.shape_keys is not None and obj.name != "Target")
    found = {"keys": [block.name for block in layout.data.shape_keys.key_blocks]}
else:  # the point cache, imported
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.wm.alembic_import(filepath=path) == {"FINISHED"}
    (layout,) = [obj for obj in bpy.data.objects if obj.type == "MESH"]
    found = {"modifiers": [modifier.type for modifier in layout.modifiers]}
widths = {}
for frame in (1, 2, 3):
    bpy.context.scene.frame_set(frame)
    mesh = layout.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    xs = np.array([vertex.co.x for vertex in mesh.vertices])
    widths[frame] = float(xs.max() - xs.min())
print(json.dumps(found | {"widths": widths}))
"""


PROBE = """
import json, bpy
try:
    bpy.ops.wm.alembic_export.get_rna_type()
    alembic = True
except (AttributeError, KeyError):  # built without Alembic (Debian's Blender 3.4)
    alembic = False
print(json.dumps({"alembic": alembic}))
"""


def has_alembic(tmp_path) -> bool:
    """Whether the Blender the scripts run in can write Alembic."""
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE)
    ran = run_script(probe)
    assert ran.returncode == 0, ran.stderr[-2000:]
    return printed(ran)["alembic"]


def printed(ran):
    """The one JSON line a reader script printed (the blender binary prints "Blender quit" after it)."""
    [line] = [line for line in ran.stdout.splitlines() if line.startswith("{")]
    return json.loads(line)


def test_a_sequence_from_the_command_line(tmp_path):
    maker, reader = tmp_path / "make.py", tmp_path / "read.py"
    maker.write_text(MAKE_BLEND)
    reader.write_text(READ)
    scene = tmp_path / "scene.blend"
    made = run_script(maker, scene)
    assert made.returncode == 0, made.stderr[-2000:]
    output, report, cache = tmp_path / "out.blend", tmp_path / "report.json", tmp_path / "cache" / "layout.abc"
    arguments = (
        *("--template", scene, "--template-object", "Template", "--target", scene, "--target-object", "Target"),
        *("--sequence", 1, 3, "--output-blend", output, "--report", report),
    )
    alembic = has_alembic(tmp_path)
    ran = run_script(RETARGET, *arguments, "--point-cache", cache)
    if not alembic:  # refused, naming what is missing, nothing written; then the sequence without a cache
        assert ran.returncode != 0 and "no Alembic" in ran.stderr, ran.stderr[-2000:]
        assert not output.exists() and not cache.exists()
        ran = run_script(RETARGET, *arguments)
    assert ran.returncode == 0, ran.stderr[-2000:]
    sequence = json.loads(report.read_text())["sequence"]
    assert [frame["frame"] for frame in sequence["frames"]] == [1, 2, 3]
    assert sequence["failed"] == []
    if alembic:
        assert sequence["point_cache"] == {"path": str(cache), "format": "ALEMBIC"}
    read = run_script(reader, output)
    assert read.returncode == 0, read.stderr[-2000:]
    measured = printed(read)
    assert measured["keys"] == ["Basis", "Wrap 0001", "Wrap 0002", "Wrap 0003"]
    widths = {int(frame): width for frame, width in measured["widths"].items()}
    assert widths[3] > 1.3 * widths[1] and widths[1] < widths[2] < widths[3]
    if not alembic:
        return
    read = run_script(reader, cache)
    assert read.returncode == 0, read.stderr[-2000:]
    cached = printed(read)
    assert "MESH_SEQUENCE_CACHE" in cached["modifiers"]
    cached_widths = {int(frame): width for frame, width in cached["widths"].items()}
    for frame, width in widths.items():  # the cache holds the keys' frames, each as playback shows it
        assert abs(cached_widths[frame] - width) < 1e-4 * width, frame
    assert not list(cache.parent.glob(".*partial*"))  # written whole, under its own name


def test_a_backward_range_is_refused(tmp_path):
    ran = run_script(RETARGET, "--template", tmp_path / "t.obj", "--target", tmp_path / "m.obj", "--sequence", 3, 1)
    assert ran.returncode == 2 and "END must not come before START" in ran.stderr


def test_a_point_cache_needs_a_sequence_and_a_cache_suffix(tmp_path):
    template, target = tmp_path / "t.obj", tmp_path / "m.obj"
    ran = run_script(RETARGET, "--template", template, "--target", target, "--point-cache", tmp_path / "c.abc")
    assert ran.returncode == 2 and "--point-cache writes a sequence's frames" in ran.stderr
    ran = run_script(
        RETARGET, "--template", template, "--target", target, "--sequence", 1, 3, "--point-cache", tmp_path / "c.obj"
    )
    assert ran.returncode == 2 and "must end with .abc (Alembic)" in ran.stderr
