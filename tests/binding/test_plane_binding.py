"""The mirror plane constraint through the kernel's Python binding (no bpy): held vertices end on the plane."""

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import make_solver, plane_target, quad_layout


def test_a_row_held_on_a_plane_across_a_flat_target_ends_on_it():
    target = plane_target()
    positions, face_corners, face_sizes = quad_layout()
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    row = np.arange(13 * 6, 13 * 7, dtype=np.uint32)  # the middle row: y = 0.05 * 6 - 0.3 = 0.0
    positions[row, 1] += 0.01  # start it off the plane y = 0
    solver, _hits = make_solver(
        target,
        positions,
        structure,
        [0, 12, 156, 168],
        plane_vertices=row,
        plane_point=(0.0, 0.0, 0.0),
        plane_normal=(0.0, 2.0, 0.0),
    )
    report = solver.step(3000)
    assert report.converged
    held = solver.positions()[row]
    assert np.abs(held[:, 1]).max() < 1e-6  # on the plane y = 0
    states = solver.states()[0][row]
    assert (states == 1).all() and np.abs(held[:, 2]).max() < 1e-6  # and on the target z = 0


def test_bad_plane_arguments_are_refused():
    target = plane_target()
    positions, face_corners, face_sizes = quad_layout(4)
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    vertices = np.array([0, 1], dtype=np.uint32)
    with pytest.raises(sk.ArrayError, match="all three of plane_vertices, plane_point and plane_normal"):
        make_solver(target, positions, structure, [0], plane_vertices=vertices, plane_point=(0.0, 0.0, 0.0))
    with pytest.raises(sk.InvalidArgumentError, match="zero length"):
        make_solver(
            target,
            positions,
            structure,
            [0],
            plane_vertices=vertices,
            plane_point=(0.0, 0.0, 0.0),
            plane_normal=(0.0, 0.0, 0.0),
        )
    with pytest.raises(sk.InvalidArgumentError, match="vertex 99 does not exist"):
        make_solver(
            target,
            positions,
            structure,
            [0],
            plane_vertices=np.array([99], np.uint32),
            plane_point=(0.0, 0.0, 0.0),
            plane_normal=(0.0, 1.0, 0.0),
        )
