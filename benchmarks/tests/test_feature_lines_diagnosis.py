"""The feature-lines diagnosis's measures on made-up polylines (no Blender)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import feature_lines_diagnosis as diagnosis


def test_a_zig_zag_row_of_points_is_longer_than_its_course_a_straight_one_is_not():
    straight = np.stack([np.linspace(0.0, 8.0, 9), np.zeros(9), np.zeros(9)], axis=1)
    assert diagnosis.arc_inflation(straight) == pytest.approx(1.0)
    zigzag = straight.copy()
    zigzag[1::2, 1] = 0.5  # every other point half a step aside
    assert diagnosis.arc_inflation(zigzag) == pytest.approx(np.hypot(1.0, 0.5))


def test_points_go_to_the_nearest_point_of_the_polyline():
    polyline = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0]])
    points = np.array([[1.0, 1.0, 0.0], [3.0, 1.5, 0.0], [-1.0, 0.0, 0.0]])
    assert np.allclose(diagnosis.projected(polyline, points), [[1.0, 0.0, 0.0], [2.0, 1.5, 0.0], [0.0, 0.0, 0.0]])


def test_each_group_gets_its_count_and_share_of_the_error():
    errors = np.array([1.0, 1.0, 2.0, 4.0])
    found = diagnosis.shares(errors, {"a": np.array([True, False, True, False]), "b": np.zeros(4, dtype=bool)})
    assert found == {"a": (2, 0.375), "b": (0, 0.0)}
