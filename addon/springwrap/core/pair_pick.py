"""What the pair tool's mouse is over, on arrays (numpy and the kernel, no ``bpy``).

The 3D view is given as its perspective matrix (``RegionView3D.perspective_matrix``: world to clip space, a
perspective or an orthographic view alike) and its region's size in pixels; the mouse as region pixels from the
bottom left, as Blender's events count them.

- :func:`project`: world points to region pixels (and whether they are in front of the view);
- :func:`mouse_ray`: the world ray under a pixel;
- :func:`pick_vertex`: the layout vertex a click takes: the nearest to the mouse *on the screen* within a pixel
  radius, among those the layout's own surface does not hide (not the nearest in 3D);
- :func:`pick_end`: the anchor end (layout or target) under the mouse;
- :func:`point_at_depth`: the point of the mouse ray as deep in the view as a reference point (a space anchor
  placed "where the layout vertex is").
"""

from typing import NamedTuple

import numpy as np

PICK_RADIUS = 12.0
"""Pixels around the mouse in which a layout vertex or an anchor end is taken."""
OCCLUSION_TOLERANCE = 1e-3
"""A vertex counts as hidden when the layout's surface lies in front of it by more than this fraction of the
layout's bounding-box diagonal (the vertex's own faces are on the surface, at its depth)."""

LAYOUT_END = "LAYOUT"
"""The anchor's end on the layout vertex."""
TARGET_END = "TARGET"
"""The anchor's end on its target point."""


class View(NamedTuple):
    """A 3D view's region as the picking sees it."""

    perspective_matrix: np.ndarray  # (4, 4) float64 world -> clip space
    width: int  # region width in pixels
    height: int  # region height in pixels


def make_view(perspective_matrix, width, height) -> View:
    """A :class:`View` with a checked matrix (4x4, finite, invertible) and a region of at least a pixel."""
    matrix = np.asarray(perspective_matrix, dtype=np.float64).reshape(4, 4)
    if not np.all(np.isfinite(matrix)) or abs(np.linalg.det(matrix)) < 1e-300:
        raise ValueError("the view's perspective matrix is not finite and invertible")
    return View(matrix, max(int(width), 1), max(int(height), 1))


def project(view: View, points) -> tuple[np.ndarray, np.ndarray]:
    """``(pixels (N, 2) float64, in_front (N,) bool)``: region pixels of world points, and whether each is in
    front of the view (inside its near and far planes); pixels of points behind it are NaN."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    clip = points @ view.perspective_matrix[:3, :3].T + view.perspective_matrix[:3, 3]
    w = points @ view.perspective_matrix[3, :3] + view.perspective_matrix[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = clip / w[:, None]
    in_front = (w > 0.0) & np.all(np.isfinite(ndc), axis=1) & (np.abs(ndc[:, 2]) <= 1.0)
    pixels = np.empty((points.shape[0], 2), dtype=np.float64)
    pixels[:, 0] = (ndc[:, 0] + 1.0) * 0.5 * view.width
    pixels[:, 1] = (ndc[:, 1] + 1.0) * 0.5 * view.height
    pixels[~in_front] = np.nan
    return pixels, in_front


def mouse_rays(view: View, pixels) -> tuple[np.ndarray, np.ndarray]:
    """``(origins (N, 3), directions (N, 3) unit)``: the world rays under region ``pixels`` (N, 2), from the view's
    near plane into the scene."""
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    clip = np.ones((pixels.shape[0], 4))
    clip[:, 0] = 2.0 * pixels[:, 0] / view.width - 1.0
    clip[:, 1] = 2.0 * pixels[:, 1] / view.height - 1.0
    inverse = np.linalg.inv(view.perspective_matrix)
    ends = []
    for depth in (-1.0, 1.0):
        clip[:, 2] = depth
        points = clip @ inverse.T
        ends.append(points[:, :3] / points[:, 3:4])
    directions = ends[1] - ends[0]
    return ends[0], directions / np.linalg.norm(directions, axis=1)[:, None]


def mouse_ray(view: View, mouse) -> tuple[np.ndarray, np.ndarray]:
    """``(origin (3,), direction (3,) unit)``: the world ray under the region pixel ``mouse``."""
    origins, directions = mouse_rays(view, mouse)
    return origins[0], directions[0]


def view_forward(view: View) -> np.ndarray:
    """(3,) unit world direction the view looks along (the ray through the region's centre)."""
    return mouse_ray(view, (0.5 * view.width, 0.5 * view.height))[1]


def within_radius(pixels: np.ndarray, mouse, radius: float) -> np.ndarray:
    """Indices of the finite ``pixels`` within ``radius`` of ``mouse``, nearest first (ties: lower index first)."""
    offsets = np.asarray(pixels, dtype=np.float64).reshape(-1, 2) - np.asarray(mouse, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        distances = np.hypot(offsets[:, 0], offsets[:, 1])
    close = np.flatnonzero(np.isfinite(distances) & (distances <= radius))
    return close[np.argsort(distances[close], kind="stable")]


def visible(view: View, points: np.ndarray, occluder, tolerance: float) -> np.ndarray:
    """(N,) bool: the world ``points`` that no surface of ``occluder`` (a ``core.target.CentredMesh``, or None:
    nothing hides anything) lies in front of by more than ``tolerance`` (world units)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if occluder is None or not points.shape[0]:
        return np.ones(points.shape[0], dtype=bool)
    origins, _directions = mouse_rays(view, project(view, points)[0])
    directions = points - origins
    lengths = np.linalg.norm(directions, axis=1)
    directions /= np.where(lengths > 0.0, lengths, 1.0)[:, None]
    hits = occluder.ray_cast(origins, directions)
    distances = np.asarray(hits.distances, dtype=np.float64)
    missed = np.asarray(hits.triangles) < 0
    return missed | (distances >= lengths - tolerance)


def pick_vertex(view: View, world_points, mouse, radius: float = PICK_RADIUS, occluder=None, tolerance=0.0) -> int:
    """The layout vertex a click at ``mouse`` takes: of the vertices whose projection lies within ``radius``
    pixels, the nearest on the screen that ``occluder`` (the layout's own surface; None: none) does not hide;
    -1 when there is none."""
    pixels, _in_front = project(view, world_points)
    candidates = within_radius(pixels, mouse, radius)
    if not candidates.size:
        return -1
    shown = visible(view, np.asarray(world_points, dtype=np.float64).reshape(-1, 3)[candidates], occluder, tolerance)
    return int(candidates[shown][0]) if shown.any() else -1


def pick_end(view: View, layout_points, target_points, mouse, radius: float = PICK_RADIUS) -> tuple[int, str]:
    """The anchor end under ``mouse``: ``(anchor index, LAYOUT_END or TARGET_END)``, the nearest on the screen
    within ``radius`` pixels (a target end wins a tie: it is the one dragged along the surface); ``(-1, "")``
    when none is. ``layout_points`` and ``target_points``: (K, 3) world positions of the anchors' two ends
    (NaN rows are never picked)."""
    layout_pixels, _ = project(view, layout_points)
    target_pixels, _ = project(view, target_points)
    count = layout_pixels.shape[0]
    both = np.concatenate([target_pixels, layout_pixels])
    nearest = within_radius(both, mouse, radius)
    if not nearest.size:
        return -1, ""
    first = int(nearest[0])
    return (first, TARGET_END) if first < count else (first - count, LAYOUT_END)


def point_at_depth(origin, direction, reference, forward) -> np.ndarray:
    """(3,) the point of the ray ``origin + t * direction`` at the depth of ``reference`` along the view's
    ``forward`` direction (in the plane facing the view through ``reference``)."""
    origin, direction = np.asarray(origin, np.float64), np.asarray(direction, np.float64)
    reference, forward = np.asarray(reference, np.float64), np.asarray(forward, np.float64)
    along = float(direction @ forward)
    if abs(along) < 1e-12:
        raise ValueError("the mouse ray runs parallel to the view plane")
    return origin + direction * (float((reference - origin) @ forward) / along)


def occlusion_tolerance(world_points) -> float:
    """:data:`OCCLUSION_TOLERANCE` of the bounding-box diagonal of the finite ``world_points``."""
    points = np.asarray(world_points, dtype=np.float64).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if not points.shape[0]:
        return 0.0
    return OCCLUSION_TOLERANCE * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def fan_triangles(face_corners, face_sizes) -> np.ndarray:
    """(T, 3) uint32 triangles of polygons given as their corners one face after another (``face_corners``) and
    their corner counts (``face_sizes``), each cut as a fan from its first corner (faces under 3 corners: none)."""
    corners = np.asarray(face_corners, dtype=np.int64).reshape(-1)
    sizes = np.asarray(face_sizes, dtype=np.int64).reshape(-1)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    fans = np.maximum(sizes - 2, 0)
    faces = np.repeat(np.arange(sizes.size), fans)
    step = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans)
    first = starts[faces]
    loops = np.stack([first, first + step + 1, first + step + 2], axis=1)
    return np.ascontiguousarray(corners[loops], dtype=np.uint32).reshape(-1, 3)
