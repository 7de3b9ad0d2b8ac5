"""Hostile arguments through the binding: every scalar argument converted with the module's own errors
naming it, counts that never abort, and the kernel's coordinate bound (no bpy).

The binding's rule (``rust_core/python/src/arguments.rs``): a value out of its range raises
``InvalidArgumentError`` (``TooLargeError`` for a count above what the kernel supports), a value of the
wrong Python type ``ArgumentTypeError`` (a ``SpringwrapError`` and a ``TypeError``), each naming the argument.
"""

import subprocess
import textwrap

import numpy as np
import pytest

import springwrap_kernel as sk
from helpers import grid, kernel_python, make_solver, plane_target, quad_layout, space_anchor, space_points

EMPTY = np.empty(0, np.uint32)


def run_isolated(code: str) -> subprocess.CompletedProcess:
    """Runs ``code`` in a fresh Python: an abort (SIGABRT) there fails the test instead of killing pytest."""
    executable, environment = kernel_python()
    return subprocess.run(
        [executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env=environment,
    )


@pytest.mark.parametrize("count", ["2**31", "2**40", "2**64", "2**200"])
def test_a_huge_layout_vertex_count_raises_instead_of_aborting(count):
    # The bug: LayoutStructure(2**31, empty, empty) printed "memory allocation of 51539607552 bytes
    # failed" and died with SIGABRT.
    result = run_isolated(f"""
        import numpy as np, springwrap_kernel as sk
        empty = np.empty(0, np.uint32)
        try:
            sk.LayoutStructure({count}, empty, empty)
        except sk.TooLargeError as error:
            assert isinstance(error, sk.InvalidArgumentError), type(error).__mro__
            print("refused:", error)
    """)
    assert result.returncode == 0, result.stderr
    assert "refused: invalid vertex_count: " in result.stdout
    assert "is more than the 2147483647 supported" in result.stdout


def test_the_largest_layout_vertex_count_costs_nothing_and_sparse_vertices_are_read():
    structure = sk.LayoutStructure(sk.MAX_ELEMENTS, EMPTY, EMPTY)
    assert structure.vertex_count == 2**31 - 1 == sk.MAX_ELEMENTS
    top = sk.MAX_ELEMENTS - 1
    corners = np.array([top - 3, top - 2, top - 1, top], np.uint32)
    structure = sk.LayoutStructure(sk.MAX_ELEMENTS, corners, np.array([4], np.uint32))
    assert sorted(structure.corners().tolist()) == corners.tolist()


def layout_structure(vertex_count):
    return sk.LayoutStructure(vertex_count, EMPTY, EMPTY)


def small_target():
    vertices, triangles = grid(2)
    return sk.TargetMesh(vertices, triangles)


def small_solver():
    target = plane_target(cells=8, size=0.25)
    positions, face_corners, face_sizes = quad_layout(n=3, size=0.2)
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    return make_solver(target, positions, structure, [0])[0]


POINTS = np.zeros((2, 3), np.float32)

# (what is called, the argument named, a bad value, the error class, text of the message)
# fmt: off
CATALOGUE = [
    (lambda v: layout_structure(v), "vertex_count", -1, sk.InvalidArgumentError, "must be 0 or more"),
    (lambda v: layout_structure(v), "vertex_count", -(2**70), sk.InvalidArgumentError, "must be 0 or more"),
    (lambda v: layout_structure(v), "vertex_count", 3.0, sk.ArgumentTypeError, "must be an int, got float"),
    (lambda v: layout_structure(v), "vertex_count", "12", sk.ArgumentTypeError, "must be an int, got str"),
    (lambda v: layout_structure(v), "vertex_count", True, sk.ArgumentTypeError, "got a bool"),
    (lambda v: small_solver().step(v), "iterations", -5, sk.InvalidArgumentError, "must be 0 or more"),
    (lambda v: small_solver().step(v), "iterations", 2**64, sk.TooLargeError, "more than the 1000000000"),
    (lambda v: small_solver().step(v), "iterations", None, sk.ArgumentTypeError, "must be an int, got NoneType"),
    (lambda v: small_target().closest_points(POINTS, max_distance=v), "max_distance", "far", sk.ArgumentTypeError, ""),
    (lambda v: small_target().closest_points(POINTS, max_distance=v), "max_distance", 1e39, sk.InvalidArgumentError, ""),
    (lambda v: small_target().closest_points(POINTS, max_distance=v), "max_distance", 10**400, sk.InvalidArgumentError, ""),
    (lambda v: small_target().nearest_vertices(POINTS, max_distance=v), "max_distance", [1.0], sk.ArgumentTypeError, ""),
    (lambda v: small_target().ray_cast(POINTS, POINTS + 1, both_directions=v), "both_directions", "yes", sk.ArgumentTypeError, ""),
    (lambda v: sk.TargetMesh(*grid(2), reject_degenerate=v), "reject_degenerate", 1, sk.ArgumentTypeError, "bool"),
    (lambda v: small_target().icp(POINTS, max_iterations=v), "max_iterations", -1, sk.InvalidArgumentError, ""),
    (lambda v: small_target().icp(POINTS, max_iterations=v), "max_iterations", 2**40, sk.TooLargeError, ""),
    (lambda v: small_target().icp(POINTS, max_iterations=v), "max_iterations", 100_001, sk.InvalidArgumentError, "100000"),
    (lambda v: small_target().icp(POINTS, trim_fraction=v), "trim_fraction", "0.1", sk.ArgumentTypeError, ""),
    (lambda v: small_target().icp(POINTS, tolerance=v), "tolerance", object(), sk.ArgumentTypeError, ""),
    (lambda v: small_target().icp(POINTS, anchor_weight=v), "anchor_weight", 2**2000, sk.InvalidArgumentError, ""),
    (lambda v: small_target().icp(POINTS, update=v), "update", 3, sk.ArgumentTypeError, "must be a str"),
    (lambda v: small_target().icp(POINTS, ignore_boundary=v), "ignore_boundary", "no", sk.ArgumentTypeError, ""),
    (lambda v: small_target().principal_curvatures(v), "scale", "big", sk.ArgumentTypeError, ""),
    (lambda v: small_target().detect_features(1.0, flat_threshold=v), "flat_threshold", 1e30, sk.InvalidArgumentError, ""),
    (lambda v: small_target().detect_features(1.0, min_length=v), "min_length", b"1", sk.ArgumentTypeError, ""),
    (lambda v: sk.fit_transform(POINTS, POINTS, v), "method", 7, sk.ArgumentTypeError, ""),
    (lambda v: sk.WrapSettings(fairness=v), "fairness", "0.5", sk.ArgumentTypeError, ""),
    (lambda v: sk.WrapSettings(momentum=v), "momentum", 10**400, sk.InvalidArgumentError, ""),
    (lambda v: sk.WrapSettings(tolerance=v), "tolerance", 1e39, sk.InvalidArgumentError, "float32"),
    (lambda v: sk.WrapSettings(solver=v), "solver", 1, sk.ArgumentTypeError, ""),
    (lambda v: sk.WrapSettings().replace(rest=v), "rest", ["EVEN"], sk.ArgumentTypeError, ""),
    (lambda v: sk.WrapSolver(v, layout_structure(3), *wrap_arrays(3)), "target", "mesh", sk.ArgumentTypeError, "TargetMesh"),
    (lambda v: sk.WrapSolver(small_target(), v, *wrap_arrays(3)), "structure", 3, sk.ArgumentTypeError, "LayoutStructure"),
    (lambda v: wrap_solver(settings=v), "settings", {"fairness": 0.5}, sk.ArgumentTypeError, "WrapSettings"),
    (lambda v: wrap_solver(plane_slide=v), "plane_slide", "no", sk.ArgumentTypeError, ""),
    (lambda v: wrap_solver(plane_point=v), "plane_point", "xyz", sk.ArgumentTypeError, "three numbers"),
    (lambda v: wrap_solver(plane_point=v), "plane_point", 3.0, sk.ArgumentTypeError, "three numbers"),
    (lambda v: wrap_solver(plane_point=v), "plane_point", (0.0, 1.0), sk.ArrayError, "got 2"),
    (lambda v: wrap_solver(plane_normal=v), "plane_normal", (0.0, 1e39, 0.0), sk.InvalidArgumentError, "float32"),
]
# fmt: on


def wrap_arrays(count):
    return (
        np.zeros(count, np.int32),
        np.full(count, -1, np.int32),
        np.zeros((count, 3), np.float32),
        np.zeros((count, 3), np.float32),
    )


def wrap_solver(**arguments):
    """A small wrap with a plane constraint, one argument replaced."""
    target = plane_target(cells=8, size=0.25)
    positions, face_corners, face_sizes = quad_layout(n=3, size=0.2)
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    plane = {
        "plane_vertices": np.array([1], np.uint32),
        "plane_point": (0.0, 0.0, 0.0),
        "plane_normal": (1.0, 0.0, 0.0),
    }
    return make_solver(target, positions, structure, [0], **{**plane, **arguments})[0]


@pytest.mark.parametrize(
    ("call", "name", "value", "error", "text"), CATALOGUE, ids=[f"{c[1]}={c[2]!r:.20}" for c in CATALOGUE]
)
def test_a_bad_scalar_argument_raises_the_modules_error_naming_it(call, name, value, error, text):
    with pytest.raises(error, match=name) as raised:
        call(value)
    assert isinstance(raised.value, sk.SpringwrapError)
    assert not isinstance(raised.value, OverflowError)
    assert text in str(raised.value)


def test_an_argument_type_error_is_both_the_modules_error_and_a_type_error():
    assert issubclass(sk.ArgumentTypeError, sk.SpringwrapError)
    assert issubclass(sk.ArgumentTypeError, TypeError)
    assert sk.ArgumentTypeError.__module__ == "springwrap_kernel"
    with pytest.raises(TypeError, match="vertex_count must be an int"):
        layout_structure("3")


def test_plausible_scalars_of_other_types_are_accepted():
    # numpy scalars, ints for floats, None for a keyword's default.
    structure = sk.LayoutStructure(np.int64(4), EMPTY, EMPTY)
    assert structure.vertex_count == 4
    hits = small_target().closest_points(POINTS, max_distance=np.float32(2))
    assert (hits.triangles >= 0).all() and (hits.distances == 0).all()
    assert (small_target().closest_points(POINTS, max_distance=None).triangles >= 0).all()
    assert sk.WrapSettings(fairness=1, tolerance=np.float64(1e-4)).fairness == 1.0
    solver = wrap_solver(plane_point=np.zeros(3, np.float32), plane_slide=np.bool_(False))
    assert solver.step(np.uint8(2)).iterations == 2


def test_coordinates_beyond_the_bound_are_refused_naming_the_array_row_and_value():
    vertices, triangles = grid(2)
    vertices[4] = (3e38, 0.0, 0.0)
    with pytest.raises(sk.CoordinateRangeError, match=r"^vertex 4 has a coordinate of 3e38, beyond the kernel's bound"):
        sk.TargetMesh(vertices, triangles)
    points = np.array([[0, 0, 0], [0, np.finfo(np.float32).max, 0]], np.float32)
    with pytest.raises(sk.CoordinateRangeError, match="^point 1 has a coordinate of 3.4028235e38"):
        small_target().closest_points(points)
    assert sk.MAX_COORDINATE == 1e8


@pytest.mark.parametrize(
    ("anchor", "error", "message"),
    [
        ((3.4e38, 0.0, 0.0), sk.CoordinateRangeError, "anchor target 0 has a coordinate of 3.4e38"),
        ((1e30, 0.0, 0.0), sk.CoordinateRangeError, "anchor target 0 has a coordinate of 1e30"),
        ((np.nan, 0.0, 0.0), sk.NonFiniteError, "anchor target 0 has a NaN or infinite coordinate"),
        (
            (0.0, 1e7, 0.0),
            sk.CoordinateRangeError,
            "anchor target 0 is 1e7 from the target's centre, beyond the region",
        ),
    ],
)
def test_an_absurd_space_anchor_is_refused_before_the_wrap(anchor, error, message):
    # The bug: an anchor at 3.4e38 (an infinity clamped by Blender's property) or 1e30 was accepted and the
    # wrap then took 27 s instead of 0.02 s.
    target = plane_target(cells=8, size=0.25)
    positions, face_corners, face_sizes = quad_layout(n=3, size=0.2)
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    with pytest.raises(error, match=message):
        sk.WrapSolver(
            target,
            structure,
            *space_points(len(positions)),
            positions,
            **space_anchor(3, anchor),
        )


def test_a_curve_with_a_nan_point_and_a_bad_state_are_refused():
    with pytest.raises(sk.NonFiniteError, match="^curve point 1 has a NaN"):
        wrap_solver(
            curve_vertices=np.array([4, 5, 6], np.uint32),
            curve_vertex_counts=np.array([3], np.uint32),
            curve_points=np.array([[0, 0, 0], [np.nan, 0, 0]], np.float32),
            curve_point_counts=np.array([2], np.uint32),
        )
    target = plane_target(cells=8, size=0.25)
    positions, face_corners, face_sizes = quad_layout(n=3, size=0.2)
    structure = sk.LayoutStructure(len(positions), face_corners, face_sizes)
    states, triangles, barycentrics, _ = wrap_arrays(len(positions))
    states[2] = 7
    with pytest.raises(sk.InvalidArgumentError, match="layout vertex 2 has state 7"):
        sk.WrapSolver(target, structure, states, triangles, barycentrics, positions)


def test_curve_fractions_of_the_wrong_length_or_outside_0_to_1_are_refused():
    curve = {
        "curve_vertices": np.array([4, 5, 6], np.uint32),
        "curve_vertex_counts": np.array([3], np.uint32),
        "curve_points": np.array([[0, 0, 0], [0.1, 0, 0]], np.float32),
        "curve_point_counts": np.array([2], np.uint32),
    }
    wrap_solver(**curve, curve_fractions=np.array([0.0, 0.5, 1.0], np.float32))
    wrap_solver(**curve, curve_fractions=np.full(3, np.nan, np.float32))  # as spaced
    with pytest.raises(sk.ArrayError, match="curve_fractions has 2 entries for 3 curve_vertices"):
        wrap_solver(**curve, curve_fractions=np.array([0.0, 1.0], np.float32))
    with pytest.raises(sk.InvalidArgumentError, match="curve constraint 0: fraction 1 is 1.5"):
        wrap_solver(**curve, curve_fractions=np.array([0.0, 1.5, 1.0], np.float32))
    with pytest.raises(sk.InvalidArgumentError, match="curve constraint 0: fraction 1 is NaN"):
        wrap_solver(**curve, curve_fractions=np.array([0.0, np.nan, 1.0], np.float32))
