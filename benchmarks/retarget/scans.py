"""Scanned surfaces without a known answer: a quad template wrapped onto a real range scan with holes.

The body cases (:mod:`cases`) know where every layout vertex belongs; a scan does not. These cases
measure what can be measured without a truth (:func:`metrics.scan_metrics`): how far the layout
ends from the scan where the scan has surface, how many quads turned over, how much the quads
were stretched.

Every case holds

- the **target**: a real scan with holes, triangulated (``target_vertices``, ``target_triangles``);
- the **template**: a quad layout of the same object that is *not* on the scan
  (``template_vertices``, ``template_quads``), made deterministically, headless under ``bpy``:

  1. a closed version of the object (:attr:`ScanSpec.closed`): the scan with its holes filled by
     ``bmesh.ops.holes_fill`` (``"filled"``), or a closed mesh shipped beside it;
  2. Blender's Remesh modifier in ``VOXEL`` mode (adaptivity 0) on it, a voxel of
     :attr:`ScanSpec.voxel_fraction` of the scan's bounding-box diagonal: an all-quad, manifold,
     closed mesh (only its largest connected piece is kept). The octree modes (``SMOOTH``,
     ``SHARP``) also give quads, but leave non-manifold edges on these two meshes;
  3. moved off the scan: :attr:`ScanSpec.smooth_iterations` umbrella smoothing steps (factor
     :data:`SMOOTH_FACTOR`: thin parts such as ears shrink), then every vertex pushed along its
     normal by :attr:`ScanSpec.inflate_fraction` of the diagonal;
  4. placed elsewhere (:data:`PLACEMENT`: turned, shifted), so that it must be aligned;

- the **anchors**: ``anchor_count`` template vertices spread by farthest-point sampling among those
  whose remeshed (unmoved) position lies over the scan's surface, each paired with the scan point
  closest to that position (where a user would click). The benchmark aligns the template to them
  (a similarity) and wraps with them as anchors.

Sources (fetched by :mod:`data`, never committed): the range-scanned Stanford bunny of the PyPI
``pymeshlab`` wheel (``bunny10k_textured.obj``: 10k triangles, five holes under it), CGAL's
elephant with holes (Debian ``libcgal-demo``: ``elephant-with-holes.off``, 88 holes, and
``elephant.off``, the same elephant closed). Cases are cached as ``.npz`` under ``<cache>/cases/``,
keyed by the spec and the source files' contents.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.retarget import cases, data, landmarks, metrics

# Bump when the way scan cases are built changes: cached ones are then rebuilt.
SCAN_FORMAT_VERSION = 1
SMOOTH_FACTOR = 0.5
# Where the template is put before the alignment: turned about +Y, shifted by fractions of the
# scan's diagonal (the scan stays where its file has it).
PLACEMENT = {"rotation_degrees": 20.0, "scale": 1.0, "translation_fractions": (0.15, -0.05, 0.1)}
ANCHOR_COUNT = 24


@dataclass(frozen=True)
class ScanSpec:
    """Everything that defines a scan case; its hash (with the sources' contents) names the cached file."""

    name: str
    source: str  # "pymeshlab" (a sample mesh of the wheel) or "cgal" (a file of CGAL's data)
    target: str  # the scan with holes: a file name (pymeshlab) or a data member (cgal)
    closed: str  # "filled" (the scan, holes filled) or a closed mesh of the same source
    voxel_fraction: float  # the template's voxel, as a fraction of the scan's bounding-box diagonal
    smooth_iterations: int = 10
    inflate_fraction: float = 0.03  # pushed along the normals by this fraction of the diagonal
    description: str = ""

    def source_file(self, member: str, cache: Path | None = None) -> Path:
        """A source file of this case, fetched (and unpacked) into the cache when needed."""
        if self.source == "pymeshlab":
            return data.pymeshlab_file(member, cache)
        if self.source == "cgal":
            return data.cgal_data_file(member, cache)
        raise ValueError(f"unknown scan source {self.source!r}")

    def key(self, cache: Path | None = None) -> str:
        """A short hash of the spec, the constants and the contents of the source files."""
        members = [self.target] + ([] if self.closed == "filled" else [self.closed])
        contents = [hashlib.sha256(self.source_file(member, cache).read_bytes()).hexdigest() for member in members]
        payload = {
            "spec": asdict(self) | {"description": ""},
            "format": SCAN_FORMAT_VERSION,
            "smooth_factor": SMOOTH_FACTOR,
            "placement": PLACEMENT,
            "anchors": ANCHOR_COUNT,
            "sources": contents,
        }
        return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:12]


SCAN_CASES: tuple[ScanSpec, ...] = (
    ScanSpec(
        "bunny-scan",
        "pymeshlab",
        "bunny10k_textured.obj",
        "filled",
        voxel_fraction=1.0 / 60.0,
        description="range-scanned Stanford bunny (pymeshlab's bunny10k_textured.obj: 10k triangles, "
        "5 holes); template: the scan with its holes filled, voxel-remeshed",
    ),
    ScanSpec(
        "elephant-holes",
        "cgal",
        "data/meshes/elephant-with-holes.off",
        "data/meshes/elephant.off",
        voxel_fraction=1.0 / 80.0,
        description="CGAL's elephant with holes (4.5k triangles, 88 holes); template: CGAL's closed "
        "elephant.off, voxel-remeshed",
    ),
)


def scan_specs(names: list[str] | None = None) -> list[ScanSpec]:
    """The scan specs named (in that order), else all of them."""
    by_name = {spec.name: spec for spec in SCAN_CASES}
    if names:
        unknown = [name for name in names if name not in by_name]
        if unknown:
            raise KeyError(f"unknown scan case(s) {unknown}; known: {', '.join(by_name)}")
        return [by_name[name] for name in names]
    return list(SCAN_CASES)


@dataclass
class ScanCase:
    """A built scan case (see the module docstring)."""

    spec: ScanSpec
    template_vertices: np.ndarray  # (N, 3) float64, moved off the scan and placed elsewhere
    template_quads: np.ndarray  # (F, 4) int64
    target_vertices: np.ndarray  # (V, 3) float32
    target_triangles: np.ndarray  # (T, 3) uint32
    anchor_vertices: np.ndarray  # (K,) int64 template vertices
    anchor_positions: np.ndarray  # (K, 3) float64 points on the scan
    info: dict = field(default_factory=dict)

    @property
    def diagonal(self) -> float:
        """The scan's bounding-box diagonal (the unit of the relative metrics)."""
        return cases.bounding_box_diagonal(np.asarray(self.target_vertices, dtype=np.float64))


# ---------------------------------------------------------------- geometry (numpy)


def triangulated(mesh: data.PolygonMesh) -> np.ndarray:
    """(T, 3) int64 triangles of a polygon mesh, each polygon cut into a fan from its first corner."""
    starts = np.concatenate([[0], np.cumsum(mesh.face_sizes)[:-1]])
    rows = []
    for size in np.unique(mesh.face_sizes):
        first = starts[mesh.face_sizes == size]
        for offset in range(1, size - 1):
            rows.append(np.stack([first, first + offset, first + offset + 1], axis=1))
    order = np.concatenate(rows)
    order = order[np.lexsort((order[:, 1], order[:, 0]))]  # polygon order, then fan order
    return mesh.face_corners[order]


def polygon_edges(faces: np.ndarray) -> np.ndarray:
    """(E, 2) int64 unique undirected edges (smaller index first) of (F, k) polygons of one size."""
    faces = np.asarray(faces, dtype=np.int64)
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(pairs, axis=1), axis=0)


def connected_labels(vertex_count: int, edges: np.ndarray) -> np.ndarray:
    """(vertex_count,) the smallest vertex index of each vertex's edge-connected piece (label
    propagation with pointer jumping, numpy only)."""
    labels = np.arange(vertex_count)
    first, second = edges[:, 0], edges[:, 1]
    while True:
        lower = np.minimum(labels[first], labels[second])
        lowered = labels.copy()
        np.minimum.at(lowered, first, lower)
        np.minimum.at(lowered, second, lower)
        lowered = lowered[lowered]  # a label is a smaller vertex of the same piece: follow it
        if np.array_equal(lowered, labels):
            return labels
        labels = lowered


def largest_piece(vertices: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The quads of the largest edge-connected piece (by vertex count), renumbered, and its vertices."""
    labels = connected_labels(len(vertices), polygon_edges(quads))
    used = np.unique(quads)
    biggest = np.bincount(labels[used]).argmax()
    kept_quads = quads[labels[quads[:, 0]] == biggest]
    kept = np.unique(kept_quads)
    renumber = np.full(len(vertices), -1, dtype=np.int64)
    renumber[kept] = np.arange(len(kept))
    return vertices[kept], renumber[kept_quads]


def vertex_normals(vertices: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(N, 3) unit vertex normals: the area-weighted sum of the quads' normals (diagonal cross products)."""
    normals = np.zeros_like(vertices, dtype=np.float64)
    corners = vertices[quads]
    face_normals = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    for corner in range(quads.shape[1]):
        np.add.at(normals, quads[:, corner], face_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.where(length > 0.0, length, 1.0)


def umbrella_smoothed(vertices: np.ndarray, quads: np.ndarray, iterations: int, factor: float) -> np.ndarray:
    """``iterations`` steps of ``x += factor * (mean of the edge neighbours - x)``."""
    edges = polygon_edges(quads)
    degree = np.bincount(edges.ravel(), minlength=len(vertices)).astype(np.float64)[:, None]
    result = np.asarray(vertices, dtype=np.float64).copy()
    for _ in range(iterations):
        sums = np.zeros_like(result)
        np.add.at(sums, edges[:, 0], result[edges[:, 1]])
        np.add.at(sums, edges[:, 1], result[edges[:, 0]])
        result += factor * (sums / np.maximum(degree, 1.0) - result)
    return result


def boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """(B, 2) int64 edges (smaller index first) used by one triangle only: the rims of the holes."""
    pairs = np.sort(np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    edges, counts = np.unique(pairs.astype(np.int64), axis=0, return_counts=True)
    return edges[counts == 1]


# ---------------------------------------------------------------- Blender


def _blender_mesh(name: str, vertices: np.ndarray, mesh: data.PolygonMesh):
    import bpy

    result = bpy.data.meshes.new(name)
    result.vertices.add(len(vertices))
    result.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    result.loops.add(len(mesh.face_corners))
    result.loops.foreach_set("vertex_index", np.ascontiguousarray(mesh.face_corners, dtype=np.int32))
    result.polygons.add(len(mesh.face_sizes))
    starts = np.concatenate([[0], np.cumsum(mesh.face_sizes)[:-1]])
    result.polygons.foreach_set("loop_start", starts.astype(np.int32))
    result.update(calc_edges=True)
    return result


def filled_holes(mesh: data.PolygonMesh) -> data.PolygonMesh:
    """The mesh with every hole closed by one polygon (``bmesh.ops.holes_fill``, headless)."""
    import bpy

    import bmesh

    blender_mesh = _blender_mesh("springwrap_bench_fill", mesh.vertices, mesh)
    try:
        editable = bmesh.new()
        editable.from_mesh(blender_mesh)
        bmesh.ops.holes_fill(editable, edges=editable.edges[:], sides=0)
        editable.to_mesh(blender_mesh)
        editable.free()
        vertices = np.empty(len(blender_mesh.vertices) * 3, dtype=np.float32)
        blender_mesh.vertices.foreach_get("co", vertices)
        sizes = np.empty(len(blender_mesh.polygons), dtype=np.int32)
        blender_mesh.polygons.foreach_get("loop_total", sizes)
        corners = np.empty(len(blender_mesh.loops), dtype=np.int32)
        blender_mesh.loops.foreach_get("vertex_index", corners)
    finally:
        bpy.data.meshes.remove(blender_mesh)
    return data.PolygonMesh(
        vertices.reshape(-1, 3).astype(np.float64), corners.astype(np.int64), sizes.astype(np.int64)
    )


def voxel_quads(mesh: data.PolygonMesh, voxel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Blender's Remesh modifier (VOXEL, adaptivity 0) on a closed polygon mesh: (N, 3) float64, (F, 4) int64."""
    blender_mesh = _blender_mesh("springwrap_bench_voxels", mesh.vertices, mesh)
    with cases.voxel_remeshed(blender_mesh, voxel_size) as result:
        positions = np.empty(len(result.vertices) * 3, dtype=np.float32)
        result.vertices.foreach_get("co", positions)
        sizes = np.empty(len(result.polygons), dtype=np.int32)
        result.polygons.foreach_get("loop_total", sizes)
        corners = np.empty(len(result.loops), dtype=np.int32)
        result.loops.foreach_get("vertex_index", corners)
    if len(sizes) == 0 or np.any(sizes != 4):
        raise RuntimeError(f"the voxel remesh (voxel {voxel_size}) gave {len(sizes)} faces, not all quads")
    return positions.reshape(-1, 3).astype(np.float64), corners.reshape(-1, 4).astype(np.int64)


# ---------------------------------------------------------------- building


def read_mesh(path: Path) -> data.PolygonMesh:
    """An OBJ or OFF file, compacted (vertices no face uses are dropped)."""
    mesh = data.read_off(path) if path.suffix.lower() == ".off" else data.read_obj(path)
    return mesh.compacted()[0]


def build_scan(spec: ScanSpec, cache: Path | None = None) -> ScanCase:
    """Build a scan case from its sources (fetched when needed; the remesh needs ``bpy``)."""
    import springwrap_kernel

    start = time.perf_counter()
    scan = read_mesh(spec.source_file(spec.target, cache))
    triangles = triangulated(scan)
    target_vertices = scan.vertices.astype(np.float32)
    target_triangles = triangles.astype(np.uint32)
    diagonal = cases.bounding_box_diagonal(scan.vertices)
    closed = filled_holes(scan) if spec.closed == "filled" else read_mesh(spec.source_file(spec.closed, cache))
    remeshed, quads = voxel_quads(closed, spec.voxel_fraction * diagonal)
    remeshed, quads = largest_piece(remeshed, quads)
    moved = umbrella_smoothed(remeshed, quads, spec.smooth_iterations, SMOOTH_FACTOR)
    moved = moved + spec.inflate_fraction * diagonal * vertex_normals(moved, quads)
    placement = cases.similarity_matrix(
        PLACEMENT["rotation_degrees"],
        PLACEMENT["scale"],
        tuple(fraction * diagonal for fraction in PLACEMENT["translation_fractions"]),
    )
    centre = scan.vertices.mean(axis=0)
    template = cases.transform_points(placement, moved - centre) + centre
    # Anchors: farthest-point samples among the remeshed vertices over the scan's surface, paired
    # with the scan point closest to their remeshed (unmoved) position.
    target = springwrap_kernel.TargetMesh(target_vertices, target_triangles)
    hits = target.closest_points(np.ascontiguousarray(remeshed, dtype=np.float32))
    over_surface = ~metrics.on_boundary(target_triangles, hits.triangles, hits.barycentrics)
    eligible = np.flatnonzero(over_surface)
    picked = landmarks.farthest_point_landmarks(remeshed[eligible], ANCHOR_COUNT).vertices
    anchor_vertices = eligible[picked]
    anchor_positions = np.asarray(hits.positions, dtype=np.float64)[anchor_vertices]
    normals = metrics.triangle_normals(target_vertices, target_triangles)
    info = {
        "target": f"{spec.source}: {spec.target}",
        "target_vertices": len(target_vertices),
        "target_triangles": len(target_triangles),
        "target_boundary_edges": int(len(boundary_edges(target_triangles))),
        "template_from": f"{spec.source}: {spec.closed}",
        "voxel_size": spec.voxel_fraction * diagonal,
        "template_vertices": len(template),
        "template_quads": len(quads),
        "remeshed_to_scan_mean_percent": float(np.asarray(hits.distances)[over_surface].mean() * 100.0 / diagonal),
        "moved_to_scan_mean_percent": float(
            metrics.surface_distances(moved, target)[over_surface].mean() * 100.0 / diagonal
        ),
        # Positive: the scan's triangles face outwards (as the remeshed template's quads do).
        "target_signed_volume": float(
            np.einsum("ij,ij->i", target_vertices[target_triangles[:, 0]].astype(np.float64), normals).sum() / 6.0
        ),
        "build_seconds": time.perf_counter() - start,
    }
    return ScanCase(
        spec,
        template,
        quads,
        target_vertices,
        target_triangles,
        anchor_vertices.astype(np.int64),
        anchor_positions,
        info,
    )


# ---------------------------------------------------------------- cache


def scan_path(spec: ScanSpec, cache: Path | None = None) -> Path:
    """Where the scan case is cached."""
    return (cache or data.cache_folder()) / "cases" / f"{spec.name}-{spec.key(cache)}.npz"


def save_scan(case: ScanCase, path: Path) -> None:
    """Store a scan case as .npz (arrays, plus the spec and info as JSON), atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial.npz")
    np.savez_compressed(
        partial,
        template_vertices=case.template_vertices,
        template_quads=case.template_quads,
        target_vertices=case.target_vertices,
        target_triangles=case.target_triangles,
        anchor_vertices=case.anchor_vertices,
        anchor_positions=case.anchor_positions,
        meta=np.array(json.dumps({"spec": asdict(case.spec), "info": case.info})),
    )
    partial.replace(path)


def load_scan(path: Path) -> ScanCase:
    """Read a scan case written by :func:`save_scan`."""
    with np.load(path) as stored:
        meta = json.loads(str(stored["meta"]))
        return ScanCase(
            ScanSpec(**meta["spec"]),
            stored["template_vertices"],
            stored["template_quads"],
            stored["target_vertices"],
            stored["target_triangles"],
            stored["anchor_vertices"],
            stored["anchor_positions"],
            meta["info"],
        )


def get_scan(spec: ScanSpec, cache: Path | None = None) -> tuple[ScanCase, bool]:
    """The scan case from the cache, built and cached when missing; and whether it came from the cache."""
    path = scan_path(spec, cache)
    if path.is_file():
        return load_scan(path), True
    case = build_scan(spec, cache)
    save_scan(case, path)
    return case, False
