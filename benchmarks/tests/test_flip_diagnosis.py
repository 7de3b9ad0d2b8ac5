"""The flip diagnosis on made-up quads over a flat target (no Blender)."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import flip_diagnosis


def two_quads():
    """Two unit quads side by side in the xy plane (normals +z), and a flat target under them."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]], dtype=np.float64)
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4]])
    target_vertices = np.array([[-5, -5, 0], [5, -5, 0], [0, 5, 0]], dtype=np.float32)
    target_triangles = np.array([[0, 1, 2]], dtype=np.uint32)
    return positions, quads, target_vertices, target_triangles


def test_only_the_quad_turned_against_the_truth_is_reported_with_how_it_sits():
    truth, quads, target_vertices, target_triangles = two_quads()
    result = truth.copy()
    result[[2, 5], 0] = 0.5  # the second quad folded back over the first: it faces -z
    found = flip_diagnosis.diagnose(result, truth, truth, quads, target_vertices, target_triangles)
    assert [flipped.quad for flipped in found] == [1]
    (flipped,) = found
    assert flipped.to_truth == 180.0 and flipped.to_target == 180.0 and flipped.to_template == 180.0
    assert flipped.truth_to_target == 0.0
    assert flipped.area_ratio == 0.5
    assert flipped.error_percent > 0.0 and "quad      1" in flipped.line()
    assert flipped.truth_depth_percent == 0.0  # the truth lies on the target


def test_a_true_quad_under_the_target_says_how_deep():
    truth, quads, target_vertices, target_triangles = two_quads()
    result = truth.copy()
    result[[2, 5], 0] = 0.5
    sunk = truth.copy()
    sunk[5, 2] = -0.3  # one corner of the second true quad under the surface (the target faces +z)
    sunk[2, 2] = 0.2  # another above it: not under
    (flipped,) = flip_diagnosis.diagnose(result, sunk, truth, quads, target_vertices, target_triangles)
    diagonal = float(np.linalg.norm(np.ptp(sunk, axis=0)))
    assert abs(flipped.truth_depth_percent - 0.3 / diagonal * 100.0) < 1e-4
    assert "% under the target" in flipped.line()


def test_a_result_that_keeps_every_orientation_has_nothing_to_report():
    truth, quads, target_vertices, target_triangles = two_quads()
    shifted = truth + np.array([0.3, -0.2, 0.05])
    assert flip_diagnosis.diagnose(shifted, truth, truth, quads, target_vertices, target_triangles) == []
