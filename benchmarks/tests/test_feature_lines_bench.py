"""The feature-lines benchmark's measures (``benchmarks/feature_lines.py``), no Blender: a crease vertex's error
split along its crease and across it."""

import numpy as np

from benchmarks.feature_lines import along_and_across, markdown, nearest_segments


def two_creases():
    """(2, 2, 3): a crease along x at the origin and one along z at (5, 0, 0)."""
    return np.array([[[0.0, 0, 0], [4.0, 0, 0]], [[5.0, 0, 0], [5.0, 0, 4]]])


def test_each_error_splits_along_the_crease_nearest_its_true_place_and_across_it():
    places = np.array([[1.0, 0, 0], [5.0, 0, 2], [2.0, 0.1, 0]])
    errors = np.array([[0.3, 0.4, 0.0], [0.3, 0.0, -0.4], [-0.2, 0.0, 0.0]])
    along, across = along_and_across(errors, places, two_creases())
    np.testing.assert_allclose(along, [0.3, 0.4, 0.2])
    np.testing.assert_allclose(across, [0.4, 0.3, 0.0], atol=1e-12)
    distance, index = nearest_segments(places, two_creases())
    np.testing.assert_allclose(distance, [0.0, 0.0, 0.1])
    assert index.tolist() == [0, 1, 0]


def test_the_table_writes_the_split_and_a_dash_for_rows_measured_before_it():
    row = {"anchors": 8, "pairing": True, "junctions": True, "placement": "MAPPED", "pairs": 3}
    row |= {"mean_confidence": 0.9, "mean_all": 0.2, "mean_crease": 0.15, "p95_crease": 0.4}
    row |= {"mean_crease_to_corner": 0.16}
    split = dict(row, along_crease=0.125, across_crease=0.031)
    target = {"tessellation": "sharp", "target_vertices": 10, "crease_vertices": 4, "crease_rounding": 0.01}
    target |= {"detection": {"scale": 0.05, "curves": 2, "median_length_edges": 3.0, "curves_under_3_edges": 0}}
    target["detection"]["crease_length_covered"] = 1.0
    result = {"mesh": "part.off", "layout": {"maker": "QuadriFlow", "vertices": 10, "quads": 8}}
    lines = markdown(result | {"targets": [target | {"rows": [split, row]}]})
    rows = [line for line in lines if line.startswith("| sharp |")]
    assert rows[0].endswith("| 0.400 | 0.125 | 0.031 | 0.160 |")
    assert rows[1].endswith("| 0.400 | - | - | 0.160 |")
