"""A target built from its float32 coordinates in the kernel's frame (what the add-on hands the kernel, without
holding float64 world vertices while it builds) is the target built from the world vertices: same origin, same
kernel vertices and triangles, same answers in world space."""

import numpy as np

from helpers import core_module


def test_a_target_built_in_its_frame_is_the_target_built_from_world_vertices():
    target = core_module("target")
    rng = np.random.default_rng(3)
    world = rng.normal(size=(300, 3)) * 0.4 + np.array([1e5, -2.5e4, 7.0])  # far from the origin
    triangles = rng.integers(0, 300, size=(500, 3)).astype(np.uint32)
    direct = target.make_target("T", world, triangles)
    origin = target.frame_origin(world)
    in_frame = target.make_target("T", target.kernel_coordinates(world, origin), triangles, None, origin)
    assert np.array_equal(in_frame.mesh.origin, direct.mesh.origin)
    assert np.array_equal(in_frame.mesh.kernel.vertices(), direct.mesh.kernel.vertices())
    assert np.array_equal(in_frame.mesh.triangles(), direct.mesh.triangles())
    assert in_frame.signature == direct.signature
    assert in_frame.reattach_tolerance == direct.reattach_tolerance
    queries = world[:40] + rng.normal(size=(40, 3)) * 0.05
    assert np.array_equal(
        in_frame.mesh.closest_points(queries).positions, direct.mesh.closest_points(queries).positions
    )
