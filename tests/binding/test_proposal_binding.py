"""Correspondence proposals through the binding: on a bumpy ball whose proportions change, the tips and pits
not anchored are proposed near their true points, each setting changes the answer, and bad input raises the
exception naming the problem. No bpy here."""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import ball_landmarks, ball_stretch, bumpy_ball, triangulated

LOOSE = 0.3
"""A least confidence below the default: the ball, with 3 anchors only, has few pairs above the default."""


@pytest.fixture(scope="module")
def ball():
    rest, faces = bumpy_ball(60, 90)
    fine, fine_faces = bumpy_ball(110, 170)
    mesh = sk.TargetMesh(ball_stretch(fine).astype(np.float32), triangulated(fine_faces).astype(np.uint32))
    corners = np.array([v for face in faces for v in face], dtype=np.uint32)
    sizes = np.array([len(face) for face in faces], dtype=np.uint32)
    current = rest * 1.05 + np.array([0.1, -0.2, 0.05])
    marks = ball_landmarks(rest, 3)
    arguments = (
        mesh,
        rest.astype(np.float32),
        current.astype(np.float32),
        corners,
        sizes,
        marks.astype(np.uint32),
        ball_stretch(rest[marks]).astype(np.float32),
    )
    return arguments, ball_stretch(rest)


def test_proposals_land_near_the_true_points(ball):
    arguments, truth = ball
    found = sk.propose_correspondences(*arguments, min_confidence=LOOSE)
    assert isinstance(found, sk.Proposals)
    assert found.vertices.dtype == np.uint32 and found.triangles.dtype == np.uint32
    assert found.barycentric.shape == (found.vertices.shape[0], 3)
    assert found.vertices.shape[0] >= 3
    assert np.all((found.confidences >= 0.0) & (found.confidences <= 1.0))
    assert np.all(np.diff(found.confidences) <= 0.0)  # most confident first
    assert not set(found.vertices.tolist()) & set(arguments[5].tolist())  # the anchored vertices are not proposed
    diagonal = np.linalg.norm(np.ptp(truth, axis=0))
    errors = np.linalg.norm(found.positions - truth[found.vertices], axis=1)
    assert errors.max() < 0.02 * diagonal, errors
    on_surface = arguments[0].face_point_positions(found.triangles, found.barycentric)
    np.testing.assert_allclose(on_surface, found.positions, atol=1e-5)


def test_every_setting_changes_the_answer(ball):
    arguments, _truth = ball
    defaults = sk.proposal_defaults()
    assert set(defaults) == {"max_count", "min_confidence", "search_radius", "feature_scale", "min_anchors"}
    every = sk.propose_correspondences(*arguments, min_confidence=LOOSE)
    two = sk.propose_correspondences(*arguments, max_count=2, min_confidence=LOOSE)
    np.testing.assert_array_equal(two.vertices, every.vertices[:2])
    sure = sk.propose_correspondences(*arguments, min_confidence=float(every.confidences[1]) + 1e-6)
    assert 1 <= sure.vertices.shape[0] < every.vertices.shape[0]
    default = sk.propose_correspondences(*arguments)
    assert defaults["min_confidence"] > LOOSE
    np.testing.assert_array_equal(default.vertices, every.vertices[every.confidences >= defaults["min_confidence"]])
    narrow = sk.propose_correspondences(*arguments, search_radius=0.002, min_confidence=LOOSE)
    assert narrow.vertices.shape[0] < every.vertices.shape[0]
    coarse = sk.propose_correspondences(*arguments, feature_scale=0.08, min_confidence=LOOSE)
    assert coarse.vertices.tolist() != every.vertices.tolist()


def test_bad_input_names_the_problem(ball):
    arguments, _truth = ball
    mesh, rest, current, corners, sizes, vertices, targets = arguments
    with pytest.raises(sk.InvalidArgumentError, match="at least 3"):
        sk.propose_correspondences(mesh, rest, current, corners, sizes, vertices[:2], targets[:2])
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        sk.propose_correspondences(mesh, rest, current, corners, sizes, vertices, targets[:2])
    with pytest.raises(sk.InvalidArgumentError, match="lengths differ"):
        sk.propose_correspondences(mesh, rest, current[1:], corners, sizes, vertices, targets)
    with pytest.raises(sk.IndexOutOfRangeError, match="anchor 0"):
        sk.propose_correspondences(mesh, rest, current, corners, sizes, vertices + 100_000, targets)
    nan = targets.copy()
    nan[1, 0] = np.nan
    with pytest.raises(sk.NonFiniteError, match="anchor target 1"):
        sk.propose_correspondences(mesh, rest, current, corners, sizes, vertices, nan)
    with pytest.raises(sk.ArrayError, match="rest"):
        sk.propose_correspondences(mesh, rest.astype(np.float64), current, corners, sizes, vertices, targets)
    with pytest.raises(sk.InvalidArgumentError, match="min_confidence"):
        sk.propose_correspondences(*arguments, min_confidence=2.0)
    with pytest.raises(sk.InvalidArgumentError, match="max_count"):
        sk.propose_correspondences(*arguments, max_count=0)
    with pytest.raises(sk.ArgumentTypeError, match="mesh"):
        sk.propose_correspondences("mesh", rest, current, corners, sizes, vertices, targets)
