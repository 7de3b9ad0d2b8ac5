"""Mesh files written byte by byte for the script tests (OBJ, PLY ascii and binary, STL ascii and binary,
glTF and .glb), so that a test states exactly what the importers get, good or hostile. No Blender."""

import base64
import json
import struct

import numpy as np

from helpers import sphere_faces, sphere_points, triangulated


def ellipsoid(
    centre=(0.3, -0.2, 0.1), radii=(1.0, 1.2, 0.8), segments: int = 24, rings: int = 12
) -> tuple[np.ndarray, np.ndarray]:
    """A UV ellipsoid, off the origin and of three different radii (any rotation of it is another shape), as
    (N, 3) float64 vertices and (M, 3) triangles winding outwards."""
    vertices = sphere_points(rings, segments) * np.array(radii) + np.array(centre)
    return vertices, triangulated(sphere_faces(rings, segments))


def on_ellipsoid(points, centre=(0.3, -0.2, 0.1), radii=(1.0, 1.2, 0.8)) -> np.ndarray:
    """The ellipsoid's implicit value at ``points``: 1 on the smooth surface (the faceted one is a little inside)."""
    scaled = (np.asarray(points, dtype=np.float64) - np.array(centre)) / np.array(radii)
    return np.sqrt((scaled**2).sum(axis=1))


def ply_header(form: str, vertex_count, face_count, index_type: str = "int") -> bytes:
    return (
        f"ply\nformat {form} 1.0\ncomment written by the Springwrap tests\nelement vertex {vertex_count}\n"
        f"property float x\nproperty float y\nproperty float z\nelement face {face_count}\n"
        f"property list uchar {index_type} vertex_indices\nend_header\n"
    ).encode()


def ply_ascii(vertices, faces) -> bytes:
    body = "".join(f"{x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in vertices)
    body += "".join(f"{len(face)} " + " ".join(map(str, face)) + "\n" for face in faces)
    return ply_header("ascii", len(vertices), len(faces)) + body.encode()


def ply_binary(vertices, faces, order: str = "<") -> bytes:
    form = "binary_little_endian" if order == "<" else "binary_big_endian"
    body = b"".join(struct.pack(order + "3f", *vertex) for vertex in vertices)
    body += b"".join(struct.pack(f"{order}B{len(face)}i", len(face), *face) for face in faces)
    return ply_header(form, len(vertices), len(faces)) + body


def stl_binary(vertices, triangles) -> bytes:
    vertices = np.asarray(vertices, dtype=np.float64)
    records = []
    for triangle in triangles:
        corners = vertices[list(triangle)]
        with np.errstate(invalid="ignore"):  # a hostile corner (NaN, inf) gives a NaN normal: written as it is
            normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
            normal = normal / (np.linalg.norm(normal) or 1.0)
        records.append(struct.pack("<12fH", *normal, *corners.ravel(), 0))
    return b"springwrap test".ljust(80, b" ") + struct.pack("<I", len(records)) + b"".join(records)


def stl_ascii(vertices, triangles) -> bytes:
    vertices = np.asarray(vertices, dtype=np.float64)
    lines = ["solid test"]
    for triangle in triangles:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.7f} {y:.7f} {z:.7f}" for x, y, z in vertices[list(triangle)]]
        lines += ["    endloop", "  endfacet"]
    return ("\n".join([*lines, "endsolid test"]) + "\n").encode()


def gltf_document(vertices, triangles, uri: str | None, bounds=None) -> tuple[dict, bytes]:
    """A glTF 2.0 document with one mesh node (no transform) and its binary buffer; ``bounds``, the positions'
    (min, max) it states (default: the true ones)."""
    positions = np.ascontiguousarray(vertices, dtype="<f4")
    indices = np.ascontiguousarray(np.asarray(triangles).ravel(), dtype="<u4")
    binary = positions.tobytes() + indices.tobytes()
    buffer = {"byteLength": len(binary)} | ({"uri": uri} if uri is not None else {})
    document = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "Mesh"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [buffer],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions.nbytes},
            {"buffer": 0, "byteOffset": positions.nbytes, "byteLength": indices.nbytes},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(positions),
                "type": "VEC3",
                "min": list(bounds[0]) if bounds else positions.min(axis=0).tolist(),
                "max": list(bounds[1]) if bounds else positions.max(axis=0).tolist(),
            },
            {"bufferView": 1, "componentType": 5125, "count": len(indices), "type": "SCALAR"},
        ],
    }
    return document, binary


def gltf_text(vertices, triangles) -> bytes:
    """A .gltf with its buffer inline (a data URI)."""
    document, binary = gltf_document(vertices, triangles, uri=None)
    document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
    return json.dumps(document).encode()


def glb(vertices, triangles, bounds=None) -> bytes:
    document, binary = gltf_document(vertices, triangles, uri=None, bounds=bounds)
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks
