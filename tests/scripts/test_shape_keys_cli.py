"""``--shape-keys TRANSFER|REFUSE`` of the headless scripts (wrap.py, retarget.py, mirror.py), end to end in their
own processes.

The input .blend is made here: an ellipsoid target (semi-axes 2.2, 2.0, 1.8) and a quad sphere layout of
radius 1 (a cube cut 10 x 10 a side, pushed onto the sphere) with the keys Basis and Cap (the cap within
35 degrees of +x pushed out by 0.1 along the normal). A reader script opens the result and measures the
carried key: how far it pushes along the ellipsoid's normal, against how much the wrap stretched the
cap's faces (the root of their area ratio, the scale the transfer promises).
"""

import json

import pytest

from helpers import REPOSITORY, run_script

SCRIPTS = REPOSITORY / "blender_scripts"

MAKE_BLEND = """
import sys, bpy, bmesh, numpy as np
output = (sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])[0]
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.mesh.primitive_uv_sphere_add(segments=96, ring_count=48, radius=1.0)
target = bpy.context.active_object
target.name = "Ellipsoid"
points = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
target.data.vertices.foreach_get("co", points)
target.data.vertices.foreach_set("co", (points.reshape(-1, 3) * [2.2, 2.0, 1.8]).astype(np.float32).ravel())
target.data.update()
bpy.ops.mesh.primitive_cube_add(size=2.0)
layout = bpy.context.active_object
layout.name = "Sphere"
editable = bmesh.new()
editable.from_mesh(layout.data)
bmesh.ops.subdivide_edges(editable, edges=editable.edges[:], cuts=9, use_grid_fill=True)
for vertex in editable.verts:
    vertex.co = vertex.co.normalized()
editable.to_mesh(layout.data)
editable.free()
rest = np.empty(len(layout.data.vertices) * 3, dtype=np.float32)
layout.data.vertices.foreach_get("co", rest)
rest = rest.reshape(-1, 3).astype(np.float64)
normals = rest / np.linalg.norm(rest, axis=1, keepdims=True)
cap = normals[:, 0] > np.cos(np.radians(35.0))
layout.shape_key_add(name="Basis")
key = layout.shape_key_add(name="Cap", from_mix=False)
key.data.foreach_set("co", (rest + np.where(cap[:, None], 0.1 * normals, 0.0)).astype(np.float32).ravel())
bpy.ops.wm.save_as_mainfile(filepath=output)
"""

READ_KEYS = """
import json, sys, bpy, numpy as np
source, result, name = (sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])[:3]

def keys(path, object_name):
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects[object_name]
    out = {}
    for block in obj.data.shape_keys.key_blocks:
        values = np.empty(len(block.data) * 3, dtype=np.float32)
        block.data.foreach_get("co", values)
        out[block.name] = values.reshape(-1, 3).astype(np.float64)
    faces = [list(polygon.vertices) for polygon in obj.data.polygons]
    return out, np.array(obj.matrix_world), faces

def area(points, faces):
    return sum(
        0.5 * np.linalg.norm(sum(np.cross(points[f[i]] - points[f[0]], points[f[(i + 1) % len(f)]] - points[f[0]])
        for i in range(len(f)))) for f in faces
    )

before, _, _ = keys(source, "Sphere")
after, matrix, faces = keys(result, name)
basis = after["Basis"] @ matrix[:3, :3].T + matrix[:3, 3]
offsets = (after["Cap"] - after["Basis"]) @ matrix[:3, :3].T
pushed = np.any(after["Cap"] != after["Basis"], axis=1)
normals = basis / np.array([2.2, 2.0, 1.8]) ** 2
normals /= np.linalg.norm(normals, axis=1, keepdims=True)
along = np.einsum("ij,ij->i", offsets, normals)
across = np.linalg.norm(offsets - along[:, None] * normals, axis=1)
cap_faces = [f for f in faces if pushed[f].any()]  # the pushed vertices' one-rings
print(json.dumps({
    "keys": list(after),
    "pushed_before": int(np.any(before["Cap"] != before["Basis"], axis=1).sum()),
    "pushed": int(pushed.sum()),
    "along_mean": float(along[pushed].mean()),
    "across_max": float(across[pushed].max()),
    "cap_stretch": float(np.sqrt(area(basis, cap_faces) / area(before["Basis"], cap_faces))),
    "radius_error": float(np.abs(np.linalg.norm(basis / np.array([2.2, 2.0, 1.8]), axis=1) - 1.0).max()),
}))
"""


@pytest.fixture(scope="module")
def scene_blend(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shape_keys_inputs")
    maker = folder / "make.py"
    maker.write_text(MAKE_BLEND)
    path = folder / "scene.blend"
    made = run_script(maker, path)
    assert made.returncode == 0, made.stderr[-2000:]
    reader = folder / "read.py"
    reader.write_text(READ_KEYS)
    return path, reader


def measure(scene_blend, result, name):
    path, reader = scene_blend
    measured = run_script(reader, path, result, name)
    assert measured.returncode == 0, measured.stderr[-2000:]
    # The reader prints one JSON line; the blender binary prints "Blender quit" after it.
    [line] = [line for line in measured.stdout.splitlines() if line.startswith("{")]
    return json.loads(line)


def assert_carried(measured):
    """The key is kept, on the same vertices, pushing along the ellipsoid's normal by 0.1 times the stretch of
    the pushed vertices' faces (the root of their area ratio)."""
    assert measured["keys"] == ["Basis", "Cap"]
    assert measured["pushed"] == measured["pushed_before"] > 20
    assert measured["radius_error"] < 0.01  # the basis is on the ellipsoid
    assert measured["along_mean"] == pytest.approx(0.1 * measured["cap_stretch"], rel=0.05)
    assert 0.18 < measured["along_mean"] < 0.3
    assert measured["across_max"] < 0.2 * measured["along_mean"]


def test_wrap_py_carries_the_keys_over(scene_blend, tmp_path):
    output = tmp_path / "wrapped.blend"
    done = run_script(
        SCRIPTS / "wrap.py",
        "--blend",
        scene_blend[0],
        "--layout",
        "Sphere",
        "--target",
        "Ellipsoid",
        "--anchors-spacing",
        "0",
        "--output",
        output,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "shape keys carried over onto the wrapped basis: Basis, Cap" in done.stdout
    assert_carried(measure(scene_blend, output, "Sphere"))


def test_retarget_py_carries_the_keys_over_and_reports_them(scene_blend, tmp_path):
    output, report = tmp_path / "r.blend", tmp_path / "r.json"
    done = run_script(
        SCRIPTS / "retarget.py",
        "--template",
        scene_blend[0],
        "--template-object",
        "Sphere",
        "--target",
        scene_blend[0],
        "--target-object",
        "Ellipsoid",
        "--align",
        "bounds",
        "--anchors-spacing",
        "0",
        "--shape-keys",
        "transfer",
        "--output-blend",
        output,
        "--report",
        report,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(report.read_text())["shape_keys"] == {"mode": "TRANSFER", "keys": ["Basis", "Cap"]}
    assert_carried(measure(scene_blend, output, "Retargeted"))


@pytest.mark.parametrize("script", ["wrap.py", "retarget.py", "mirror.py"])
def test_refuse_fails_in_one_line_naming_the_option_and_writes_nothing(scene_blend, tmp_path, script):
    output = tmp_path / "out.blend"
    arguments = {
        "wrap.py": ["--blend", scene_blend[0], "--layout", "Sphere", "--target", "Ellipsoid", "--output", output],
        "retarget.py": ["--template", scene_blend[0], "--template-object", "Sphere", "--target", scene_blend[0]]
        + ["--target-object", "Ellipsoid", "--output-blend", output],
        "mirror.py": ["--layout", scene_blend[0], "--layout-object", "Sphere", "--target", scene_blend[0]]
        + ["--target-object", "Ellipsoid", "--output-blend", output],
    }[script]
    done = run_script(SCRIPTS / script, *arguments, "--shape-keys", "REFUSE")
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    failure = done.stderr.strip().splitlines()[-1]
    assert "has shape keys; Shape Keys is set to Refuse" in failure and "--shape-keys REFUSE" in failure
    assert sorted(path.name for path in tmp_path.iterdir()) == []


@pytest.mark.parametrize("script", ["wrap.py", "retarget.py", "mirror.py"])
def test_an_unknown_shape_keys_value_exits_with_code_2(scene_blend, script):
    done = run_script(SCRIPTS / script, "--shape-keys", "KEEP")
    assert done.returncode == 2
    assert "--shape-keys" in done.stderr
