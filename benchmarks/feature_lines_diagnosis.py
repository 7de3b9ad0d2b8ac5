"""Where the feature-lines benchmark's crease error comes from: one line per target and anchor count.

    .venv/bin/python benchmarks/feature_lines_diagnosis.py --off fandisk.off [--anchors 8 24]

The scene is ``feature_lines.py``'s (its layout, targets, anchors and truth); each case runs its *with* row (two
wraps, Pair Feature Lines at its defaults between them) with the pairing's internals recorded. For the paired
crease vertices, in % of the target's diagonal (mean; *along* the crease at the true place, as the benchmark splits
it): where the placement puts them (**placed**: the wrap puts each paired vertex there); where the true place
projected onto the same stretch of target curve would put them (**floor**: what a perfect map would give, the
target curve's own error); where the first wrap's fit projected onto it puts them (**fit**: placing by the wrap's
sliding); and, for the lines between two matched corners, sharing out the curve between the corners' true places
by the true arc length (**true arc**: the error of the target curve's arc length as a parameter, which a zig-zag of
its points stretches); and where the map's places go when shifted along the stretch (by at most 3 % of it) so that
the line's turning profile (how fast its rest shape turns, smoothed over two of its edges) lines up with the curve's
(**shape warp**: more matched points from the crease's own shape), with how far it shifts them against how far the
true places lie from the map's (mean, fraction of the stretch) and how the two shifts correlate; and where the map
refitted with one more matched point per line (of 5 vertices or more; its middle vertex at its true place) puts them
(**middle known**: what a perfect extra point per line would give). The target curves' zig-zag: their arc length over that of every fourth point (median,
paired curves). And the crease vertices left unpaired: how many and their share of the crease error, by why
(a free line, by reason; a line's end, a corner; on no line).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY))
sys.path.insert(0, str(REPOSITORY / "blender_scripts"))

from benchmarks import feature_lines as bench  # noqa: E402 - after the path is set
from benchmarks.feature_detection import read_off  # noqa: E402


def arc_inflation(points, step: int = 4) -> float:
    """A polyline's arc length over the length of every ``step``-th of its points (the last kept): 1 for points
    in a straight or gently bending row, more where they zig-zag at a finer scale than ``step`` points."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if points.shape[0] < 2:
        return 1.0
    coarse = np.concatenate([points[::step], points[-1:]]) if (points.shape[0] - 1) % step else points[::step]
    chord = np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum()
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum() / chord) if chord > 0.0 else 1.0


def nearest_on_polyline(polyline, points):
    """(near (P, S, 3), t (P, S), nearest (P,)): for each of ``points``, the nearest point of every segment of the
    polyline ((K, 3), K >= 2, S = K - 1 segments), where along its segment it lies (0..1), and the nearest segment."""
    polyline = np.asarray(polyline, dtype=np.float64).reshape(-1, 3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    starts, direction = polyline[:-1], np.diff(polyline, axis=0)
    squared = np.maximum((direction**2).sum(axis=1), 1e-300)
    t = np.clip(np.einsum("psk,sk->ps", points[:, None, :] - starts[None], direction) / squared, 0.0, 1.0)
    near = starts[None] + t[..., None] * direction[None]
    return near, t, np.argmin(np.linalg.norm(near - points[:, None, :], axis=2), axis=1)


def projected(polyline, points) -> np.ndarray:
    """(P, 3): each of ``points`` taken to the nearest point of the polyline ((K, 3), K >= 2)."""
    near, _t, nearest = nearest_on_polyline(polyline, points)
    return near[np.arange(len(nearest)), nearest]


def turning_profile(points, samples: int, sigma: float) -> np.ndarray:
    """(samples,): how fast a polyline ((K, 3), K >= 2) turns, in radians per fraction of its length, at ``samples``
    points evenly spaced along it, after a Gaussian smoothing of ``sigma`` (a length) of its points (a zig-zag
    finer than that does not count; the ends continued by reflection through the end point, which straightens the
    last three ``sigma``)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    cumulative = lengths(points)
    even = np.linspace(0.0, cumulative[-1], samples)
    resampled = np.stack([np.interp(even, cumulative, points[:, axis]) for axis in range(3)], axis=1)
    spread = sigma / (cumulative[-1] / (samples - 1))
    reach = min(int(3.0 * spread) + 1, samples - 1)
    if spread > 0.0:
        padded = np.concatenate(
            [
                2.0 * resampled[0] - resampled[1 : reach + 1][::-1],
                resampled,
                2.0 * resampled[-1] - resampled[-reach - 1 : -1][::-1],
            ]
        )
        weights = np.exp(-0.5 * (np.arange(-reach, reach + 1) / spread) ** 2)
        weights /= weights.sum()
        resampled = np.stack([np.convolve(padded[:, axis], weights, mode="valid") for axis in range(3)], axis=1)
    tangent = np.gradient(resampled, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)[:, None]
    return np.linalg.norm(np.gradient(tangent, axis=0), axis=1) * (samples - 1)


def shape_warp(profile, target_profile, guess, band: float, keep: float, stiffness: float, steps: int = 41):
    """(S,): the fraction along the target curve for each of a line's ``profile`` samples ((S,) evenly spaced on the
    line; ``target_profile`` (T,) evenly spaced on the curve, both :func:`turning_profile`): the ``guess`` ((S,)
    fractions, the map's) shifted by at most ``band`` so that the two profiles agree, at a cost ``keep`` for a shift of
    the whole band and ``stiffness`` for a change of it by the whole band from one sample to the next (dynamic
    programming over ``steps`` shifts)."""
    shifts = np.linspace(-band, band, steps)
    along = np.clip(np.asarray(guess)[:, None] + shifts[None, :], 0.0, 1.0)
    target = np.interp(along, np.linspace(0.0, 1.0, np.size(target_profile)), target_profile)
    cost = (np.asarray(profile)[:, None] - target) ** 2 + keep * (shifts[None, :] / band) ** 2
    change = stiffness * ((shifts[:, None] - shifts[None, :]) / band) ** 2
    total, back = cost[0].copy(), np.zeros(cost.shape, dtype=np.int64)
    for row in range(1, cost.shape[0]):
        options = total[:, None] + change
        back[row] = np.argmin(options, axis=0)
        total = cost[row] + options[back[row], np.arange(steps)]
    path = [int(np.argmin(total))]
    for row in range(cost.shape[0] - 1, 0, -1):
        path.append(int(back[row, path[-1]]))
    return np.asarray(guess) + shifts[np.array(path[::-1])]


SHAPE_SAMPLES = 150
SHAPE_SETTINGS = {"sigma_edges": 2.0, "band": 0.03, "keep": 0.01, "stiffness": 1.0}
"""The shape warp's smoothing (in the line's mean edge lengths), band (a fraction of the curve) and costs."""


def shape_fractions(chain_rest, curve_points, fractions) -> np.ndarray:
    """(C,): a paired chain's ``fractions`` (the map's, along ``curve_points``) shifted by :func:`shape_warp` to line
    up the turning profiles of its rest points ``chain_rest`` ((C, 3)) and of the curve."""
    chain_rest = np.asarray(chain_rest, dtype=np.float64).reshape(-1, 3)
    rest_lengths = lengths(chain_rest)
    sigma = SHAPE_SETTINGS["sigma_edges"] * rest_lengths[-1] / (chain_rest.shape[0] - 1)
    profile = turning_profile(chain_rest, SHAPE_SAMPLES, sigma)
    target = turning_profile(curve_points, 4 * SHAPE_SAMPLES, sigma)
    even, rest_fractions = np.linspace(0.0, 1.0, SHAPE_SAMPLES), rest_lengths / rest_lengths[-1]
    guess = np.interp(even, rest_fractions, fractions)
    settings = {key: value for key, value in SHAPE_SETTINGS.items() if key != "sigma_edges"}
    warped = shape_warp(profile, target, guess, **settings)
    return np.clip(np.maximum.accumulate(fractions + np.interp(rest_fractions, even, warped - guess)), 0.0, 1.0)


def projected_fractions(polyline, points) -> np.ndarray:
    """(P,): where along the polyline ((K, 3), K >= 2) the point of it nearest each of ``points`` lies, as a fraction
    of its length."""
    polyline = np.asarray(polyline, dtype=np.float64).reshape(-1, 3)
    _near, t, nearest = nearest_on_polyline(polyline, points)
    cumulative = lengths(polyline)
    rows = np.arange(len(nearest))
    along = cumulative[nearest] + t[rows, nearest] * (cumulative[nearest + 1] - cumulative[nearest])
    return along / cumulative[-1]


def lengths(points) -> np.ndarray:
    """(K,): the arc length of the polyline ``points`` ((K, 3)) up to each of its points."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def shares(errors, groups: dict) -> dict:
    """``{label: (count, share of the errors' sum)}`` for each boolean mask of ``groups`` over ``errors``."""
    total = float(np.sum(errors))
    return {
        label: (int(mask.sum()), float(errors[mask].sum() / total) if total else 0.0) for label, mask in groups.items()
    }


def record_pairing(store: dict):
    """Wrap ``core.feature_lines.pair_lines`` so that each call's inputs and result land in ``store``."""
    from springwrap.core import feature_lines as core

    original = core.pair_lines

    def recording(lines, current, curves_found, anchored, existing, max_distance, **keywords):
        result = original(lines, current, curves_found, anchored, existing, max_distance, **keywords)
        store.update(
            lines=lines, current=np.array(current), curves=curves_found, anchored=np.array(anchored), result=result
        )
        store.update(junctions=dict(keywords.get("junctions") or {}), rest=keywords.get("rest"))
        store.update(mapping=result.mapping)
        return result

    core.pair_lines = recording


def along(scene, vertices, placed) -> float:
    """The mean along-the-crease error (% of the diagonal) of ``placed`` ((C, 3)) for crease ``vertices``."""
    _target, _rest, _quads, truth, on_surface, _crease, diagonal, segments = scene
    error, _across = bench.along_and_across(placed - on_surface[vertices], truth[vertices], segments)
    return float(error.mean() / diagonal * 100.0)


def diagnose(anchors: int, scene, store: dict) -> dict:
    """One case's measures (see the module docs)."""
    import bpy

    from benchmarks.retarget.baselines import mesh_object, read_positions
    from benchmarks.retarget.springwrap_methods import _add_anchors, _call, _select_only
    from springwrap.core import curves
    from springwrap.core.edge_paths import length_fractions

    target, rest, quads, truth, on_surface, crease, diagonal, _segments = scene
    layout = mesh_object(f"Diagnosis {anchors}", rest, quads)
    layout.springwrap.target = target
    _select_only(layout)
    chosen = bench.farthest_points(rest, anchors)
    _call("detach", bpy.ops.springwrap.detach, only_selected=False)
    _add_anchors(layout, chosen, on_surface[chosen])
    _call("wrap", bpy.ops.springwrap.wrap)
    first = read_positions(layout.data)
    store.clear()
    _call("feature_lines_pair", bpy.ops.springwrap.feature_lines_pair)
    _call("wrap", bpy.ops.springwrap.wrap)
    result = read_positions(layout.data)
    bpy.data.objects.remove(layout)
    constraints = store["result"].constraints
    chains = [c.layout_vertices[crease[c.layout_vertices]] for c in constraints]
    placed = [curves.arc_length_points(store["current"][c.layout_vertices], c.points, c.fractions) for c in constraints]
    rows = [crease[c.layout_vertices] for c in constraints]
    vertices = np.concatenate(chains)
    measures = {
        "placed": along(scene, vertices, np.concatenate([p[r] for p, r in zip(placed, rows)])),
        "floor": along(
            scene, vertices, np.concatenate([projected(c.points, on_surface[v]) for c, v in zip(constraints, chains)])
        ),
        "fit": along(
            scene, vertices, np.concatenate([projected(c.points, first[v]) for c, v in zip(constraints, chains)])
        ),
    }
    shaped, shifts, true_shifts = [], [], []
    for c, p, r in zip(constraints, placed, rows):
        if len(c.fractions) == 0 or c.layout_vertices.size < 5:
            shaped.append(p[r])
            continue
        fractions = shape_fractions(scene[1][c.layout_vertices], c.points, c.fractions)
        shaped.append(curves.arc_length_points(p, c.points, fractions)[r])
        shifts.append(fractions - c.fractions)
        true_shifts.append(projected_fractions(c.points, on_surface[c.layout_vertices]) - c.fractions)
    measures["shape warp"] = along(scene, vertices, np.concatenate(shaped))
    if store["mapping"] is not None:
        measures["middle known"] = along(scene, vertices, middle_known(store, scene, constraints, placed, rows))
    shift, true_shift = np.concatenate(shifts), np.concatenate(true_shifts)
    shape = {"correlation": float(np.corrcoef(shift, true_shift)[0, 1]), "shift": float(np.abs(shift).mean())}
    shape["true shift"] = float(np.abs(true_shift).mean())
    junctions, arc_vertices, arc_placed = store["junctions"], [], []
    for line in store["lines"]:
        ends = (int(line.vertices[0]), int(line.vertices[-1]))
        inner = line.vertices[1:-1][crease[line.vertices[1:-1]]]
        constraint = next((c for c in constraints if np.isin(inner, c.layout_vertices).all()), None)
        if line.closed or not all(end in junctions for end in ends) or inner.size == 0 or constraint is None:
            continue
        curve = containing_curve(store["curves"], constraint.points, 1e-6 * diagonal)
        stretch = bench_stretch(curve, on_surface[ends[0]], on_surface[ends[1]])
        fractions = length_fractions(truth[line.vertices])[np.isin(line.vertices, inner)]
        arc_vertices.append(inner)
        arc_placed.append(curves.arc_length_points(np.zeros((fractions.size, 3)), stretch, fractions))
    if arc_vertices:
        measures["true arc"] = along(scene, np.concatenate(arc_vertices), np.concatenate(arc_placed))
    inflation = [arc_inflation(c.points) for c in constraints if c.points.shape[0] > 8]
    errors = np.linalg.norm(result - on_surface, axis=1) / diagonal * 100.0
    paired = np.zeros(rest.shape[0], dtype=bool)
    paired[np.concatenate([c.layout_vertices for c in constraints])] = True
    free = crease & ~paired & ~store["anchored"]
    groups, on_line, line_ends = {}, np.zeros_like(free), np.zeros_like(free)
    for line in store["lines"]:
        on_line[line.vertices] = True
        if not line.closed:
            line_ends[[line.vertices[0], line.vertices[-1]]] = True
    for line, reason in store["result"].free:
        mask = np.zeros_like(free)
        mask[line.vertices] = True
        groups[reason] = groups.get(reason, np.zeros_like(free)) | (mask & free & ~line_ends)
    groups["line end"] = free & line_ends
    groups["on no line"] = free & ~on_line
    return {
        "anchors": anchors,
        "crease": float(errors[crease].mean()),
        "along": measures,
        "inflation": float(np.median(inflation)) if inflation else None,
        "shape": shape,
        "unpaired": shares(errors[crease], {label: mask[crease] for label, mask in groups.items()}),
    }


def middle_known(store: dict, scene, constraints, placed, rows) -> np.ndarray:
    """The crease rows of the paired chains placed by the map refitted with one more matched point per mapped chain
    of 5 vertices or more: its middle vertex at its true place (what a perfect extra point per line would give)."""
    from springwrap.core import curves, smooth_map

    rest, on_surface, mapping = scene[1], scene[4], store["mapping"]
    middles = [int(c.layout_vertices[c.layout_vertices.size // 2]) for c in constraints if len(c.fractions) >= 5]
    refitted = smooth_map.fit(
        np.concatenate([mapping.centres, rest[middles]]),
        np.concatenate([smooth_map.apply(mapping, mapping.centres), on_surface[middles]]),
        degree=mapping.degree,
    )
    return np.concatenate(
        [
            (
                p
                if len(c.fractions) == 0
                else curves.arc_length_points(
                    p, c.points, smooth_map.placements(refitted, rest[c.layout_vertices], c.points)
                )
            )[r]
            for c, p, r in zip(constraints, placed, rows)
        ]
    )


def containing_curve(found, points, tolerance: float) -> np.ndarray:
    """The points of the first of ``found`` (the pairing's target curves) on which all ``points`` lie."""
    for _kind, curve, *_rest in found:
        curve = np.asarray(curve, dtype=np.float64).reshape(-1, 3)
        if curve.shape[0] >= 2 and np.linalg.norm(projected(curve, points) - points, axis=1).max() <= tolerance:
            return curve
    raise ValueError("no target curve holds the stretch")


def bench_stretch(curve, start, end) -> np.ndarray:
    """The stretch of the open polyline ``curve`` between the points nearest ``start`` and ``end``."""
    from springwrap.core import line_placement as placement
    from springwrap.core.edge_paths import cumulative_lengths

    curve = np.asarray(curve, dtype=np.float64).reshape(-1, 3)
    cumulative = cumulative_lengths(curve)
    begin = placement.parameter(curve, cumulative, np.asarray(start, dtype=np.float64))[0]
    finish = placement.parameter(curve, cumulative, np.asarray(end, dtype=np.float64))[0]
    return placement.piece(curve, cumulative, begin, finish)


def main(argv: list[str] | None = None) -> int:
    import bpy

    import headless
    import springwrap_kernel

    parser = argparse.ArgumentParser(prog="feature_lines_diagnosis.py", description=__doc__.splitlines()[0])
    parser.add_argument("--off", type=Path, required=True)
    parser.add_argument("--anchors", nargs="+", type=int, default=[8, 24])
    parser.add_argument(
        "--tessellations", nargs="+", choices=sorted(bench.TESSELLATIONS), default=list(bench.TESSELLATIONS)
    )
    arguments = parser.parse_args(argv)
    headless.enable_addon()
    store: dict = {}
    record_pairing(store)
    bpy.ops.wm.read_homefile(use_empty=True)
    vertices, triangles = read_off(arguments.off)
    rest, quads = bench.make_layout(vertices, triangles, 3000)
    bounds = (vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64))
    edges = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    layout_edge = float(np.median(np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)))
    segments = bench.sharp_segments(vertices.astype(np.float64), triangles.astype(np.int64))
    for tessellation in arguments.tessellations:
        target = bench.changed_target(
            f"Target {tessellation}", vertices.astype(np.float64), triangles.astype(np.int64), bounds, tessellation
        )
        truth = bench.design_change(rest, *bounds)
        crease = bench.distance_to_segments(rest, segments) < 0.1 * layout_edge
        target_vertices, target_triangles = bench.target_arrays(target)
        diagonal = float(np.linalg.norm(np.ptp(target_vertices, axis=0)))
        changed = bench.design_change(segments.reshape(-1, 3), *bounds).reshape(-1, 2, 3)
        mesh = springwrap_kernel.TargetMesh(target_vertices, target_triangles)
        on_surface = mesh.closest_points(np.ascontiguousarray(truth, dtype=np.float32)).positions.astype(np.float64)
        scene = (target, rest, quads, truth, on_surface, crease, diagonal, changed)
        for count in arguments.anchors:
            found = diagnose(count, scene, store)
            split = ", ".join(f"{label} {value:.3f}" for label, value in found["along"].items())
            unpaired = ", ".join(
                f"{label} {n} ({100 * share:.0f} %)" for label, (n, share) in found["unpaired"].items() if n
            )
            print(
                f"{tessellation} {count}: crease {found['crease']:.3f}; paired vertices along: {split}; "
                f"curves' zig-zag {found['inflation']:.4f}; shape warp's shift (fraction of the stretch) "
                f"{found['shape']['shift']:.4f} against the true {found['shape']['true shift']:.4f}, correlation "
                f"{found['shape']['correlation']:+.2f}; unpaired: {unpaired}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
