"""The quality read-out of a layout on its target, measured without a known answer (no ``bpy``).

Three numbers an artist can read after a snap, projection, wrap or mirror:

- **distance** (per vertex, world units): from the vertex to the closest point of the target surface, by the
  kernel's exact closest-point query (``core.target.CentredMesh``: the target in a frame centred on it, the
  distance in float64; a face-point's search starts from its own triangle);
- **stretch** (per vertex, a ratio): the mean length of the vertex's edges now over their mean length in the
  rest shape (the template as made, ``springwrap_rest``), both in world space. 1 = unchanged, 2 = its edges
  are twice as long, 0.5 = half as long. A vertex without edges, or whose rest edges all have zero length,
  reads 1 (nothing to measure);
- **flipped** (per face): the face is turned over against its rest shape. Its normal (Newell's, so n-gons and
  warped quads have one) points against its rest normal carried by the best rotation of its neighbourhood (its
  corners and their edge neighbours) from the rest shape to now (Horn's, always proper). The rotation is fitted
  locally, so a posed limb or a template turned round is not flipped; a face folded over its neighbours is. A
  degenerate face (zero normal, now or at rest) is not flipped; nothing here produces NaN. (Judging the face against the target's
  smoothed normal instead was measured and rejected: on the benchmark's MakeHuman body it flags 433 faces of the
  *true* layout, in the mouth and eye cavities and wherever the closest target point belongs to another part.)

:func:`summary` turns a :class:`Readout` into the numbers of the command line's report (percentiles, counts;
the batch summary judges them, ``blender_scripts/retarget_batch.py``); :func:`problem_mask` is what
``springwrap.select_problems`` selects; :func:`heat_scale` and :func:`ramp_colours` are the heat-map's colours.
The three measures run in the kernel (``springwrap_kernel.layout_readout`` for the stretch and the flips,
``TargetMesh.surface_distances``: Rust, in parallel); this module prepares their arrays and reads the results.
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import layout_state, transforms

DISTANCE_ATTRIBUTE = "springwrap_distance"
"""POINT FLOAT attribute: distance to the target surface, world units."""
STRETCH_ATTRIBUTE = "springwrap_stretch"
"""POINT FLOAT attribute: mean edge length now / at rest (1 = unchanged)."""
FLIPPED_ATTRIBUTE = "springwrap_flipped"
"""FACE BOOLEAN attribute: the face is turned over against its rest shape."""

OFF_SURFACE_FRACTION = 0.001
"""A vertex is off the surface beyond this fraction of the layout's bounding-box diagonal (0.1 %) unless a
threshold is given."""
ON_SURFACE_FRACTION = 1e-6
"""A face-point this close to its own triangle (a fraction of the target's bounding-box diagonal: about ten times
float32's rounding of its coordinates) is on the surface: its distance is read from that triangle."""
STRETCH_FACTOR = 1.5
"""A vertex is stretched when its stretch is above this factor or below its inverse unless a threshold is given."""

PROBLEM_KINDS = {
    "FLIPPED": ("Flipped", "Faces turned over against the rest shape (folds)"),
    "STRETCHED": ("Stretched", "Vertices whose edges are longer or shorter than at rest by more than the threshold"),
    "OFF_SURFACE": ("Off Surface", "Vertices farther from the target than the threshold"),
}
"""What ``springwrap.select_problems`` selects (faces, vertices, vertices): label and description of each kind."""
HEATMAP_KINDS = {
    "DISTANCE": ("Distance", "Distance to the target surface: blue on it, red at the scale's top"),
    "STRETCH": ("Stretch", "Edge length against the rest shape: blue half as long, green unchanged, red twice"),
    "FLIPPED": ("Flipped", "Faces turned over against the rest shape in red, the others in blue"),
}
"""What the quality heat-map can show: label and description of each kind."""


class Readout(NamedTuple):
    """The read-out of one layout: per-vertex distances and stretch, per-face flips."""

    distances: np.ndarray  # (N,) float64, world units
    stretch: np.ndarray  # (N,) float64, 1 = unchanged
    flipped: np.ndarray  # (F,) bool
    diagonal: float  # the layout's world bounding-box diagonal (the default off-surface threshold's unit)


def vertex_distances(world_points: np.ndarray, mesh, state=None) -> np.ndarray:
    """(N,) float64 distance of each world point to the surface of ``mesh`` (a ``core.target.CentredMesh``).

    The kernel's exact closest point, the distance in float64 between the point and it; a non-finite point
    reads ``inf``. ``state`` (the layout's ``LayoutState``, optional): a face-point within
    :data:`ON_SURFACE_FRACTION` of the target's size of its own triangle reads its distance to that triangle
    (the closest point is no farther, and the two differ by less than that rounding-sized tolerance), without
    a search; the others' searches start from their triangle.
    """
    return mesh.surface_distances(world_points, near=_near_triangles(state), on_surface=_on_surface(mesh))


def _near_triangles(state) -> np.ndarray | None:
    """(N,) uint32 the triangle of each face-point of ``state`` (0xFFFFFFFF: none, no start); None without a
    state."""
    if state is None:
        return None
    faces = np.asarray(state.faces).reshape(-1)
    on_face = (np.asarray(state.states).reshape(-1) == layout_state.FACE_POINT) & (faces >= 0)
    return np.where(on_face, faces, -1).astype(np.int64).astype(np.uint32)  # -1: no start (0xFFFFFFFF)


def _on_surface(mesh) -> float:
    """How near its own triangle a face-point reads its distance from it: :data:`ON_SURFACE_FRACTION` of the
    target's bounding-box diagonal."""
    low, high = mesh.bounding_box()
    return ON_SURFACE_FRACTION * float(np.linalg.norm(high - low))


def vertex_stretch(world_points: np.ndarray, world_rest: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(N,) float64 mean incident edge length now over the same at rest (see the module's docstring)."""
    return springwrap_kernel.vertex_stretch(_points64(world_points), _points64(world_rest), _pairs(edges))


def face_normals(world_points: np.ndarray, face_corners: np.ndarray, face_sizes: np.ndarray) -> np.ndarray:
    """(F, 3) float64 Newell normals (twice the area vector; zero for a degenerate face), each face's corners
    taken relative to its centre (precise far from the origin)."""
    return springwrap_kernel.face_normals(_points64(world_points), _indices(face_corners), _indices(face_sizes))


def flipped_faces(
    world_points: np.ndarray, world_rest: np.ndarray, face_corners: np.ndarray, face_sizes: np.ndarray, edges
) -> np.ndarray:
    """(F,) bool: the face's normal points against its rest normal carried by its neighbourhood's best rotation
    (the kernel's, in parallel)."""
    return springwrap_kernel.flipped_faces(
        _points64(world_points), _points64(world_rest), _indices(face_corners), _indices(face_sizes), _pairs(edges)
    )


def _points64(points) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))


def _indices(values) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values).reshape(-1), dtype=np.uint32)


def _pairs(edges) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(edges).reshape(-1, 2), dtype=np.uint32)


def bounding_diagonal(world_points: np.ndarray) -> float:
    """The diagonal of the finite points' bounding box (0 for none)."""
    world_points = np.asarray(world_points, dtype=np.float64).reshape(-1, 3)
    finite = world_points if np.isfinite(world_points).all() else world_points[np.isfinite(world_points).all(axis=1)]
    return float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0))) if finite.shape[0] else 0.0


def measure(world_points: np.ndarray, world_rest: np.ndarray | None, topology, mesh, state=None) -> Readout:
    """The :class:`Readout` of a layout at ``world_points`` (rest shape ``world_rest``, both (N, 3) world; None:
    no usable rest shape, the stretch reads 1 and no face is flipped) with ``topology`` (a
    ``core.subdivision.LayoutTopology``) on the target ``mesh`` (a ``CentredMesh``). ``state``: the layout's
    face-points at those positions, where the distances' searches start (see :func:`vertex_distances`).

    The stretch, the flips and the layout's size come from one kernel call (``springwrap_kernel.layout_readout``:
    the faces and edges checked once, each vertex's ring measured once), the distances from the target's."""
    world_points = _points64(world_points)
    stretch, flipped, diagonal = springwrap_kernel.layout_readout(
        world_points,
        None if world_rest is None else _points64(world_rest),
        _indices(topology.face_corners),
        _indices(topology.face_sizes),
        _pairs(topology.edges),
    )
    return Readout(
        distances=vertex_distances(world_points, mesh, state),
        stretch=stretch,
        flipped=flipped,
        diagonal=diagonal,
    )


def measure_placed(
    local_positions: np.ndarray, local_rest: np.ndarray | None, matrix_world, topology, mesh, state=None
) -> Readout:
    """The :class:`Readout` of a layout as its object stores it: ``local_positions`` and ``local_rest`` ((N, 3)
    in the object's space, taken as float32 as they are stored; ``local_rest`` None, of another length or not
    finite in the world: no usable rest shape) placed by ``matrix_world`` (4x4; its last row is not used, as
    in :func:`~.transforms.transform_points`), on ``mesh``, with ``topology`` and ``state`` as in
    :func:`measure`.

    The same numbers as :func:`measure` of the world positions and rest shape, in one kernel call
    (``springwrap_kernel.placed_readout``): the world positions, the stretch, the flips, the layout's size and
    the distances computed in parallel in Rust, with no world copies made here."""
    positions = _points32(local_positions)
    rest = None if local_rest is None else _points32(local_rest)
    if rest is not None and rest.shape[0] != positions.shape[0]:
        rest = None
    affine = np.array(matrix_world, dtype=np.float64, order="C").reshape(4, 4)
    affine[3] = (0.0, 0.0, 0.0, 1.0)
    distances, stretch, flipped, diagonal = springwrap_kernel.placed_readout(
        mesh.kernel,
        positions,
        rest,
        affine,
        _indices(topology.face_corners),
        _indices(topology.face_sizes),
        _pairs(topology.edges),
        origin=np.ascontiguousarray(mesh.origin, dtype=np.float64),
        near=_near_triangles(state),
        on_surface=_on_surface(mesh),
    )
    return Readout(distances=distances, stretch=stretch, flipped=flipped, diagonal=diagonal)


def _points32(points) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 3))


def off_surface_threshold(diagonal: float, threshold: float = 0.0) -> float:
    """The off-surface distance: ``threshold`` when above 0, else :data:`OFF_SURFACE_FRACTION` of ``diagonal``."""
    return float(threshold) if threshold > 0.0 else OFF_SURFACE_FRACTION * float(diagonal)


def stretch_factor(threshold: float = 0.0) -> float:
    """The stretch factor judged (at least 1): ``threshold`` when above 0 (its inverse when below 1), else
    :data:`STRETCH_FACTOR`."""
    if not threshold > 0.0:
        return STRETCH_FACTOR
    return float(threshold) if threshold >= 1.0 else 1.0 / float(threshold)


def problem_mask(kind: str, values: np.ndarray, threshold: float, diagonal: float) -> np.ndarray:
    """What ``springwrap.select_problems`` selects: for ``'FLIPPED'`` the faces whose flag is set (``values`` the
    flags; no threshold), for ``'STRETCHED'`` the vertices whose stretch is above the factor or below its
    inverse, for ``'OFF_SURFACE'`` the vertices farther from the target than the distance (see
    :func:`off_surface_threshold`, :func:`stretch_factor`)."""
    values = np.asarray(values)
    if kind == "FLIPPED":
        return values.astype(bool)
    if kind == "STRETCHED":
        factor = stretch_factor(threshold)
        return (values > factor) | (values < 1.0 / factor)
    if kind == "OFF_SURFACE":
        return values > off_surface_threshold(diagonal, threshold)
    raise ValueError(f"unknown problem kind {kind!r}; one of {', '.join(PROBLEM_KINDS)}")


def summary(readout: Readout, threshold: float = 0.0) -> dict:
    """The read-out's numbers for a report: distance mean / p50 / p95 / max, stretch p5 / p50 / p95 / max, the
    flipped faces, the vertices off the surface (beyond :func:`off_surface_threshold`) and that threshold."""
    distances, stretch = readout.distances, readout.stretch
    limit = off_surface_threshold(readout.diagonal, threshold)

    def percentile(values, q):
        return float(np.percentile(values, q)) if values.size else 0.0

    return {
        "vertices": int(distances.size),
        "faces": int(readout.flipped.size),
        "distance_mean": float(distances.mean()) if distances.size else 0.0,
        "distance_p50": percentile(distances, 50),
        "distance_p95": percentile(distances, 95),
        "distance_max": float(distances.max()) if distances.size else 0.0,
        "stretch_p5": percentile(stretch, 5),
        "stretch_p50": percentile(stretch, 50),
        "stretch_p95": percentile(stretch, 95),
        "stretch_max": float(stretch.max()) if stretch.size else 0.0,
        "flipped": int(readout.flipped.sum()),
        "off_surface": int((distances > limit).sum()),
        "off_surface_threshold": limit,
    }


def report_line(readout: Readout) -> str:
    """One line for an operator's report: the read-out in numbers, and where to look."""
    numbers = summary(readout)
    return (
        f"Read-out: distance to the target p95 {numbers['distance_p95']:.3g}, max {numbers['distance_max']:.3g}; "
        f"stretch {numbers['stretch_p5']:.2f} to {numbers['stretch_p95']:.2f} (p5 to p95); "
        f"{numbers['flipped']} faces flipped, {numbers['off_surface']} vertices off the surface "
        "(Check › Heat-Map, Select Problems)"
    )


# ---------------------------------------------------------------- the heat-map's colours

RAMP = np.array([[0.05, 0.2, 1.0], [0.0, 0.85, 1.0], [0.1, 0.9, 0.2], [1.0, 0.9, 0.0], [1.0, 0.1, 0.05]])
"""The heat-map's colour ramp at 0, 1/4, 1/2, 3/4 and 1: blue, cyan, green, yellow, red."""


class HeatScale(NamedTuple):
    """What the heat-map shows: each element's place on the ramp (0 to 1), and its legend."""

    values: np.ndarray  # (N,) per vertex, or (F,) per face, in [0, 1]
    per_face: bool
    title: str
    labels: tuple  # ((place on the ramp, text), ...)


def ramp_colours(places: np.ndarray, alpha: float = 1.0) -> np.ndarray:
    """(N, 4) float32 RGBA of places in [0, 1] on :data:`RAMP` (non-finite places read as the top)."""
    places = np.asarray(places, dtype=np.float64).reshape(-1)
    places = np.clip(np.where(np.isfinite(places), places, 1.0), 0.0, 1.0)
    stops = np.linspace(0.0, 1.0, RAMP.shape[0])
    colours = np.stack([np.interp(places, stops, RAMP[:, channel]) for channel in range(3)], axis=1)
    return np.column_stack([colours, np.full(places.size, alpha)]).astype(np.float32)


def heat_scale(kind: str, readout: Readout) -> HeatScale:
    """The heat-map of ``kind`` (``'DISTANCE'``, ``'STRETCH'``, ``'FLIPPED'``) for a read-out.

    Distance: 0 (blue) to the larger of the 95th percentile and the off-surface distance (red, and anything
    beyond). Stretch: on a log scale from 0.5 (blue) through 1 (green) to 2 (red), the ends clipped.
    Flipped: per face, red turned over, blue not.
    """
    if kind == "DISTANCE":
        distances = readout.distances
        finite = distances[np.isfinite(distances)]
        top = max(float(np.percentile(finite, 95)) if finite.size else 0.0, off_surface_threshold(readout.diagonal))
        top = top if top > 0.0 else 1.0
        labels = ((0.0, "0"), (0.5, f"{top / 2:.3g}"), (1.0, f"{top:.3g}+"))
        return HeatScale(distances / top, False, "Distance to the target", labels)
    if kind == "STRETCH":
        with np.errstate(divide="ignore", invalid="ignore"):
            places = (np.log2(np.maximum(readout.stretch, 1e-12)) + 1.0) / 2.0
        labels = ((0.0, "0.5-"), (0.25, "0.71"), (0.5, "1"), (0.75, "1.41"), (1.0, "2+"))
        return HeatScale(places, False, "Stretch (edge length / rest)", labels)
    if kind == "FLIPPED":
        count = int(readout.flipped.sum())
        labels = ((0.0, "as at rest"), (1.0, f"turned over ({count})"))
        return HeatScale(readout.flipped.astype(np.float64), True, "Flipped faces (against the rest shape)", labels)
    raise ValueError(f"unknown heat-map kind {kind!r}")


def world_rest_or_none(matrix_world: np.ndarray, rest_local: np.ndarray | None, vertex_count: int):
    """The rest shape in world space (float64), or None when it cannot be used (missing, another length, not
    finite): the stretch then reads 1."""
    if rest_local is None:
        return None
    rest = np.asarray(rest_local, dtype=np.float64).reshape(-1, 3)
    if rest.shape[0] != vertex_count:
        return None
    world = transforms.transform_points(matrix_world, rest)
    return world if np.all(np.isfinite(world)) else None
