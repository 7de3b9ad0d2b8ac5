"""The wrap's and the mirror's ranges are decided once (``properties.WRAP_RANGES``): the properties' hard limits
are the valid range (the kernel's, for its settings) and Blender clamps a value beyond them, from the panel and
from scripts alike; the guide says so."""

import bpy

import numpy as np
import pytest

import springwrap_kernel as sk
from bpy_helpers import head_scene, plane_scene, snapshot

KERNEL_SETTINGS = ("fairness", "arc_length", "thin_plate", "constraint", "folding", "tolerance")


def _ranges():
    from springwrap import properties

    return properties.WRAP_RANGES


@pytest.mark.parametrize("operator", ["wrap", "mirror"])
def test_the_operators_properties_have_the_decided_ranges(operator):
    properties = getattr(bpy.ops.springwrap, operator).get_rna_type().properties
    checked = 0
    for name, decided in _ranges().items():
        if name not in properties:
            continue
        prop = properties[name]
        assert (prop.hard_min, prop.hard_max) == pytest.approx((decided.hard_min, decided.hard_max)), name
        assert (prop.soft_min, prop.soft_max) == pytest.approx((decided.soft_min, decided.soft_max)), name
        checked += 1
    assert checked == (8 if operator == "wrap" else 2)


@pytest.mark.parametrize("name", KERNEL_SETTINGS)
def test_the_hard_limits_are_the_kernels_valid_range(name):
    decided = _ranges()[name]
    above = float(np.nextafter(np.float32(decided.hard_max), np.float32(np.inf)))
    below = float(np.nextafter(np.float32(decided.hard_min), np.float32(-np.inf)))
    assert getattr(sk.WrapSettings(**{name: decided.hard_max}), name) == pytest.approx(decided.hard_max)
    with pytest.raises(sk.InvalidArgumentError, match=name):
        sk.WrapSettings(**{name: above})
    with pytest.raises(sk.InvalidArgumentError, match=name):
        sk.WrapSettings(**{name: below})
    if name == "tolerance":  # (0, 1]: the one open end, which a hard minimum cannot express
        with pytest.raises(sk.InvalidArgumentError, match="tolerance"):
            sk.WrapSettings(tolerance=0.0)
        sk.WrapSettings(tolerance=float(np.finfo(np.float32).tiny))
    else:
        sk.WrapSettings(**{name: decided.hard_min})


def test_a_value_beyond_a_limit_is_clamped_by_blender_as_the_guide_says(capfd):
    """``max_iterations=0`` and ``-5`` run one iteration; a weight of 2 wraps exactly as 1; a spring resolution
    of 9 as 8."""
    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    start = snapshot(layout)
    capfd.readouterr()
    for iterations in (0, -5):
        assert bpy.ops.springwrap.wrap(max_iterations=iterations) == {"FINISHED"}
        assert "in 1 iterations (stopped at the iteration limit)" in capfd.readouterr().out
    results = {}
    for fairness, resolution in ((2.0, 9), (1.0, 8)):
        bpy.ops.wm.read_homefile(use_empty=True)
        _target, layout, _normal = plane_scene()
        bpy.ops.springwrap.anchors_auto(spacing=0.5)
        assert snapshot(layout) == start
        assert bpy.ops.springwrap.wrap(fairness=fairness, spring_resolution=resolution, max_iterations=40) == {
            "FINISHED"
        }
        results[fairness] = snapshot(layout)
    assert results[2.0] == results[1.0]


def test_mirror_max_iterations_zero_runs_one_iteration(capfd):
    head_scene()
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=0) == {"FINISHED"}
    assert "the new half wrapped in 1 iterations" in capfd.readouterr().out


def test_a_tolerance_of_zero_is_refused_by_the_kernel():
    _target, layout, _normal = plane_scene()
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match=r"invalid tolerance: the tolerance must be within \(0, 1\], not 0"):
        bpy.ops.springwrap.wrap(tolerance=0.0)
    assert snapshot(layout) == before
