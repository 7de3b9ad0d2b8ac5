"""Parts in the kernel (``springwrap_kernel.layout_pieces``, ``SurfaceFollower``) through the binding: the numbers
against numpy references, and bad arguments raising the module's exceptions by name."""

import numpy as np
import pytest

import springwrap_kernel as sk


def sphere(count, radius, centre=(0.0, 0.0, 0.0)):
    index = np.arange(count) + 0.5
    y = 1.0 - 2.0 * index / count
    ring = np.sqrt(1.0 - y * y)
    angle = np.pi * (3.0 - np.sqrt(5.0)) * index
    return np.stack([ring * np.cos(angle), y, ring * np.sin(angle)], axis=1) * radius + np.asarray(centre)


def test_pieces_are_the_connected_components():
    pieces = sk.layout_pieces(6, np.array([[3, 1], [1, 0], [5, 4]], np.uint32))
    assert pieces.dtype == np.uint32 and pieces.tolist() == [0, 0, 1, 0, 2, 2]
    with pytest.raises(sk.IndexOutOfRangeError):
        sk.layout_pieces(2, np.array([[0, 2]], np.uint32))
    with pytest.raises(sk.ArrayError):
        sk.layout_pieces(2, np.array([[0, 1]], np.int64))


def test_a_turned_and_shifted_surface_carries_the_parts_exactly():
    surface, ball = sphere(300, 1.0), sphere(40, 0.2, (0.5, 0.0, 0.0))
    angle = 0.3
    turn = np.array([[np.cos(angle), 0.0, np.sin(angle)], [0.0, 1.0, 0.0], [-np.sin(angle), 0.0, np.cos(angle)]])
    shift = np.array([0.2, -0.1, 0.4])
    for rigid in (True, False):
        follower = sk.SurfaceFollower(surface, ball, np.zeros(40, np.uint32), np.array([rigid]))
        assert follower.part_count == 40
        moved = follower.apply(surface @ turn.T + shift)
        assert moved.dtype == np.float64 and np.allclose(moved, ball @ turn.T + shift, atol=1e-9)


def test_neighbours_and_scale_change_the_result_and_bad_arguments_are_named():
    surface, ball = sphere(300, 1.0), sphere(40, 0.2, (0.5, 0.0, 0.0))
    now = surface * np.array([1.3, 1.0, 0.8])
    pieces, rigid = np.zeros(40, np.uint32), np.array([True])
    default = sk.SurfaceFollower(surface, ball, pieces, rigid).apply(now)
    assert np.abs(sk.SurfaceFollower(surface, ball, pieces, rigid, neighbours=4).apply(now) - default).max() > 1e-4
    assert np.abs(sk.SurfaceFollower(surface, ball, pieces, rigid, scale=True).apply(now) - default).max() > 1e-4
    reweighted = sk.SurfaceFollower(surface, ball, pieces, rigid, robust_rounds=8).apply(now)
    assert np.abs(reweighted - default).max() > 1e-4
    with pytest.raises(sk.InvalidArgumentError, match="robust_rounds"):
        sk.SurfaceFollower(surface, ball, pieces, rigid, robust_rounds=17)
    # soft_neighbours binds the soft vertices alone; neighbours the rigid pieces alone.
    soft = np.array([False])
    soft_default = sk.SurfaceFollower(surface, ball, pieces, soft).apply(now)
    assert (
        np.abs(sk.SurfaceFollower(surface, ball, pieces, soft, soft_neighbours=8).apply(now) - soft_default).max()
        > 1e-4
    )
    assert np.array_equal(sk.SurfaceFollower(surface, ball, pieces, soft, neighbours=8).apply(now), soft_default)
    assert np.array_equal(sk.SurfaceFollower(surface, ball, pieces, rigid, soft_neighbours=8).apply(now), default)
    with pytest.raises(sk.InvalidArgumentError, match="soft_neighbours"):
        sk.SurfaceFollower(surface, ball, pieces, soft, soft_neighbours=5000)
    with pytest.raises(sk.InvalidArgumentError, match="neighbours"):
        sk.SurfaceFollower(surface, ball, pieces, rigid, neighbours=0)
    with pytest.raises(sk.InvalidArgumentError, match="pieces"):
        sk.SurfaceFollower(surface, ball, pieces + 1, rigid)
    with pytest.raises(sk.InvalidArgumentError, match="surface"):
        sk.SurfaceFollower(np.zeros((0, 3)), ball, pieces, rigid)
    with pytest.raises(sk.NonFiniteError):
        sk.SurfaceFollower(surface, np.full((40, 3), np.nan), pieces, rigid)
    with pytest.raises(sk.ArgumentTypeError):
        sk.SurfaceFollower(surface, ball, pieces, rigid, scale="yes")
    follower = sk.SurfaceFollower(surface, ball, pieces, rigid)
    with pytest.raises(sk.SpringwrapError, match="surface"):
        follower.apply(surface[:10])
