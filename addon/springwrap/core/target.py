"""The target mesh as the operations see it, and the deleted-face rule applied through it (no ``bpy``).

``blender.target`` builds a :class:`Target` from the evaluated target object; everything here works
on it with the kernel's queries.

**Precision far from the origin.** The kernel works in float32. A target 1e6 from the world origin
has float32 coordinates 0.06 apart, so the kernel's answers there would be off by centimetres
whatever the mesh's own size. :class:`CentredMesh` therefore hands the kernel the target relative
to the centre of its bounding box (subtracted in float64), and every query point likewise; the
answers come back in world space as float64. An object's distance from the origin then does not
change the result beyond what the float32 storage of the final coordinates allows.
"""

from typing import NamedTuple

import numpy as np

import springwrap_kernel

from . import input_policy, layout_state, transforms
from .layout_state import LayoutArrays, LayoutState


def frame_origin(world_vertices: np.ndarray) -> np.ndarray:
    """(3,) float64 origin of the kernel's frame for a target: the centre of its bounding box, rounded to
    a multiple of the largest power of two not above the box's diagonal.

    The rounding keeps the frame where it is while the target is edited a little, keeps a target that
    is symmetric about a world plane through the origin symmetric in the kernel's float32 coordinates
    (its centre, 1e-9 off the plane, rounds onto it), and still leaves every vertex within about a
    diagonal of the origin. Zero for an empty or non-finite mesh (the kernel refuses those and names why).
    """
    world_vertices = np.asarray(world_vertices, dtype=np.float64).reshape(-1, 3)
    if not world_vertices.shape[0] or not np.all(np.isfinite(world_vertices)):
        return np.zeros(3)
    low, high = world_vertices.min(axis=0), world_vertices.max(axis=0)
    diagonal = float(np.linalg.norm(high - low))
    if not diagonal > 0.0:
        return np.zeros(3)
    step = 2.0 ** np.floor(np.log2(diagonal))
    return np.round(0.5 * (low + high) / step) * step


def kernel_coordinates(points: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """(N, 3) float32 coordinates of world points in the kernel's frame at ``origin`` (subtracted in float64)."""
    return transforms.as_float32_points(np.asarray(points, dtype=np.float64).reshape(-1, 3) - origin)


class CentredMesh:
    """A kernel ``TargetMesh`` built in a frame centred on the target, queried in world coordinates.

    ``kernel`` is the kernel's mesh, its coordinates world minus :attr:`origin`; the query methods
    take world points (any float dtype; float64 keeps the precision) and return the kernel's hits
    with their positions in world space (float64). :meth:`to_kernel` / :meth:`from_kernel` convert
    for the calls that use the kernel directly (the wrap's solver).
    """

    def __init__(self, world_vertices: np.ndarray, triangles: np.ndarray, origin: np.ndarray | None = None):
        """``origin`` given: ``world_vertices`` are already the kernel's coordinates in the frame at ``origin``
        (:func:`kernel_coordinates`), so that a caller need not hold float64 vertices while the kernel builds."""
        if origin is None:
            self.origin = frame_origin(world_vertices)
            self.kernel = springwrap_kernel.TargetMesh(self.to_kernel(world_vertices), triangles)
        else:
            self.origin = np.asarray(origin, dtype=np.float64)
            self.kernel = springwrap_kernel.TargetMesh(world_vertices, triangles)

    def to_kernel(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) float32 kernel coordinates of world points."""
        return kernel_coordinates(points, self.origin)

    def from_kernel(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) float64 world coordinates of kernel points."""
        return np.asarray(points, dtype=np.float64).reshape(-1, 3) + self.origin

    def matrix_to_kernel(self, matrix: np.ndarray) -> np.ndarray:
        """A world-space 4x4 affine map as the same map on kernel coordinates."""
        shift = np.eye(4)
        shift[:3, 3] = self.origin
        return np.linalg.inv(shift) @ np.asarray(matrix, dtype=np.float64).reshape(4, 4) @ shift

    def matrix_from_kernel(self, matrix: np.ndarray) -> np.ndarray:
        """A 4x4 affine map on kernel coordinates as the same map in world space."""
        shift = np.eye(4)
        shift[:3, 3] = self.origin
        return shift @ np.asarray(matrix, dtype=np.float64).reshape(4, 4) @ np.linalg.inv(shift)

    @property
    def vertex_count(self) -> int:
        return self.kernel.vertex_count

    @property
    def triangle_count(self) -> int:
        return self.kernel.triangle_count

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners in world space, float64."""
        low, high = self.kernel.bounding_box()
        return self.from_kernel(low)[0], self.from_kernel(high)[0]

    def vertices(self) -> np.ndarray:
        """(V, 3) float64 world vertices (as the kernel holds them)."""
        return self.from_kernel(self.kernel.vertices())

    def triangles(self) -> np.ndarray:
        return self.kernel.triangles()

    def closest_points(self, points, **options):
        """The kernel's ``closest_points`` at world points; positions in world space. The last query without
        options is remembered: asked again at the very same points (a sequence's frame measures the layout, then
        resolves its face-points there), its answer is given again without searching."""
        kernel_points = self.to_kernel(points)
        remembered = getattr(self, "_last_closest", None)
        if not options and remembered is not None and np.array_equal(remembered[0], kernel_points):
            return remembered[1]._replace(**{name: value.copy() for name, value in remembered[1]._asdict().items()})
        hits = self.kernel.closest_points(kernel_points, **options)
        hits = hits._replace(positions=self.from_kernel(hits.positions))
        if not options:
            self._last_closest = (kernel_points, hits)
        return hits

    def surface_distances(self, points, near=None, on_surface: float = 0.0) -> np.ndarray:
        """(N,) float64 distance of each world point to the surface (the kernel's ``surface_distances``: the
        point taken in float64 in the kernel's frame); ``near``: the triangle each point lies on, if known."""
        kernel_points = transforms.add_offset(points, -self.origin)
        return self.kernel.surface_distances(kernel_points, near=near, on_surface=on_surface)

    def nearest_vertices(self, points, **options):
        """The kernel's ``nearest_vertices`` at world points; positions in world space."""
        hits = self.kernel.nearest_vertices(self.to_kernel(points), **options)
        return hits._replace(positions=self.from_kernel(hits.positions))

    def ray_cast(self, origins, directions, **options):
        """The kernel's ``ray_cast`` from world origins; positions in world space."""
        hits = self.kernel.ray_cast(self.to_kernel(origins), transforms.as_float32_points(directions), **options)
        return hits._replace(positions=self.from_kernel(hits.positions))

    def face_point_positions(self, triangles, barycentrics) -> np.ndarray:
        """(K, 3) float64 world positions of face-points."""
        return self.from_kernel(self.kernel.face_point_positions(triangles, barycentrics))

    def icp(self, source, initial=None, **options):
        """The kernel's ``icp`` of world points from a world-space ``initial``; the report's matrix in world space."""
        for name in ("anchor_source", "anchor_target"):
            if options.get(name) is not None:
                options[name] = self.to_kernel(options[name])
        start = np.eye(4) if initial is None else initial
        report = self.kernel.icp(self.to_kernel(source), np.ascontiguousarray(self.matrix_to_kernel(start)), **options)
        return report._replace(matrix=self.matrix_from_kernel(report.matrix))


class Target(NamedTuple):
    """A target mesh prepared for queries, in world space."""

    name: str  # the target object's name
    mesh: CentredMesh  # the kernel's mesh, queried in world coordinates
    triangle_polygons: np.ndarray  # (M,) int32, the polygon of each loop triangle
    signature: str  # topology signature, see layout_state.target_signature
    reattach_tolerance: float  # see layout_state.reattach_tolerance

    @property
    def extent(self) -> input_policy.Extent:
        """Where the target is, for :mod:`.input_policy`."""
        low, high = self.mesh.bounding_box()
        return input_policy.extent_of(self.name, low, high)


def make_target(
    name: str, world_vertices: np.ndarray, triangles: np.ndarray, triangle_polygons=None, origin=None
) -> Target:
    """A :class:`Target` from world vertices and triangles (the kernel's errors raised as they are); with
    ``origin``, the vertices are the kernel's coordinates in that frame (see :class:`CentredMesh`)."""
    triangles = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
    mesh = CentredMesh(world_vertices, triangles, origin)
    low, high = mesh.bounding_box()
    if triangle_polygons is None:
        triangle_polygons = np.arange(triangles.shape[0], dtype=np.int32)
    return Target(
        name=name,
        mesh=mesh,
        triangle_polygons=triangle_polygons,
        signature=layout_state.target_signature(triangles, mesh.vertex_count),
        reattach_tolerance=layout_state.reattach_tolerance(low, high),
    )


def resolve_topology(layout: LayoutArrays, target: Target, stored_signature: str) -> layout_state.Resolution:
    """Re-attach or detach the face-points whose face may be gone (paper section 2.1).

    Applies to the whole layout, whatever the selection: when the target's topology changed
    since the face-points were written (or a face index is out of range), each face-point is
    looked up on the current surface at its current position.
    """
    mask = layout_state.face_points_to_resolve(
        layout.state, target.mesh.triangle_count, stored_signature, target.signature
    )
    if not mask.any():
        return layout_state.Resolution(layout.state, 0, 0)
    layout_state.check_finite(layout, mask)
    world = transforms.world_positions(layout)
    if 2 * int(mask.sum()) < mask.size or not np.isfinite(world).all():
        return resolve_points(layout.state, mask, world[mask], target)
    # Most of the layout: asked at every vertex, the query a sequence's later frame has just made to see where
    # the target changed (``CentredMesh.closest_points`` answers it again without searching).
    hits = target.mesh.closest_points(world)
    return layout_state.resolve_face_points(
        layout.state,
        mask,
        hits.triangles[mask],
        hits.barycentrics[mask],
        hits.distances[mask],
        target.reattach_tolerance,
    )


def resolve_points(
    state: LayoutState, mask: np.ndarray, world_points: np.ndarray, target: Target
) -> layout_state.Resolution:
    """The deleted-face rule for the face-points in ``mask``, looked up at ``world_points`` (mask order).

    Each is found again on the current target surface (the exact closest point): within the
    target's re-attach tolerance it re-attaches there, otherwise it becomes a space-point. Used
    for layout vertices (at their positions) and for anchors (at their cached target points).
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return layout_state.Resolution(state, 0, 0)
    hits = target.mesh.closest_points(world_points)
    return layout_state.resolve_face_points(
        state, mask, hits.triangles, hits.barycentrics, hits.distances, target.reattach_tolerance
    )
