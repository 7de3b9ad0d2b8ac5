"""Mesh files are checked before Blender's importers see them (``blender_scripts/mesh_files.py``): good files of
every format pass, and every hostile one is refused with one line naming the file and the problem. Plain
Python, no Blender (the scripts' end-to-end runs are in ``test_cli_catalogue.py``)."""

import json
import re
import struct

import numpy as np
import pytest

import mesh_files
from headless import ScriptError
from helpers import obj_text
from mesh_writers import ellipsoid, glb, gltf_text, ply_ascii, ply_binary, stl_ascii, stl_binary

VERTICES, TRIANGLES = ellipsoid(segments=8, rings=4)
QUADS_AND_TRIANGLES = [[0, 1, 2], [1, 2, 3, 4], [2, 3, 4]]  # faces of different lengths


def refused(tmp_path, name: str, data: bytes) -> str:
    """The one-line refusal of a file ``name`` holding ``data`` (the test fails when it passes)."""
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(ScriptError) as error:
        mesh_files.check_mesh_file(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message.removeprefix(f"{path}: ")


@pytest.mark.parametrize(
    "name, data",
    [
        ("ball.obj", obj_text(VERTICES, TRIANGLES).encode()),
        ("ball.ply", ply_ascii(VERTICES, TRIANGLES)),
        ("ball_le.ply", ply_binary(VERTICES, TRIANGLES)),
        ("ball_be.ply", ply_binary(VERTICES, TRIANGLES, order=">")),
        ("mixed.ply", ply_binary(VERTICES, QUADS_AND_TRIANGLES)),
        ("mixed_ascii.ply", ply_ascii(VERTICES, QUADS_AND_TRIANGLES)),
        ("ball.stl", stl_binary(VERTICES, TRIANGLES)),
        ("ball_ascii.stl", stl_ascii(VERTICES, TRIANGLES)),
        ("ball.gltf", gltf_text(VERTICES, TRIANGLES)),
        ("ball.glb", glb(VERTICES, TRIANGLES)),
        ("relative.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n"),
        ("continued.obj", b"v 0 0 \\\n 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("with_w.obj", b"# comment\nv 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nvt 0 0\nf 1/1 2/1 3/1\n"),
        ("colours.obj", b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvn 0 0 1\nf 1//1 2//1 3//1\nl 1 2\n"),
        ("mixed.obj", b"v 0 0 0\nv 1 0 0 1\n  v 0 1 0\nf 1 2 3\n"),
    ],
)
def test_good_files_of_every_format_pass(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data)
    mesh_files.check_mesh_file(path)


def test_missing_empty_and_unknown_files(tmp_path):
    with pytest.raises(ScriptError, match="no such file"):
        mesh_files.check_mesh_file(tmp_path / "nowhere.obj")
    for name in ("empty.obj", "empty.ply", "empty.stl", "empty.glb", "empty.gltf"):
        assert refused(tmp_path, name, b"") == "the file is empty"
    assert refused(tmp_path, "blank.obj", b"\n  \n") == "the file is empty"
    assert "not a mesh file" in refused(tmp_path, "notes.txt", b"v 0 0 0\n")


BINARY_GARBAGE = bytes(np.random.default_rng(13).integers(0, 256, 3000, dtype=np.uint8))


@pytest.mark.parametrize(
    "name, expected",
    [
        ("garbage.obj", "binary data (a NUL byte at byte"),
        ("garbage.ply", "not a PLY file"),
        ("garbage.stl", "truncated binary STL"),
        ("garbage.glb", "not a binary glTF"),
        ("garbage.gltf", "not valid glTF JSON"),
    ],
)
def test_binary_garbage_is_refused(tmp_path, name, expected):
    assert expected in refused(tmp_path, name, BINARY_GARBAGE)


@pytest.mark.parametrize(
    "text, expected",
    [
        (
            "v nan nan nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "vertex 0 (line 1) has a NaN or infinite coordinate (nan, nan, nan)",
        ),
        ("v 0 0 0\nv 1 inf 0\nv 0 1 0\nf 1 2 3\n", "vertex 1 (line 2) has a NaN or infinite coordinate (1, inf, 0)"),
        ("v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n", "vertex 2 (line 3) is absurdly far from the origin (0, 1e+39, 0)"),
        ("v 0 0 0\nv 1 0 0\nv 0 0 3e30\nf 1 2 3\n", "vertex 2 (line 3) is absurdly far from the origin (0, 0, 3e+30)"),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "line 2: a vertex needs three coordinates"),
        ("v 0 0 0\nv 1 up 0\nv 0 1 0\nf 1 2 3\n", "line 2: a vertex coordinate is not a number"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "line 4: vertex index 9 does not exist (the file has 3 vertices)"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "line 4: vertex index 0 does not exist"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "line 4: 'x' is not a vertex index"),
        ("o nothing\ng here\n", "no vertices (no 'v' line)"),
    ],
)
def test_obj_faults(tmp_path, text, expected):
    assert expected in refused(tmp_path, "bad.obj", text.encode())
    assert not mesh_files._obj_is_clean(text.encode())  # the fast pass hands it to the line-by-line one


def test_the_fast_obj_pass_takes_the_usual_files():
    """Large OBJ files are checked by numpy (about 1 s for 35 MiB); only unusual ones go line by line."""
    assert mesh_files._obj_is_clean(obj_text(VERTICES, TRIANGLES).encode())
    assert mesh_files._obj_is_clean(b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1/1/1 2/2/2 3/3/3\n")
    assert not mesh_files._obj_is_clean(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n")  # relative: line by line


def test_ply_counts_the_file_cannot_hold(tmp_path):
    """A header announcing 4e9 vertices aborted Blender's importer (exit 134): refused from the header alone."""
    huge = ply_header_only("ascii", 4_000_000_000) + b"0 0 0\n"
    assert "element 'vertex' has 4000000000 entries, more than Blender's PLY importer can read" in refused(
        tmp_path, "huge.ply", huge
    )
    many = ply_header_only("binary_little_endian", 2_000_000_000) + struct.pack("<3f", 0, 0, 0)
    assert refused(tmp_path, "many.ply", many) == (
        "truncated: element 'vertex' announces 2000000000 entries of at least 12 bytes, 12 bytes are left"
    )
    faces = ply_binary(VERTICES, TRIANGLES).replace(
        f"element face {len(TRIANGLES)}".encode(), b"element face 1000000000"
    )
    assert "truncated: element 'face' announces 1000000000 entries" in refused(tmp_path, "faces.ply", faces)
    ascii_many = ply_ascii(VERTICES, TRIANGLES).replace(
        f"element vertex {len(VERTICES)}".encode(), b"element vertex 9999"
    )
    assert "truncated: element 'vertex' announces 9999 entries" in refused(tmp_path, "ascii_many.ply", ascii_many)


def ply_header_only(form: str, vertex_count: int) -> bytes:
    return (
        f"ply\nformat {form} 1.0\nelement vertex {vertex_count}\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n"
    ).encode()


@pytest.mark.parametrize("writer", [ply_ascii, ply_binary], ids=["ascii", "binary"])
def test_truncated_ply_is_refused_wherever_it_is_cut(tmp_path, writer):
    whole = writer(VERTICES, TRIANGLES)
    body = whole.index(b"end_header\n") + len(b"end_header\n")
    for cut in (body + 5, (body + len(whole)) // 2, len(whole) - 6):
        assert "truncated" in refused(tmp_path, "cut.ply", whole[:cut]), cut
    assert "no 'end_header'" in refused(tmp_path, "header.ply", whole[: body - 20])


@pytest.mark.parametrize("writer", [ply_ascii, ply_binary], ids=["ascii", "binary"])
def test_ply_indices_and_coordinates(tmp_path, writer):
    far_face = [[0, 1, len(VERTICES) + 5]]
    assert f"element 'face': vertex index {len(VERTICES) + 5} does not exist" in refused(
        tmp_path, "index.ply", writer(VERTICES, [*TRIANGLES.tolist(), *far_face])
    )
    broken = VERTICES.copy()
    broken[4] = (np.nan, 0.0, 0.0)
    assert (
        refused(tmp_path, "nan.ply", writer(broken, TRIANGLES))
        == "vertex 4 has a NaN or infinite coordinate (nan, 0, 0)"
    )
    broken[4] = (0.0, -2e20, 0.0)
    assert "vertex 4 is absurdly far from the origin (0, -2e+20, 0)" in refused(
        tmp_path, "far.ply", writer(broken, TRIANGLES)
    )


def test_ply_header_faults(tmp_path):
    good = ply_ascii(VERTICES, TRIANGLES)
    assert "unknown format" in refused(tmp_path, "f.ply", good.replace(b"format ascii 1.0", b"format utf16 1.0"))
    assert "unknown property" in refused(tmp_path, "p.ply", good.replace(b"property float x", b"property quaternion x"))
    assert "no x, y and z" in refused(tmp_path, "x.ply", good.replace(b"property float x", b"property float u"))
    assert "no 'vertex' element" in refused(tmp_path, "v.ply", good.replace(b"element vertex", b"element point"))
    assert "expected 'element NAME COUNT'" in refused(
        tmp_path, "c.ply", good.replace(f"element vertex {len(VERTICES)}".encode(), b"element vertex -5")
    )
    assert "a vertex value is not a number" in refused(tmp_path, "n.ply", good.replace(b"\n0.3", b"\nabc", 1))


def test_stl_faults(tmp_path):
    whole = stl_binary(VERTICES, TRIANGLES)
    assert "truncated binary STL" in refused(tmp_path, "cut.stl", whole[:-10])
    assert "less than a binary STL's 84-byte header" in refused(tmp_path, "short.stl", whole[:40])
    assert "a binary STL with no triangles" in refused(tmp_path, "none.stl", whole[:80] + struct.pack("<I", 0))
    broken = VERTICES.copy()
    broken[TRIANGLES[2][1]] = (0.0, np.inf, 0.0)
    assert refused(tmp_path, "inf.stl", stl_binary(broken, TRIANGLES)).startswith(
        "triangle 2 corner 1 has a NaN or infinite coordinate"
    )
    assert refused(tmp_path, "nan_ascii.stl", stl_ascii(broken, TRIANGLES)).startswith(
        "facet 2 vertex 1 has a NaN or infinite coordinate"
    )
    assert "three vertices per facet" in refused(tmp_path, "odd.stl", b"solid x\nvertex 0 0 0\nendsolid x\n")


def test_gltf_faults(tmp_path):
    whole = glb(VERTICES, TRIANGLES)
    assert "truncated: the header says" in refused(tmp_path, "cut.glb", whole[:-8])
    document = json.loads(gltf_text(VERTICES, TRIANGLES))
    document["accessors"][0]["count"] = 4_000_000_000
    assert "accessor 0 has 4000000000 elements" in refused(tmp_path, "count.gltf", json.dumps(document).encode())
    document["accessors"][0]["count"] = len(VERTICES) + 1
    assert "accessor 0 needs" in refused(tmp_path, "view.gltf", json.dumps(document).encode())
    document["accessors"][0]["count"] = len(VERTICES)
    document["accessors"][0]["max"] = [float("nan"), 0, 0]
    assert "its max [nan, 0, 0] is not finite" in refused(tmp_path, "max.gltf", json.dumps(document).encode())
    broken = VERTICES.copy()
    broken[3] = (0.0, 0.0, 5e12)
    assert refused(tmp_path, "far.glb", glb(broken, TRIANGLES, bounds=([-2.0] * 3, [2.0] * 3))) == (
        "accessor 0: vertex 3 is absurdly far from the origin (0, 0, 5e+12): coordinates beyond 1e+09 are refused"
    )  # the data, not only the bounds it states
    document["buffers"][0]["uri"] = "elsewhere.bin"
    assert "buffer 0: no such file" in refused(tmp_path, "external.gltf", json.dumps(document).encode())
    assert "malformed glTF" in refused(tmp_path, "shape.gltf", b'{"accessors": [{"count": "many"}]}')


def test_blend_files_are_recognised_by_their_header(tmp_path):
    for name, data, expected in (
        ("empty.blend", b"", "the file is empty"),
        ("text.blend", b"v 0 0 0\n", "not a .blend file (no 'BLENDER' header)"),
    ):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ScriptError, match=re.escape(f"{tmp_path / name}: {expected}")):
            mesh_files.check_blend_file(tmp_path / name)
    with pytest.raises(ScriptError, match="no such file"):
        mesh_files.check_blend_file(tmp_path / "missing.blend")
    for name, head in (
        ("plain.blend", b"BLENDER-v304RENDH"),
        ("gzip.blend", b"\x1f\x8b\x08"),
        ("zstd.blend", b"\x28\xb5\x2f\xfd"),
    ):
        (tmp_path / name).write_bytes(head + bytes(40))
        mesh_files.check_blend_file(tmp_path / name)  # Blender reads the rest
