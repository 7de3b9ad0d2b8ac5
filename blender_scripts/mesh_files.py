"""Mesh files checked before Blender's importers read them, and the coordinate limits every input is held to.

Blender's importers trust their input: a PLY header announcing 4e9 vertices aborts the whole process
(``std::out_of_range``, exit 134) and ``v nan nan nan`` in an OBJ is read as the origin. So every mesh
file goes through :func:`check_mesh_file` first, which reads it the way the importer will and refuses,
with one line naming the file and the problem: an empty or truncated file, binary garbage, a header
whose element counts the file cannot hold, an index naming a vertex that does not exist, a coordinate
that is not a number, not finite, or beyond :data:`MAX_COORDINATE`. A .blend is only recognised by its
header (:func:`check_blend_file`); Blender reads the rest and says what is wrong with it. What the importers make of a file
is checked again after the import (``scene_io.check_world_coordinates``).

No ``bpy`` here: numpy only (the batch's coordinator and the tests use it without Blender).
"""

import json
import math
import re
import struct
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # `blender --python` does not add it
from headless import ScriptError

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
"""Mesh files the scripts read (a .blend is read too, as Blender's own file)."""

MAX_COORDINATE = 1.0e9
"""Coordinates beyond this (in absolute value) are refused: Blender stores float32, which keeps no
fraction of a unit there (its spacing at 1e9 is 64), and such values make the wrap crawl."""

MAX_ELEMENTS = 2**31 - 1
"""Blender's importers count elements in a C ``int``: more aborts them."""

PLY_HEADER_LIMIT = 1 << 20
"""A PLY header longer than this (1 MiB) is not a header."""

PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}

GLTF_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
GLTF_TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def check_mesh_file(path: Path) -> None:
    """Refuse (:class:`ScriptError`, naming ``path``) a mesh file Blender's importer must not be given."""
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise ScriptError(f"{path}: not a mesh file ({', '.join((*MESH_SUFFIXES, '.blend'))})")
    if not path.is_file():
        raise ScriptError(f"{path}: no such file")
    try:
        data = path.read_bytes()
    except OSError as error:
        raise ScriptError(f"{path}: cannot read: {error.strerror or error}") from None
    if not data.strip():
        raise ScriptError(f"{path}: the file is empty")
    check = {".obj": _check_obj, ".ply": _check_ply, ".stl": _check_stl, ".glb": _check_glb, ".gltf": _check_gltf}
    try:
        check[suffix](path, data)
    except MeshFileError as error:
        raise ScriptError(f"{path}: {error}") from None


def check_blend_file(path: Path) -> None:
    """Refuse an empty file, or one that is not a .blend (Blender's own, or compressed), before Blender reads it."""
    if not path.is_file():
        raise ScriptError(f"{path}: no such file")
    with open(path, "rb") as handle:
        head = handle.read(12)
    if not head:
        raise ScriptError(f"{path}: the file is empty")
    if not head.startswith((b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")):  # plain, gzip, zstd
        raise ScriptError(f"{path}: not a .blend file (no 'BLENDER' header)")


class MeshFileError(Exception):
    """What is wrong with a mesh file (the caller names the file)."""


def check_coordinates(points: np.ndarray, where=lambda index: f"vertex {index}") -> None:
    """Refuse the first point of the (N, 3) ``points`` with a coordinate that is NaN, infinite or beyond
    :data:`MAX_COORDINATE`; ``where(index)`` names it."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        index = int(np.flatnonzero(~finite)[0])
        raise MeshFileError(f"{where(index)} has a NaN or infinite coordinate {_triple(points[index])}")
    beyond = (np.abs(points) > MAX_COORDINATE).any(axis=1)
    if beyond.any():
        index = int(np.flatnonzero(beyond)[0])
        raise MeshFileError(
            f"{where(index)} is absurdly far from the origin {_triple(points[index])}: "
            f"coordinates beyond {MAX_COORDINATE:g} are refused"
        )


def _triple(point) -> str:
    return "(" + ", ".join(f"{value:g}" for value in point) + ")"


def _not_text(data: bytes) -> None:
    nul = data.find(b"\0")
    if nul >= 0:
        raise MeshFileError(f"binary data (a NUL byte at byte {nul}): not a text file")


# ---------------------------------------------------------------- OBJ


OBJ_ELEMENTS = (b"f ", b"f\t", b"l ", b"l\t", b"p ", b"p\t")


def _check_obj(_path: Path, data: bytes) -> None:
    """Every ``v`` line has three numbers, every face and line index names a vertex of the file."""
    _not_text(data)
    data = data.replace(b"\\\r\n", b" ").replace(b"\\\n", b" ")  # a line ending in a backslash goes on
    if not _obj_is_clean(data):
        _find_obj_fault(data.decode("latin-1"))


def _obj_is_clean(data: bytes) -> bool:
    """The whole file at numpy's speed: True when it is good; False when something is off (or unusual, such
    as relative indices), for :func:`_find_obj_fault` to name it line by line."""
    lines = [line.lstrip() for line in data.splitlines()]
    vertex_text = b"\n".join(line[2:] for line in lines if line.startswith((b"v ", b"v\t")))
    words_per_line = _words_per_line(vertex_text)
    if not len(words_per_line) or words_per_line.min() != words_per_line.max() or words_per_line[0] < 3:
        return False  # no vertices, too few coordinates, or lines of different lengths (x y z [w] [r g b])
    values = _numbers(vertex_text, np.float64, int(words_per_line.sum()))
    if values is None:
        return False
    points = values.reshape(len(words_per_line), -1)[:, :3]
    if not (np.isfinite(points).all() and (np.abs(points) <= MAX_COORDINATE).all()):
        return False
    element_text = b"\n".join(line[2:] for line in lines if line.startswith(OBJ_ELEMENTS))
    if b"/" in element_text:  # v/vt/vn: the vertex index is the first of each
        element_text = re.sub(rb"/\S*", b"", element_text)
    indices = _numbers(element_text, np.int64, _word_count(element_text))
    if indices is None:
        return False
    return not len(indices) or bool(indices.min() >= 1 and indices.max() <= len(points))


WHITESPACE = np.zeros(256, dtype=bool)
WHITESPACE[[9, 10, 11, 12, 13, 32]] = True


def _word_starts(text: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``text`` as bytes, and where each of its whitespace-separated words starts (True)."""
    codes = np.frombuffer(text, dtype=np.uint8)
    space = WHITESPACE[codes]
    starts = ~space
    starts[1:] &= space[:-1]
    return codes, starts


def _word_count(text: bytes) -> int:
    return int(np.count_nonzero(_word_starts(text)[1])) if text else 0


def _words_per_line(text: bytes) -> np.ndarray:
    """How many whitespace-separated words each line of ``text`` holds (lines without any left out)."""
    if not text:
        return np.zeros(0, dtype=np.int64)
    codes, starts = _word_starts(text)
    line = np.cumsum(codes == 10)
    counts = np.bincount(line[starts], minlength=int(line[-1]) + 1)
    return counts[counts > 0]


def _numbers(text: bytes, dtype, expected: int) -> np.ndarray | None:
    """The ``expected`` whitespace-separated numbers of ``text``, or None when a word is not one."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpy warns when it stops at a word that is not a number
        values = np.fromstring(text, dtype=dtype, sep=" ")
    return values if len(values) == expected else None


def _find_obj_fault(text: str) -> None:
    """The first fault of an OBJ file, by its line (see :func:`_obj_is_clean`); nothing when there is none."""
    coordinates: list[tuple[float, float, float]] = []
    vertex_lines: list[int] = []
    references: list[tuple[int, int]] = []  # (line, 1-based index into the file's vertices)
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        keyword = words[0]
        if keyword == "v":
            if len(words) < 4:
                raise MeshFileError(f"line {number}: a vertex needs three coordinates: {line.strip()[:80]!r}")
            try:
                coordinates.append((float(words[1]), float(words[2]), float(words[3])))
            except ValueError:
                raise MeshFileError(
                    f"line {number}: a vertex coordinate is not a number: {line.strip()[:80]!r}"
                ) from None
            vertex_lines.append(number)
        elif keyword in ("f", "l", "p"):
            for word in words[1:]:
                try:
                    index = int(word.split("/")[0])
                except ValueError:
                    raise MeshFileError(f"line {number}: {word!r} is not a vertex index") from None
                if index < 0:  # relative: -1 is the last vertex so far
                    index += len(coordinates) + 1
                references.append((number, index))
    for number, index in references:
        if not 1 <= index <= len(coordinates):
            raise MeshFileError(
                f"line {number}: vertex index {index} does not exist (the file has {len(coordinates)} vertices)"
            )
    if not coordinates:
        raise MeshFileError("no vertices (no 'v' line): not an OBJ mesh")
    check_coordinates(
        np.array(coordinates, dtype=np.float64),
        lambda index: f"vertex {index} (line {vertex_lines[index]})",
    )


# ---------------------------------------------------------------- PLY


class _PlyElement:
    def __init__(self, name: str, count: int) -> None:
        self.name, self.count = name, count
        self.properties: list[tuple[str, str, str | None]] = []  # (name, type or list count type, list item type)

    def is_scalar(self) -> bool:
        return all(item is None for _name, _kind, item in self.properties)


def _ply_header(data: bytes) -> tuple[str, list[_PlyElement], int]:
    """The format, the elements and the offset of the body."""
    if not data.startswith((b"ply\n", b"ply\r\n")):
        raise MeshFileError("not a PLY file (it does not start with 'ply')")
    end = data.find(b"end_header", 0, PLY_HEADER_LIMIT)
    if end < 0:
        raise MeshFileError("no 'end_header' line in the first MiB: not a PLY header")
    body = data.find(b"\n", end)
    if body < 0:
        raise MeshFileError("the file ends after 'end_header': no data")
    body += 1
    _not_text(data[:end])
    form, elements = None, []
    for number, line in enumerate(data[:end].decode("latin-1").splitlines()[1:], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) != 3 or words[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise MeshFileError(f"header line {number}: unknown format {line.strip()!r}")
            form = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise MeshFileError(f"header line {number}: expected 'element NAME COUNT', found {line.strip()!r}")
            count = int(words[2])
            if count > MAX_ELEMENTS:
                raise MeshFileError(
                    f"header line {number}: element '{words[1]}' has {count} entries, more than Blender's PLY "
                    f"importer can read ({MAX_ELEMENTS})"
                )
            elements.append(_PlyElement(words[1], count))
        elif words[0] == "property":
            if not elements:
                raise MeshFileError(f"header line {number}: a property before any element")
            if len(words) == 5 and words[1] == "list" and words[2] in PLY_TYPES and words[3] in PLY_TYPES:
                elements[-1].properties.append((words[4], words[2], words[3]))
            elif len(words) == 3 and words[1] in PLY_TYPES:
                elements[-1].properties.append((words[2], words[1], None))
            else:
                raise MeshFileError(f"header line {number}: unknown property {line.strip()!r}")
        else:
            raise MeshFileError(f"header line {number}: not a PLY header line: {line.strip()[:80]!r}")
    if form is None:
        raise MeshFileError("the header has no 'format' line")
    vertex = next((element for element in elements if element.name == "vertex"), None)
    if vertex is None:
        raise MeshFileError("the header has no 'vertex' element")
    scalars = {name for name, _kind, item in vertex.properties if item is None}
    if not {"x", "y", "z"} <= scalars:
        raise MeshFileError("the 'vertex' element has no x, y and z properties")
    if any(not element.properties for element in elements if element.count):
        empty = next(element.name for element in elements if element.count and not element.properties)
        raise MeshFileError(f"element '{empty}' has entries but no properties")
    return form, elements, body


def _check_ply(_path: Path, data: bytes) -> None:
    form, elements, body = _ply_header(data)
    if form == "ascii":
        _check_ply_ascii(data[body:], elements)
    else:
        _check_ply_binary(data[body:], elements, "<" if form == "binary_little_endian" else ">")


def _check_ply_binary(body: bytes, elements: list[_PlyElement], order: str) -> None:
    offset, vertex_count = 0, None
    for element in elements:
        left = len(body) - offset
        smallest = sum(
            np.dtype(PLY_TYPES[kind]).itemsize for _name, kind, _item in element.properties
        )  # lists: count only
        if element.count * smallest > left:
            raise MeshFileError(
                f"truncated: element '{element.name}' announces {element.count} entries of at least {smallest} "
                f"bytes, {left} bytes are left"
            )
        if element.is_scalar():
            row = np.dtype(
                [(f"p{index}", order + PLY_TYPES[kind]) for index, (_n, kind, _i) in enumerate(element.properties)]
            )
            table = np.frombuffer(body, dtype=row, count=element.count, offset=offset)
            offset += element.count * row.itemsize
            if element.name == "vertex":
                names = [name for name, _kind, _item in element.properties]
                points = np.stack([table[f"p{names.index(axis)}"].astype(np.float64) for axis in "xyz"], axis=1)
                check_coordinates(points)
                vertex_count = element.count
            continue
        offset, indices = _walk_binary_lists(body, offset, element, order)
        if indices is not None and vertex_count is not None:
            _check_indices(indices, vertex_count, element.name)


def _walk_binary_lists(body: bytes, offset: int, element: _PlyElement, order: str):
    """The offset after an element with list properties, and its vertex indices (or None)."""
    collected = []
    is_faces = element.name in ("face", "edge")
    # The usual face element (one list, all of the same length): checked as one array.
    if len(element.properties) == 1 and element.count:
        _name, count_kind, item_kind = element.properties[0]
        count_type, item_type = np.dtype(order + PLY_TYPES[count_kind]), np.dtype(order + PLY_TYPES[item_kind])
        first = int(np.frombuffer(body, dtype=count_type, count=1, offset=offset)[0])
        stride = count_type.itemsize + max(first, 0) * item_type.itemsize
        if first >= 0 and offset + element.count * stride <= len(body):
            row = np.dtype([("n", count_type), ("items", item_type, (first,))])
            table = np.frombuffer(body, dtype=row, count=element.count, offset=offset)
            if (table["n"] == first).all():
                indices = table["items"].reshape(-1).astype(np.int64) if is_faces else None
                return offset + element.count * stride, indices
    for entry in range(element.count):
        for name, kind, item in element.properties:
            size = np.dtype(PLY_TYPES[kind]).itemsize
            if offset + size > len(body):
                raise MeshFileError(f"truncated: element '{element.name}' ends at entry {entry} of {element.count}")
            value = struct.unpack_from(order + np.dtype(PLY_TYPES[kind]).char, body, offset)[0]
            offset += size
            if item is None:
                continue
            if value < 0:
                raise MeshFileError(f"element '{element.name}' entry {entry}: a list of {value} items")
            item_size = np.dtype(PLY_TYPES[item]).itemsize
            if offset + value * item_size > len(body):
                raise MeshFileError(f"truncated: element '{element.name}' ends at entry {entry} of {element.count}")
            if is_faces and name in ("vertex_indices", "vertex_index"):
                collected.append(np.frombuffer(body, dtype=order + PLY_TYPES[item], count=value, offset=offset))
            offset += value * item_size
    indices = np.concatenate(collected).astype(np.int64) if collected else None
    return offset, indices


def _ply_ascii_is_clean(body: bytes, elements: list[_PlyElement]) -> bool:
    """The whole body at numpy's speed when its lists all have one length per element (triangles, quads): True
    when it is good; False when something is off or unusual, for :func:`_check_ply_ascii` to name it."""
    values = _numbers(body, np.float64, _word_count(body))
    if values is None:
        return False
    position, vertex_count = 0, None
    for element in elements:
        if element.is_scalar():
            width = len(element.properties)
            if position + element.count * width > len(values):
                return False
            table = values[position : position + element.count * width].reshape(element.count, width)
            position += element.count * width
            if element.name == "vertex":
                names = [name for name, _kind, _item in element.properties]
                points = table[:, [names.index(axis) for axis in "xyz"]]
                if not (np.isfinite(points).all() and (np.abs(points) <= MAX_COORDINATE).all()):
                    return False
                vertex_count = element.count
            continue
        if len(element.properties) != 1 or position >= len(values) or not element.count:
            return False
        first = values[position]
        stride = 1 + int(first) if first == int(first) and first >= 0 else 0
        if not stride or position + element.count * stride > len(values):
            return False
        rows = values[position : position + element.count * stride].reshape(element.count, stride)
        position += element.count * stride
        indices = rows[:, 1:]
        if not (rows[:, 0] == first).all() or not (indices == np.floor(indices)).all():
            return False
        if vertex_count is not None and indices.size and (indices.min() < 0 or indices.max() >= vertex_count):
            return False
    return True


def _check_ply_ascii(body: bytes, elements: list[_PlyElement]) -> None:
    _not_text(body)
    if _ply_ascii_is_clean(body, elements):
        return
    tokens = body.split()
    position, vertex_count = 0, None
    for element in elements:
        left = len(tokens) - position
        if element.count * len(element.properties) > left:
            raise MeshFileError(
                f"truncated: element '{element.name}' announces {element.count} entries of "
                f"{len(element.properties)} values or more, {left} values are left"
            )
        if element.is_scalar():
            width = len(element.properties)
            table = tokens[position : position + element.count * width]
            position += element.count * width
            if element.name == "vertex":
                names = [name for name, _kind, _item in element.properties]
                try:
                    values = np.array(table, dtype=np.bytes_).astype(np.float64).reshape(element.count, width)
                except ValueError:
                    raise MeshFileError("a vertex value is not a number") from None
                check_coordinates(values[:, [names.index(axis) for axis in "xyz"]])
                vertex_count = element.count
            continue
        collected = []
        for entry in range(element.count):
            for name, _kind, item in element.properties:
                try:
                    value = int(tokens[position]) if item is not None else float(tokens[position])
                except IndexError:
                    raise MeshFileError(
                        f"truncated: element '{element.name}' ends at entry {entry} of {element.count}"
                    ) from None
                except ValueError:
                    raise MeshFileError(
                        f"element '{element.name}' entry {entry}: {tokens[position][:20]!r} is not a number"
                    ) from None
                position += 1
                if item is None:
                    continue
                if value < 0 or position + value > len(tokens):
                    raise MeshFileError(f"truncated: element '{element.name}' ends at entry {entry} of {element.count}")
                if name in ("vertex_indices", "vertex_index"):
                    try:
                        collected.extend(int(token) for token in tokens[position : position + value])
                    except ValueError:
                        raise MeshFileError(
                            f"element '{element.name}' entry {entry}: an index is not a number"
                        ) from None
                position += value
        if collected and vertex_count is not None:
            _check_indices(np.array(collected, dtype=np.int64), vertex_count, element.name)


def _check_indices(indices: np.ndarray, vertex_count: int, element: str) -> None:
    bad = (indices < 0) | (indices >= vertex_count)
    if bad.any():
        raise MeshFileError(
            f"element '{element}': vertex index {int(indices[np.flatnonzero(bad)[0]])} does not exist "
            f"(the file has {vertex_count} vertices)"
        )


# ---------------------------------------------------------------- STL


STL_TRIANGLE = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def _check_stl(_path: Path, data: bytes) -> None:
    if len(data) >= 84:
        count = struct.unpack_from("<I", data, 80)[0]
        if 84 + 50 * count == len(data) or not data.lstrip().startswith(b"solid"):
            if 84 + 50 * count > len(data):
                raise MeshFileError(
                    f"truncated binary STL: {count} triangles need {84 + 50 * count} bytes, the file has {len(data)}"
                )
            if count == 0:
                raise MeshFileError("a binary STL with no triangles")
            triangles = np.frombuffer(data, dtype=STL_TRIANGLE, count=count, offset=84)
            check_coordinates(
                triangles["corners"].reshape(-1, 3), lambda index: f"triangle {index // 3} corner {index % 3}"
            )
            return
    elif not data.lstrip().startswith(b"solid"):
        raise MeshFileError(f"truncated: {len(data)} bytes is less than a binary STL's 84-byte header")
    _not_text(data)
    points = []
    for number, line in enumerate(data.decode("latin-1").splitlines(), start=1):
        words = line.split()
        if words[:1] == ["vertex"]:
            try:
                points.append(tuple(float(word) for word in words[1:4]))
            except ValueError:
                raise MeshFileError(f"line {number}: a vertex coordinate is not a number") from None
            if len(points[-1]) != 3:
                raise MeshFileError(f"line {number}: a vertex needs three coordinates")
    if not points or len(points) % 3:
        raise MeshFileError(f"an ASCII STL needs three vertices per facet, found {len(points)} vertices")
    check_coordinates(np.array(points), lambda index: f"facet {index // 3} vertex {index % 3}")


# ---------------------------------------------------------------- glTF


def _check_glb(path: Path, data: bytes) -> None:
    if len(data) < 20 or data[:4] != b"glTF":
        raise MeshFileError("not a binary glTF (.glb) file (no 'glTF' header)")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise MeshFileError(f"glTF version {version}: only version 2 is read")
    if length > len(data):
        raise MeshFileError(f"truncated: the header says {length} bytes, the file has {len(data)}")
    chunks, offset = {}, 12
    while offset + 8 <= length:
        size, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + size > length:
            raise MeshFileError(f"truncated: a chunk of {size} bytes at byte {offset} runs past the end")
        chunks.setdefault(kind, data[offset + 8 : offset + 8 + size])
        offset += 8 + size
    if 0x4E4F534A not in chunks:
        raise MeshFileError("no JSON chunk")
    document = _gltf_json(chunks[0x4E4F534A])
    _check_gltf_document(path, document, chunks.get(0x004E4942))


def _check_gltf(path: Path, data: bytes) -> None:
    _check_gltf_document(path, _gltf_json(data), None)


def _gltf_json(data: bytes) -> dict:
    try:
        document = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise MeshFileError(f"not valid glTF JSON: {error}") from None
    if not isinstance(document, dict):
        raise MeshFileError("not valid glTF JSON: not an object")
    return document


def _check_gltf_document(path: Path, document: dict, binary: bytes | None) -> None:
    """Buffers hold what they say, views lie inside their buffers, accessors inside their views, and the
    meshes' positions are finite and not absurd (Blender's glTF importer reads a NaN as 0)."""
    import base64

    try:
        contents = []
        for index, buffer in enumerate(document.get("buffers", [])):
            uri = buffer.get("uri")
            if uri is None:
                content = binary if binary is not None else b""
            elif uri.startswith("data:"):
                content = base64.b64decode(uri.partition(",")[2], validate=False)
            else:
                external = path.parent / uri
                if not external.is_file():
                    raise MeshFileError(f"buffer {index}: no such file {external}")
                content = external.read_bytes()
            if int(buffer["byteLength"]) > len(content):
                raise MeshFileError(
                    f"truncated: buffer {index} says {buffer['byteLength']} bytes, {len(content)} are there"
                )
            contents.append(content)
        sizes = [int(buffer["byteLength"]) for buffer in document.get("buffers", [])]
        views = document.get("bufferViews", [])
        for index, view in enumerate(views):
            end = int(view.get("byteOffset", 0)) + int(view["byteLength"])
            if not 0 <= int(view["buffer"]) < len(sizes) or end > sizes[int(view["buffer"])]:
                raise MeshFileError(f"buffer view {index} lies outside its buffer")
        for index, accessor in enumerate(document.get("accessors", [])):
            count = int(accessor["count"])
            element = GLTF_COMPONENT_BYTES[int(accessor["componentType"])] * GLTF_TYPE_COMPONENTS[accessor["type"]]
            if count > MAX_ELEMENTS:
                raise MeshFileError(f"accessor {index} has {count} elements, more than Blender can read")
            if "bufferView" not in accessor:
                continue
            view = views[int(accessor["bufferView"])]
            stride = int(view.get("byteStride", element))
            needed = int(accessor.get("byteOffset", 0)) + (stride * (count - 1) + element if count else 0)
            if needed > int(view["byteLength"]):
                raise MeshFileError(f"accessor {index} needs {needed} bytes, its buffer view has {view['byteLength']}")
            if accessor["type"] == "VEC3" and int(accessor["componentType"]) == 5126:
                start = int(view.get("byteOffset", 0)) + int(accessor.get("byteOffset", 0))
                points = np.ndarray(
                    (count, 3), dtype="<f4", buffer=contents[int(view["buffer"])], offset=start, strides=(stride, 4)
                )
                try:
                    check_coordinates(points)
                except MeshFileError as error:
                    raise MeshFileError(f"accessor {index}: {error}") from None
                for name, bound in (("min", accessor.get("min")), ("max", accessor.get("max"))):
                    if bound is not None and not all(
                        isinstance(value, (int, float)) and math.isfinite(value) and abs(value) <= MAX_COORDINATE
                        for value in bound
                    ):
                        raise MeshFileError(f"accessor {index}: its {name} {bound} is not finite or absurdly large")
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
        raise MeshFileError(f"malformed glTF ({type(error).__name__}: {error})") from None
