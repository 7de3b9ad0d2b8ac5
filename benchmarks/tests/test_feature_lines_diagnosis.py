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


def test_a_quarter_circle_turns_evenly_a_straight_line_not_at_all():
    angles = np.linspace(0.0, np.pi / 2.0, 41)
    arc = np.stack([np.cos(angles), np.sin(angles), np.zeros(41)], axis=1)
    profile = diagnosis.turning_profile(arc, 100, 0.05)  # smoothed over 1.3 segments
    assert np.allclose(profile[20:-20], np.pi / 2.0, rtol=0.005)  # the ends straightened by the reflection
    straight = np.stack([np.linspace(0.0, 1.0, 9), np.zeros(9), np.zeros(9)], axis=1)
    assert np.allclose(diagnosis.turning_profile(straight, 50, 0.1), 0.0, atol=1e-9)


def test_the_shape_warp_lines_up_a_bend_the_guess_puts_too_early():
    samples = np.linspace(0.0, 1.0, 101)
    target = np.exp(-0.5 * ((samples - 0.52) / 0.04) ** 2)  # the curve bends at 0.52
    profile = np.exp(-0.5 * ((samples - 0.5) / 0.04) ** 2)  # the line at 0.5, the guess taking it to 0.5
    warped = diagnosis.shape_warp(profile, target, samples, band=0.05, keep=0.0, stiffness=0.01)
    assert warped[50] == pytest.approx(0.52, abs=0.003)
    kept = diagnosis.shape_warp(profile, target, samples, band=0.05, keep=1e6, stiffness=0.01)
    assert np.allclose(kept, samples)


def test_fractions_are_where_the_nearest_points_lie_along_the_polyline():
    polyline = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0]])
    points = np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 0.0]])
    assert np.allclose(diagnosis.projected_fractions(polyline, points), [0.25, 0.75])


def test_a_known_middle_point_pulls_the_chain_to_its_true_places():
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "addon"))
    from springwrap.core import curves, smooth_map

    corners = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 4.0], [4.0, 4.0, 4.0]])
    rest = np.stack([np.linspace(0.0, 4.0, 9), np.zeros(9), np.zeros(9)], axis=1)
    truth = rest.copy()
    truth[:, 0] = 4.0 * (rest[:, 0] / 4.0) ** 1.5  # the true places bunch up at the start of the stretch
    chain = np.arange(9)
    constraint = curves.make_constraint(
        chain, rest.copy(), curves.FEATURE_LINE, confidence=1.0, fractions=np.linspace(0.0, 1.0, 9)
    )
    store = {"mapping": smooth_map.fit(corners, corners)}  # the identity: places the chain evenly
    scene = (None, rest, None, None, truth, None, 1.0, None)
    placed = diagnosis.middle_known(store, scene, [constraint], [rest.copy()], [np.ones(9, dtype=bool)])
    assert np.allclose(placed[4], truth[4], atol=1e-9)
    assert np.abs(placed - truth)[:, 0].mean() < 0.5 * np.abs(rest - truth)[:, 0].mean()
