"""Random calls to every function and class of ``springwrap_kernel`` (run by ``test_binding_fuzz.py``).

``python fuzz_calls.py SEED CALLS`` makes CALLS calls with arguments drawn from a catalogue of hostile
values (wrong dtypes, shapes and memory layouts, NaN, infinities, 3.4e38, 1e30, negative and huge
counts, out-of-range indices, wrong Python types, empty arrays) mixed with plausible ones. Every call
must return or raise a ``springwrap_kernel.SpringwrapError``; any other exception is printed and the
script exits 1; an abort kills the process, which the test sees from the exit status. Results of
calls that return are checked: every number of a hit, a position or a transform is finite.
"""

import sys
import traceback

import numpy as np

import springwrap_kernel as sk

F32_MAX = float(np.finfo(np.float32).max)
SPECIAL_FLOATS = [float("nan"), float("inf"), -float("inf"), F32_MAX, -3.4e38, 1e30, 1e39, 1.0000001e8, -0.0, 1e-45]
SPECIAL_INTS = [-1, 0, 2**31 - 1, 2**31, 2**32, 2**40, 2**63, 2**64, -(2**70)]
WRONG_TYPES = [None, "text", b"bytes", [1.0, 2.0], (1, 2, 3), {"a": 1}, object(), True, 1.5j]


class Draw:
    """Hostile and plausible values from one seeded generator."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    def pick(self, items):
        return items[int(self.rng.integers(len(items)))]

    def number(self, low=0.0, high=1.0):
        roll = self.rng.random()
        if roll < 0.7:
            return float(self.rng.uniform(low, high))
        if roll < 0.85:
            return self.pick(SPECIAL_FLOATS)
        if roll < 0.95:
            return self.pick(SPECIAL_INTS)
        return self.pick(WRONG_TYPES)

    def count(self, high=10):
        roll = self.rng.random()
        if roll < 0.75:
            return int(self.rng.integers(0, high + 1))
        if roll < 0.9:
            return self.pick(SPECIAL_INTS)
        return self.pick(WRONG_TYPES + [2.0, np.int64(3), np.float32(2)])

    def flag(self):
        return self.pick([True, False, True, False, np.bool_(True), 1, "yes", None])

    def text(self, choices):
        return self.pick(choices * 4 + ["", "rigid", 3, None])

    def coordinates(self, rows, scale=1.0):
        values = self.rng.uniform(-scale, scale, size=(rows, 3))
        if rows and self.chance(0.25):
            for _ in range(int(self.rng.integers(1, 3))):
                values[self.rng.integers(rows), self.rng.integers(3)] = self.pick(SPECIAL_FLOATS)
        return values

    def array(self, kind, rows=None, columns=3):
        """A float32 (N, columns) or uint32 / int32 / bool (N,) / (N, columns) array, sometimes broken."""
        rows = int(self.rng.integers(0, 12)) if rows is None else rows
        if kind == "points":
            with np.errstate(over="ignore"):
                good = self.coordinates(rows).astype(np.float32)
        elif kind == "indices":
            good = self.rng.integers(0, 12, size=(rows, columns) if columns else rows).astype(np.uint32)
            if good.size and self.chance(0.2):
                good.flat[self.rng.integers(good.size)] = self.pick([2**32 - 1, 2**31, 12, 100])
        elif kind == "signed":
            good = self.rng.integers(-1, 12, size=rows).astype(np.int32)
        elif kind == "flags":
            good = self.rng.random(rows) < 0.3
        else:
            good = self.rng.uniform(0, 1, size=rows).astype(np.float32)
        roll = self.rng.random()
        if roll < 0.8:
            return good
        if roll < 0.85:
            return good.astype(np.float64)
        if roll < 0.89:
            return np.asfortranarray(np.atleast_2d(good)) if good.ndim == 2 else good[::-1]
        if roll < 0.92:
            return good.reshape(-1) if good.ndim == 2 else good.reshape(-1, 1)
        if roll < 0.95:
            return good.tolist()
        return self.pick(WRONG_TYPES)


def finite(*arrays) -> bool:
    return all(np.isfinite(np.asarray(array, dtype=np.float64)).all() for array in arrays)


def check_hits(hits):
    hit = np.asarray(hits.triangles) >= 0
    assert finite(hits.positions[hit], hits.barycentrics[hit], hits.distances[hit]), hits


def good_mesh(draw: Draw):
    """A valid target: a small grid, bent and scaled."""
    size = int(draw.rng.integers(1, 5))
    row = size + 1
    xs, ys = np.meshgrid(np.arange(row), np.arange(row))
    z = draw.rng.uniform(-0.3, 0.3, size=row * row)
    vertices = np.stack([xs.ravel(), ys.ravel(), z], 1).astype(np.float32) * np.float32(draw.rng.uniform(0.1, 2))
    corner = (np.arange(size)[None] + row * np.arange(size)[:, None]).ravel()
    triangles = np.concatenate(
        [np.stack([corner, corner + 1, corner + row + 1], 1), np.stack([corner, corner + row + 1, corner + row], 1)]
    ).astype(np.uint32)
    return sk.TargetMesh(vertices, triangles), vertices


def call_target_mesh(draw):
    if draw.chance(0.5):
        vertices = draw.array("points")
        triangles = draw.array("indices", columns=3)
    else:
        mesh, vertices = good_mesh(draw)
        vertices = draw.array("points", rows=len(vertices)) if draw.chance(0.3) else vertices
        triangles = mesh.triangles()
    mesh = sk.TargetMesh(vertices, triangles, reject_degenerate=draw.flag())
    assert finite(mesh.bounding_box(), mesh.face_normals(), mesh.vertex_normals())
    mesh.prepare_all()


def call_queries(draw):
    mesh, _ = good_mesh(draw)
    method = draw.pick(["closest", "nearest", "ray", "face_points"])
    if method == "closest":
        check_hits(mesh.closest_points(draw.array("points"), max_distance=draw.number(0, 5)))
    elif method == "nearest":
        check_hits(mesh.nearest_vertices(draw.array("points"), max_distance=draw.number(0, 5)))
    elif method == "ray":
        rows = int(draw.rng.integers(0, 8))
        check_hits(
            mesh.ray_cast(
                draw.array("points", rows),
                draw.array("points", rows if draw.chance(0.9) else rows + 1),
                max_distance=draw.number(0, 5),
                both_directions=draw.flag(),
            )
        )
    else:
        rows = int(draw.rng.integers(0, 8))
        triangles = draw.array("indices", rows, columns=None)
        barycentrics = draw.rng.dirichlet([1, 1, 1], size=rows).astype(np.float32) if draw.chance(0.7) else None
        barycentrics = draw.array("points", rows) if barycentrics is None else barycentrics
        assert finite(mesh.face_point_positions(triangles, barycentrics))


def call_icp(draw):
    mesh, vertices = good_mesh(draw)
    source = vertices[: int(draw.rng.integers(0, len(vertices) + 1))] + np.float32(0.05)
    source = draw.array("points") if draw.chance(0.2) else np.ascontiguousarray(source, np.float32)
    initial = None
    if draw.chance(0.5):
        initial = np.eye(4)
        initial[:3, 3] = draw.rng.uniform(-0.1, 0.1, 3)
        if draw.chance(0.2):
            initial[draw.rng.integers(4), draw.rng.integers(4)] = draw.pick(SPECIAL_FLOATS + [1e12])
        if draw.chance(0.05):
            initial = draw.pick([np.eye(3), np.eye(4, dtype=np.float32), "identity", np.eye(4)[::-1]])
    options = {}
    for name, value in [
        ("update", lambda: draw.text(["RIGID", "SIMILARITY"])),
        ("max_iterations", lambda: draw.count(20)),
        ("trim_fraction", lambda: draw.number(0, 0.5)),
        ("max_distance", lambda: draw.number(0.01, 3)),
        ("tolerance", lambda: draw.number(0, 1e-3)),
        ("ignore_boundary", draw.flag),
        ("anchor_weight", lambda: draw.number(0, 2)),
    ]:
        if draw.chance(0.3):
            options[name] = value()
    if draw.chance(0.3):
        rows = int(draw.rng.integers(0, 5))
        options["anchor_source"] = draw.array("points", rows)
        options["anchor_target"] = draw.array("points", rows if draw.chance(0.9) else rows + 1)
    report = mesh.icp(source, initial, **options)
    assert finite(report.matrix, report.rms_before, report.rms_after), report


def call_features(draw):
    mesh, _ = good_mesh(draw)
    scale = draw.number(0.05, 1.5)
    if draw.chance(0.3):
        curvatures = mesh.principal_curvatures(scale)
        assert finite(*curvatures)
        return
    options = {}
    for name in ("flat_threshold", "ridge_threshold", "min_length", "join_distance"):
        if draw.chance(0.3):
            options[name] = draw.number(0, 0.5)
    features = mesh.detect_features(scale, **options)
    assert finite(*features.curvatures) and all(finite(curve.points) for curve in features.curves)


def layout_arrays(draw, size):
    row = size + 1
    corner = (np.arange(size)[None] + row * np.arange(size)[:, None]).ravel()
    corners = np.stack([corner, corner + 1, corner + row + 1, corner + row], 1).astype(np.uint32).ravel()
    return row * row, corners, np.full(size * size, 4, np.uint32)


def call_layout_structure(draw):
    if draw.chance(0.5):
        count, corners, sizes = layout_arrays(draw, int(draw.rng.integers(1, 4)))
        count = draw.count(30) if draw.chance(0.3) else count
    else:
        count, corners, sizes = draw.count(12), draw.array("indices", columns=None), draw.array("indices", columns=None)
    options = {}
    if draw.chance(0.3):
        options["edges"] = draw.array("indices", columns=2)
    if draw.chance(0.2):
        options["seams"] = draw.array("indices", columns=2)
    structure = sk.LayoutStructure(count, corners, sizes, **options)
    structure.line_triples(), structure.corners(), structure.extraordinary(), structure.curves()


def settings(draw):
    names = ["fairness", "arc_length", "thin_plate", "constraint", "folding", "tolerance", "landing_distance"]
    names += ["fold_tolerance"]
    options = {name: draw.number(0, 0.5) for name in names if draw.chance(0.15)}
    if draw.chance(0.2):
        options["schedule"] = draw.text(["AUTO", "LOCAL", "GLOBAL_TO_LOCAL"])
    return sk.WrapSettings(**options)


def call_wrap_settings(draw):
    value = settings(draw)
    assert value == sk.WrapSettings(**value.to_dict())
    if draw.chance(0.5):
        value.replace(**{draw.pick(["fairness", "folding", "tolerance", "schedule"]): draw.number(0, 1)})


def call_wrap(draw):
    mesh, vertices = good_mesh(draw)
    size = int(draw.rng.integers(1, 4))
    count, corners, sizes = layout_arrays(draw, size)
    structure = sk.LayoutStructure(count, corners, sizes)
    low, high = (np.array(corner, np.float32) for corner in mesh.bounding_box())
    grid = np.linspace(0.1, 0.9, size + 1, dtype=np.float32)
    xs, ys = np.meshgrid(grid, grid)
    positions = np.stack([xs.ravel(), ys.ravel(), np.full(count, 0.5, np.float32)], 1)
    positions = (low + positions * (high - low + np.float32(0.1))).astype(np.float32)
    if draw.chance(0.2):
        positions = draw.array("points", rows=count if draw.chance(0.9) else count + 1)
    states = np.zeros(count, np.int32)
    triangles = np.full(count, -1, np.int32)
    barycentrics = np.zeros((count, 3), np.float32)
    if draw.chance(0.2):
        states, triangles = draw.array("signed", count), draw.array("signed", count)
    options = {}
    if draw.chance(0.4):
        rows = int(draw.rng.integers(0, 4))
        options.update(
            anchor_vertices=draw.array("indices", rows, columns=None),
            anchor_triangles=draw.array("signed", rows),
            anchor_barycentrics=draw.rng.dirichlet([1, 1, 1], size=rows).astype(np.float32),
            anchor_positions=draw.array("points", rows),
        )
        if draw.chance(0.1):
            del options["anchor_positions"]
    if draw.chance(0.2):
        options.update(
            curve_vertices=draw.array("indices", 3, columns=None),
            curve_vertex_counts=np.array([draw.pick([3, 2, 0, 2**32 - 1])], np.uint32),
            curve_points=draw.array("points", 2),
            curve_point_counts=np.array([2], np.uint32),
        )
    if draw.chance(0.2):
        options.update(
            plane_vertices=draw.array("indices", 2, columns=None),
            plane_point=draw.pick([(0.5, 0.5, 0.0), (0.0, 1e30, 0.0), "xyz", (1.0,), None]),
            plane_normal=draw.pick([(1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (float("nan"), 0, 0), [0, 1, 0]]),
            plane_slide=draw.flag(),
        )
    for name, kind in [("rest_positions", "points"), ("unreliable_triangles", "flags"), ("stiffness", "floats")]:
        if draw.chance(0.1):
            options[name] = draw.array(kind, count if draw.chance(0.8) else None)
    if draw.chance(0.1):
        options["free_vertices"] = draw.array("flags", count)
    if draw.chance(0.5):
        options["settings"] = settings(draw) if draw.chance(0.9) else draw.pick(WRONG_TYPES)
    solver = sk.WrapSolver(mesh, structure, states, triangles, barycentrics, positions, **options)
    for _ in range(int(draw.rng.integers(1, 3))):
        try:
            solver.step(draw.count(4))
        finally:
            assert finite(solver.positions()), solver.positions()
    assert finite(solver.states()[2])


def call_fit_transform(draw):
    rows = int(draw.rng.integers(0, 7))
    source = draw.array("points", rows)
    target = draw.array("points", rows if draw.chance(0.9) else rows + 1)
    options = {"weights": draw.array("floats", rows)} if draw.chance(0.3) else {}
    method = draw.text(["RIGID", "SIMILARITY", "AFFINE"])
    matrix = sk.fit_transform(source, target, method, **options)
    assert finite(matrix), matrix


CALLS = [
    call_target_mesh,
    call_queries,
    call_icp,
    call_features,
    call_layout_structure,
    call_wrap_settings,
    call_wrap,
    call_fit_transform,
]


def main(seed: int, calls: int) -> int:
    draw = Draw(seed)
    outcomes = {}
    for number in range(calls):
        call = CALLS[number % len(CALLS)]
        try:
            call(draw)
            outcome = "ok"
        except sk.SpringwrapError as error:
            outcome = type(error).__name__
        except Exception:  # noqa: BLE001 (any other exception is the finding: reported, exit 1)
            print(f"call {number} ({call.__name__}) raised outside the module's errors:", file=sys.stderr)
            traceback.print_exc()
            return 1
        outcomes[(call.__name__, outcome)] = outcomes.get((call.__name__, outcome), 0) + 1
    for (name, outcome), count in sorted(outcomes.items()):
        print(f"{name} {outcome} {count}")
    return 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]), int(sys.argv[2])))
