"""Feature detection through the binding: curvatures of a sphere, the rounded box's 12 blend
centre-lines, the result types, and the errors (a plane, a bad scale). No bpy here.

``rounded_box`` is also the target of the add-on's feature tests (``tests/addon/test_features.py``).
"""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import centre_line_distance, grid, rounded_box


def test_sphere_curvatures_are_one_over_the_radius():
    vertices, triangles = rounded_box(2.0, 2.0, 16)
    curvatures = sk.TargetMesh(vertices, triangles).principal_curvatures(0.6)
    assert isinstance(curvatures, sk.Curvatures)
    assert curvatures.k1.dtype == np.float32 and curvatures.k1.shape == (vertices.shape[0],)
    assert curvatures.d1.shape == (vertices.shape[0], 3)
    np.testing.assert_allclose(curvatures.k1, 0.5, rtol=0.01)
    np.testing.assert_allclose(curvatures.k2, 0.5, rtol=0.01)
    # The directions are unit, tangent (normal to the radius) and orthogonal.
    radial = vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    assert np.abs(np.linalg.norm(curvatures.d1, axis=1) - 1).max() < 1e-5
    assert np.abs((curvatures.d1 * radial).sum(1)).max() < 1e-3
    assert np.abs((curvatures.d1 * curvatures.d2).sum(1)).max() < 1e-5


def test_rounded_box_gives_twelve_ridges_on_the_blend_centre_lines():
    vertices, triangles = rounded_box()
    features = sk.TargetMesh(vertices, triangles).detect_features(0.25)
    assert isinstance(features, sk.Features)
    assert len(features.curves) == 12
    for curve in features.curves:
        assert isinstance(curve, sk.FeatureCurve)
        assert curve.kind == "RIDGE" and not curve.closed
        assert curve.points.dtype == np.float32 and curve.points.shape[1] == 3
        assert centre_line_distance(curve.points).max() < 0.05
    regions = features.regions
    assert regions.dtype == np.uint8 and regions.shape == (vertices.shape[0],)
    face_middle = np.sort(np.abs(vertices), axis=1)[:, 1] < 0.4
    assert (regions[face_middle] == 0).all()
    assert (regions[centre_line_distance(vertices) < 0.02] == 1).all()
    assert sk.TargetMesh(vertices, triangles).feature_curves(0.25, min_length=10.0) == []


def test_a_plane_raises_flat_surface_error():
    vertices, triangles = grid(10)
    mesh = sk.TargetMesh(vertices, triangles)
    with pytest.raises(sk.FlatSurfaceError, match="no curvature"):
        mesh.detect_features(2.0)
    assert issubclass(sk.FlatSurfaceError, sk.SpringwrapError)
    assert np.abs(mesh.principal_curvatures(2.0).k1).max() < 1e-4


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), 1e6])
def test_bad_scales_raise_invalid_argument(scale):
    vertices, triangles = rounded_box(1.0, 1.0, 6)
    with pytest.raises(sk.InvalidArgumentError, match="feature scale"):
        sk.TargetMesh(vertices, triangles).principal_curvatures(scale)


def test_a_negative_threshold_is_refused():
    vertices, triangles = rounded_box(1.0, 1.0, 6)
    with pytest.raises(sk.InvalidArgumentError, match="ridge_threshold"):
        sk.TargetMesh(vertices, triangles).detect_features(0.3, ridge_threshold=-1.0)


def test_the_default_scale_is_automatic_and_finds_the_l_parts_six_blends():
    """The machined L part of ``benchmarks/feature_shapes.py`` (blend radius 0.04): with no scale given the
    kernel picks a tenth of the diagonal (about the blend radius), says so in ``scale``, and every blend
    centre-line is covered over at least 90 % of its length within a quarter of the radius, reaching both caps."""
    from benchmarks.feature_shapes import DEPTH, curve_measures, end_reach, l_part, l_part_centre_lines

    vertices, triangles = l_part()
    mesh = sk.TargetMesh(vertices, triangles)
    diagonal = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    assert mesh.automatic_feature_scale() == pytest.approx(0.1 * diagonal, rel=1e-5)
    features = mesh.detect_features()
    assert features.scale == pytest.approx(0.1 * diagonal, rel=1e-5)
    segments, kinds = l_part_centre_lines()
    measures = curve_measures(features.curves, segments, kinds, tolerance=0.01)
    assert min(measures["coverage"]) >= 0.9, measures
    assert measures["offset"] < 0.003, measures
    reach = np.array(end_reach(features.curves, segments, kinds, tolerance=0.01))
    assert reach[:, :2].max() < 0.01 * DEPTH, reach  # within 2 mm of both caps


def test_a_layout_edge_length_sets_the_scale_within_the_targets_edges():
    vertices, triangles = rounded_box()  # edges of 0.05 (mean 0.057 with the diagonals)
    mesh = sk.TargetMesh(vertices, triangles)
    assert mesh.automatic_feature_scale(0.4) == pytest.approx(0.4)
    assert mesh.detect_features(layout_edge_length=0.35).scale == pytest.approx(0.35)
    assert len(mesh.detect_features(0.0, layout_edge_length=0.35).curves) == 12
    # Below 6 mean edges or above 30: held there; a given scale wins over the layout.
    mean_edge = float(np.linalg.norm(vertices[triangles] - np.roll(vertices[triangles], 1, axis=1), axis=2).mean())
    assert mesh.automatic_feature_scale(1e-4) == pytest.approx(6 * mean_edge, rel=1e-4)
    assert mesh.detect_features(0.3, layout_edge_length=0.01).scale == pytest.approx(0.3)


def test_feature_defaults_come_from_the_kernel():
    defaults = sk.feature_defaults()
    assert defaults["scale"] == 0.0
    assert defaults["flat_threshold"] == pytest.approx(0.1)
    assert defaults["ridge_threshold"] == pytest.approx(0.25)
    assert 0.0 < defaults["hysteresis"] < 1.0
    assert defaults["scale_min_edges"] < defaults["scale_max_edges"]


@pytest.mark.parametrize(
    ("keyword", "value"), [("layout_edge_length", -1.0), ("layout_edge_length", float("nan")), ("hysteresis", 2.0)]
)
def test_bad_layout_edge_lengths_and_hysteresis_are_refused(keyword, value):
    vertices, triangles = rounded_box(1.0, 0.25, 8)
    with pytest.raises(sk.InvalidArgumentError, match=keyword):
        sk.TargetMesh(vertices, triangles).detect_features(**{keyword: value})
