"""Feature detection's numbers on arrays (no ``bpy``): the colours of the kernel's regions, and the scale a
detection uses when none is given (a few mean edge lengths of the target)."""

import numpy as np

REGION_COLORS = np.array(
    [
        (0.55, 0.55, 0.55, 1.0),  # flat: grey
        (0.85, 0.25, 0.15, 1.0),  # convex: red
        (0.15, 0.35, 0.85, 1.0),  # concave: blue
        (0.90, 0.75, 0.15, 1.0),  # saddle: yellow
    ],
    dtype=np.float32,
)
"""RGBA per region number (the kernel's order: flat, convex, concave, saddle)."""

DEFAULT_SCALE_EDGES = 3.0
"""With ``scale = 0``, the scale is this many mean edge lengths of the target."""


def mean_edge_length(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Mean length of the triangles' edges (each inner edge counted twice: it does not matter for a mean)."""
    corners = vertices[triangles.astype(np.int64)]
    edges = corners - np.roll(corners, 1, axis=1)
    return float(np.linalg.norm(edges, axis=2).mean())


def region_colors(regions: np.ndarray) -> np.ndarray:
    """(V, 4) RGBA of the region numbers."""
    return REGION_COLORS[np.asarray(regions, dtype=np.int64)]
