"""Feature detection's numbers on arrays (no ``bpy``): the colours of the kernel's regions, the kernel's
defaults, and the layout edge length the automatic scale is chosen from."""

import numpy as np

import springwrap_kernel

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


def feature_defaults() -> dict:
    """The kernel's defaults of feature detection (scale 0 = automatic, flat_threshold, ridge_threshold,
    hysteresis, ...; see ``springwrap_kernel.feature_defaults``)."""
    return springwrap_kernel.feature_defaults()


def median_edge_length(positions: np.ndarray, edges: np.ndarray) -> float:
    """Median length of a layout's edges ((E, 2) vertex pairs); 0 when it has none (then the automatic scale
    comes from the target alone)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if edges.shape[0] == 0:
        return 0.0
    positions = np.asarray(positions, dtype=np.float64)
    lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    lengths = lengths[np.isfinite(lengths) & (lengths > 0.0)]
    return float(np.median(lengths)) if lengths.size else 0.0


def region_colors(regions: np.ndarray) -> np.ndarray:
    """(V, 4) RGBA of the region numbers."""
    return REGION_COLORS[np.asarray(regions, dtype=np.int64)]
