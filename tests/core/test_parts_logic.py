"""Parts on arrays (``addon/springwrap/core/parts.py``): pieces, the guess of which pieces the target's surface does
not need, rigid or soft, the groups' overrides, the follower, the read-out of the surface alone. No Blender."""

import numpy as np
import pytest

from helpers import core_module

parts = core_module("parts")
target_module = core_module("target")
subdivision = core_module("subdivision")
errors = core_module("errors")
part_registration = core_module("part_registration")


def cube_sphere(n, radius, centre=(0.0, 0.0, 0.0)):
    """A closed quad sphere (each cube face n x n), (V, 3) float64 and (F, 4) quads."""
    steps = np.linspace(-1.0, 1.0, n + 1)
    points, quads = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            u, v = np.meshgrid(steps, steps, indexing="ij")
            face = np.zeros((n + 1, n + 1, 3))
            face[..., axis], face[..., (axis + 1) % 3], face[..., (axis + 2) % 3] = sign, u, v * sign
            base = sum(len(block) for block in points)
            points.append(face.reshape(-1, 3))
            index = base + np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
            quads.append(np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4))
    vertices, faces = np.concatenate(points), np.concatenate(quads)
    _unique, first, inverse = np.unique(np.round(vertices * n * 4), axis=0, return_index=True, return_inverse=True)
    vertices, faces = vertices[first], inverse.reshape(-1)[faces]
    vertices = vertices / np.linalg.norm(vertices, axis=1, keepdims=True) * radius + np.asarray(centre)
    return vertices, faces


def topology_of(pieces):
    """(positions, LayoutTopology) of quad pieces ((V, 3), (F, 4)) put one after another."""
    positions, quads, offset = [], [], 0
    for vertices, faces in pieces:
        positions.append(vertices)
        quads.append(faces + offset)
        offset += len(vertices)
    quads = np.concatenate(quads)
    edges = np.unique(np.sort(np.concatenate([quads[:, [i, (i + 1) % 4]] for i in range(4)]), axis=1), axis=0)
    topology = subdivision.LayoutTopology(
        offset,
        quads.reshape(-1).astype(np.uint32),
        np.full(len(quads), 4, np.uint32),
        edges.astype(np.uint32),
        np.zeros((0, 2), np.uint32),
    )
    return np.concatenate(positions), topology


def target_sphere(radius=1.5):
    vertices, faces = cube_sphere(24, radius)
    triangles = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    return target_module.CentredMesh(vertices, np.ascontiguousarray(triangles, dtype=np.uint32))


def strip(length=0.4, width=0.05, centre=(0.0, 0.0, 1.6)):
    """An open strip of 8 x 1 quads (lashes), in front of the sphere's top."""
    xs = np.linspace(-length / 2, length / 2, 9)
    vertices = np.concatenate([np.stack([xs, np.full(9, y), np.zeros(9)], 1) for y in (0.0, width)])
    vertices += np.asarray(centre)
    faces = np.array([[i, i + 1, i + 10, i + 9] for i in range(8)])
    return vertices, faces


def test_pieces_inside_and_in_front_are_guessed_and_a_second_skin_is_not():
    body = cube_sphere(8, 1.5)  # on the target
    ball = cube_sphere(3, 0.3, (0.4, 0.0, 0.3))
    lashes = strip()
    other_side = cube_sphere(3, 0.5, (0.0, 0.0, -4.0))  # a piece with its own part of the target
    target = target_sphere()
    island, island_faces = cube_sphere(6, 0.6, (0.0, 0.0, -4.0))
    island_triangles = np.concatenate([island_faces[:, [0, 1, 2]], island_faces[:, [0, 2, 3]]])
    far_target = target_module.CentredMesh(
        np.concatenate([target.vertices(), island]),
        np.concatenate([target.triangles(), len(target.vertices()) + island_triangles]).astype(np.uint32),
    )
    positions, topology = topology_of([body, ball, lashes, other_side])
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, far_target)
    sizes = [len(piece[0]) for piece in (body, ball, lashes, other_side)]
    bounds = np.cumsum([0, *sizes])
    assert not plan.parts[: bounds[1]].any()
    assert plan.parts[bounds[1] : bounds[3]].all()
    assert not plan.parts[bounds[3] :].any()
    assert not plan.soft[bounds[1] : bounds[2]].any() and plan.soft[bounds[2] : bounds[3]].all()
    assert [(row.mode, row.reason) for row in plan.rows] == [("rigid", "found"), ("soft", "found")]
    assert "Parts: 2 pieces" in parts.report_text(plan)
    # Find Parts off: nothing; the Surface group keeps a piece wrapped; Follow Soft makes the ball soft.
    assert not parts.plan_parts("Layout", positions, topology, parts.PartGroups(), False, far_target).any
    surface = np.zeros(len(positions), bool)
    surface[bounds[1]] = True
    kept = parts.plan_parts("Layout", positions, topology, parts.PartGroups(surface=surface), True, far_target)
    assert not kept.parts[bounds[1] : bounds[2]].any() and kept.parts[bounds[2] : bounds[3]].all()
    soft = np.zeros(len(positions), bool)
    soft[bounds[1] : bounds[2]] = True
    bent = parts.plan_parts("Layout", positions, topology, parts.PartGroups(soft=soft), False)
    assert bent.soft[bounds[1] : bounds[2]].all() and bent.rows[0].reason == "Follow group"
    # A pinned piece (an anchor on it) is never guessed.
    pinned = np.zeros(len(positions), bool)
    pinned[bounds[1]] = True
    anchored = parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, far_target, pinned)
    assert not anchored.parts[bounds[1] : bounds[2]].any()


def dented(vertices, floor=1.2):
    """``vertices`` with the cap above ``floor`` pushed in through it (a pocket: the mouth behind the lips)."""
    vertices = np.array(vertices)
    cap = vertices[:, 2] > floor
    vertices[cap, 2] = 2.0 * floor - vertices[cap, 2]
    return vertices, cap


def test_the_surface_the_target_does_not_show_is_not_pulled():
    sphere, quads = cube_sphere(12, 1.5)
    body, cap = dented(sphere)
    ball = cube_sphere(3, 0.3, (0.0, 0.0, 0.45))  # under the pocket's floor (at 0.9), within its own radius
    target = target_sphere()
    positions, topology = topology_of([(body, quads), ball])
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, target)
    assert plan.parts[len(body) :].all() and not plan.parts[: len(body)].any()
    unseen = plan.unseen[: len(body)]
    # The pocket's floor beside the ball is hidden deep inside the target; the skin on the target is seen.
    beside = np.linalg.norm(body - (0.0, 0.0, 0.45), axis=1) < 0.3 + 0.25  # within the ball's radius of it
    deep = cap & (body[:, 2] < 1.0) & beside
    assert deep.any() and unseen[deep].all()
    assert not unseen[~cap].any() and not unseen[~beside].any() and not plan.unseen[len(body) :].any()
    assert "surface vertices the target does not show" in parts.report_text(plan)
    # Every face turned inwards: the whole surface faces away from the target, whose normals are then doubted.
    flipped = topology_of([(body, quads[:, ::-1]), ball])[1]
    turned = parts.plan_parts("Layout", positions, flipped, parts.PartGroups(), True, target).unseen
    assert turned is not None and not turned.any()
    # Without parts, the surface is wrapped as it was: nothing is left out for being unseen.
    assert parts.plan_parts("Layout", positions, topology, parts.PartGroups(), False, target).unseen is None
    # An anchored vertex is pulled wherever it is.
    pinned = np.zeros(len(positions), bool)
    pinned[np.flatnonzero(deep)[0]] = True
    held = parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, target, pinned)
    assert not held.unseen[pinned].any() and held.unseen[: len(body)][deep & ~pinned[: len(body)]].all()


def test_the_surface_facing_away_from_the_target_is_not_pulled():
    sphere, quads = cube_sphere(12, 1.5)
    ball = cube_sphere(3, 0.3, (0.0, 0.0, 1.0))  # just under the patch
    # A patch of the skin folded over (its faces turned inwards) while lying on the target: it faces away.
    turned = np.isin(quads, np.flatnonzero(sphere[:, 2] > 1.3)).all(axis=1)
    faces = np.where(turned[:, None], quads[:, ::-1], quads)
    positions, topology = topology_of([(sphere, faces), ball])
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, target_sphere())
    inner = np.zeros(len(positions), bool)
    inner[np.unique(quads[turned])] = True
    inner[np.unique(quads[~turned])] = False  # the patch's rim is shared with the skin facing out
    inner &= np.concatenate(
        [np.linalg.norm(sphere - (0.0, 0.0, 1.0), axis=1) < 0.3 + 0.25, np.zeros(len(ball[0]), bool)]
    )
    assert inner.any() and plan.unseen[inner].all()
    assert plan.unseen.sum() <= np.unique(quads[turned]).size
    # The same patch away from every part is wrapped as it was: only the surface beside the parts is judged.
    away = cube_sphere(3, 0.3, (0.0, 0.0, -1.0))
    positions, topology = topology_of([(sphere, faces), away])
    assert not parts.plan_parts("Layout", positions, topology, parts.PartGroups(), True, target_sphere()).unseen.any()


def test_every_vertex_a_part_is_refused():
    positions, topology = topology_of([cube_sphere(3, 1.0)])
    with pytest.raises(errors.LayoutError, match="Every vertex of layout 'Layout' would follow"):
        parts.plan_parts("Layout", positions, topology, parts.PartGroups(follow=np.ones(len(positions), bool)), True)


def test_the_follower_moves_the_ball_with_the_body_and_the_readout_leaves_it_out():
    body, ball = cube_sphere(8, 1.4), cube_sphere(3, 0.3, (0.4, 0.0, 0.3))
    positions, topology = topology_of([body, ball])
    follow = np.zeros(len(positions), bool)
    follow[len(body[0]) :] = True
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(follow=follow), False)
    follower = parts.make_follower(plan, positions)
    moved = positions.copy()
    moved[: len(body[0])] = moved[: len(body[0])] * 1.1 + np.array([0.5, 0.0, 0.0])  # the body grows and moves
    result = parts.follow(follower, plan, moved)
    assert np.allclose(result[: len(body[0])], moved[: len(body[0])])
    shift = result[len(body[0]) :].mean(axis=0) - positions[len(body[0]) :].mean(axis=0)
    assert shift[0] > 0.5
    sizes = np.linalg.norm(result[len(body[0]) :] - result[len(body[0]) :].mean(axis=0), axis=1)
    assert np.allclose(sizes, np.linalg.norm(ball[0] - ball[0].mean(axis=0), axis=1))  # rigid, its size kept
    assert list(np.unique(parts.part_codes(plan))) == [0, 2]
    quality = core_module("quality")
    readout = quality.Readout(np.arange(len(positions), dtype=float), np.ones(len(positions)), np.zeros(3, bool), 2.0)
    surface = parts.surface_readout(readout, plan.parts)
    assert surface.distances.size == len(body[0]) and surface.distances.max() == len(body[0]) - 1
    assert parts.surface_readout(readout, None) is readout


def turned_about_x(points, angle, hinge):
    """``points`` turned by ``angle`` (radians) about the x axis through ``hinge``."""
    c, s = np.cos(angle), np.sin(angle)
    return (points - hinge) @ np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]).T + hinge


def opened_jaw():
    """A 'jaw' opening: a body whose lower front half turns about a hinge, a ball inside that half (as the lower
    teeth in a mouth) and the 'lips' (the skin between the halves in front) left where they were, as a wrap leaves
    skin the target does not hold. (positions, plan, moved positions, the ball's true place, lips (N,) bool)."""
    body, ball = cube_sphere(16, 1.0), cube_sphere(3, 0.12, (0.0, -0.62, 0.6))
    positions, topology = topology_of([body, ball])
    count = len(body[0])
    follow = np.zeros(len(positions), bool)
    follow[count:] = True
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(follow=follow), False)
    skin = positions[:count]
    lips = np.zeros(len(positions), bool)
    lips[:count] = (skin[:, 1] > -0.5) & (skin[:, 1] < 0.15) & (skin[:, 2] > 0.0)
    jaw = np.zeros(len(positions), bool)
    jaw[:count] = skin[:, 1] < -0.05
    hinge, angle = np.array([0.0, 0.0, -0.6]), -0.35
    moved = positions.copy()
    moved[jaw & ~lips] = turned_about_x(positions[jaw & ~lips], angle, hinge)
    return positions, plan, moved, turned_about_x(positions[count:], angle, hinge), lips


def test_a_piece_in_an_opening_jaw_follows_the_skin_the_target_holds():
    positions, plan, moved, truth, lips = opened_jaw()
    follower = parts.make_follower(plan, positions)
    held = ~plan.parts & ~lips  # the wrap's face points: every surface vertex but the lagging lips
    result = parts.follow(follower, plan, moved, held)
    assert np.abs(result[plan.parts] - truth).max() < 1e-9  # the jaw's turn, exactly
    assert np.array_equal(result[~plan.parts], moved[~plan.parts])
    # Following the whole surface, the lagging lips drag a plain fit of the ball's nearest skin (64 neighbours, no
    # reweighting): off by a tenth of its radius or more. The wrap's fit, reweighted over its wider binding, is
    # carried by the jaw that moves as one, not by the lips.
    import springwrap_kernel

    surface = ~plan.parts
    rigid_piece = np.zeros(int(plan.parts.sum()), dtype=np.uint32)
    plain = springwrap_kernel.SurfaceFollower(positions[surface], positions[plan.parts], rigid_piece, np.ones(1, bool))
    dragged = np.asarray(plain.apply(np.ascontiguousarray(moved[surface])))
    assert np.linalg.norm(dragged - truth, axis=1).max() > 0.012
    unweighted = parts.follow(follower, plan, moved)
    assert np.linalg.norm(unweighted[plan.parts] - truth, axis=1).max() < 1e-3


def test_a_wrap_that_holds_little_of_the_surface_has_its_parts_follow_all_of_it():
    positions, plan, moved, _truth, lips = opened_jaw()
    follower = parts.make_follower(plan, positions)
    few = lips & (np.arange(len(positions)) % 2 == 0)  # far below half of the surface
    assert few.sum() < parts.HELD_SHARE * (~plan.parts).sum()
    assert np.array_equal(parts.follow(follower, plan, moved, few), parts.follow(follower, plan, moved))
    everything = ~plan.parts
    assert np.array_equal(parts.follow(follower, plan, moved, everything), parts.follow(follower, plan, moved))


def body_and_ball_inputs():
    """(positions, topology, plan, WrapInputs) of a body with a ball part after it, an anchor on each, the body's
    vertex 2 held on a plane and a curve through its vertices 0, 1 and 2."""
    wrap_inputs = core_module("wrap_inputs")
    body, ball = cube_sphere(4, 1.4), cube_sphere(2, 0.3, (0.4, 0.0, 0.3))
    positions, topology = topology_of([body, ball])
    count, body_count = len(positions), len(body[0])
    follow = np.arange(count) >= body_count
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(follow=follow), False)
    points = positions.astype(np.float32)
    anchors = np.array([5, body_count + 1], dtype=np.uint32)
    inputs = wrap_inputs.WrapInputs(
        states=np.zeros(count, dtype=np.int32),
        triangles=np.full(count, -1, dtype=np.int32),
        barycentrics=np.zeros((count, 3), dtype=np.float32),
        positions=points,
        anchor_vertices=anchors,
        anchor_triangles=np.full(2, -1, dtype=np.int32),
        anchor_barycentrics=np.zeros((2, 3), dtype=np.float32),
        anchor_positions=points[anchors],
        unreliable_triangles=None,
        curve_vertices=np.array([0, 1, 2], dtype=np.uint32),
        curve_vertex_counts=np.array([3], dtype=np.uint32),
        curve_points=points[:2],
        curve_point_counts=np.array([2], dtype=np.uint32),
        plane_vertices=np.array([2, body_count + 3], dtype=np.uint32),
        plane_point=(0.0, 0.0, 0.0),
        plane_normal=(1.0, 0.0, 0.0),
        free_vertices=follow.copy(),
    )
    return positions, topology, plan, inputs


def test_the_solver_is_given_the_layout_without_its_parts():
    positions, topology, plan, inputs = body_and_ball_inputs()
    body_count = int((~plan.parts).sum())
    restriction, cut = parts.cut_out(topology, inputs, plan, positions.astype(np.float32))
    assert restriction.kept.tolist() == list(range(body_count))  # the body alone, in its own numbering
    assert restriction.topology.vertex_count == body_count
    assert restriction.topology.face_corners.max() < body_count
    assert cut.positions.shape == (body_count, 3) and not cut.free_vertices.any()
    assert cut.anchor_vertices.tolist() == [5]  # the ball's anchor is not the body's
    assert cut.curve_vertices.tolist() == [0, 1, 2] and cut.plane_vertices.tolist() == [2]
    # Within a region, only the region's surface vertices are re-settled.
    region = np.zeros(len(positions), dtype=bool)
    region[:4] = True
    region[-1] = True
    restriction, _cut = parts.cut_out(topology, inputs, plan, positions.astype(np.float32), region)
    assert restriction.region.tolist() == (region & ~plan.parts).tolist()
    none = plan._replace(parts=np.zeros(len(positions), dtype=bool))
    assert parts.cut_out(topology, inputs, none, positions) is None


def test_faces_without_the_parts():
    _positions, topology, plan, _inputs = body_and_ball_inputs()
    corners, sizes = parts.faces_without(topology, plan.parts)
    body_count = int((~plan.parts).sum())
    assert corners.max() < body_count and corners.size == sizes.sum()
    assert sizes.size == int((np.asarray(topology.face_corners).reshape(-1, 4) < body_count).all(axis=1).sum())


def egg(n=12, axes=(0.7, 1.4, 0.5)):
    """A closed quad ellipsoid (no symmetry a rigid motion could slide along), (V, 3) and (F, 4)."""
    vertices, faces = cube_sphere(n, 1.0)
    return vertices * np.asarray(axes), faces


SHIFT = np.array([0.1, -0.15, 0.05])
"""How far the target moved from the egg in the lagging-skin scenes."""


def lagging_skin_scene(pieces):
    """An egg with ``pieces`` inside (all in the Follow group), its target the egg moved by :data:`SHIFT`, the
    wrapped skin having carried only 0.4 of that motion (it slid along the target): (positions, skin vertex count,
    plan, follower, target, moved positions, held skin)."""
    body = egg()
    positions, topology = topology_of([body, *pieces])
    count = len(body[0])
    follow = np.zeros(len(positions), bool)
    follow[count:] = True
    plan = parts.plan_parts("Layout", positions, topology, parts.PartGroups(follow=follow), False)
    follower = parts.make_follower(plan, positions)
    triangles = np.concatenate([body[1][:, [0, 1, 2]], body[1][:, [0, 2, 3]]])
    target = target_module.CentredMesh(body[0] + SHIFT, np.ascontiguousarray(triangles, dtype=np.uint32))
    moved = positions.copy()
    moved[:count] += 0.4 * SHIFT
    return positions, count, plan, follower, target, moved, ~plan.parts


def test_a_rigid_piece_is_placed_by_its_skin_on_the_target_where_the_wrapped_skin_lags():
    ball = cube_sphere(3, 0.15, (0.0, 1.1, 0.0))  # in the egg's pointed end, as teeth in a chin
    positions, count, plan, follower, target, moved, held = lagging_skin_scene([ball])
    shift = SHIFT
    truth = positions[count:] + shift
    followed = parts.follow(follower, plan, moved, held)
    assert np.linalg.norm(followed[count:] - truth, axis=1).min() > 0.5 * np.linalg.norm(shift)  # it lags too
    registered = []
    placed = parts.follow(follower, plan, moved, held, target, registered)
    assert np.linalg.norm(placed[count:] - truth, axis=1).max() < 1e-3
    assert np.array_equal(placed[:count], moved[:count])
    (piece,) = registered  # the ball, reported as placed by its skin
    assert piece == plan.pieces[count]
    assert "rigid, placed by its skin on the target" in parts.report_text(plan, registered)
    assert "placed by its skin" not in parts.report_text(plan)


def test_a_skin_vertex_without_a_position_leaves_the_registration_to_the_others():
    ball = cube_sphere(3, 0.15, (0.0, 1.1, 0.0))
    positions, count, plan, follower, target, moved, held = lagging_skin_scene([ball])
    followed = parts.follow(follower, plan, moved, held)
    lost = int(np.argmin(np.linalg.norm(positions[:count] - positions[count:].mean(axis=0), axis=1)))
    followed[lost] = np.nan  # the skin vertex nearest the ball, lost (a diverged point)
    placed = part_registration.place_pieces(plan, follower.rest, followed, held, target)
    assert np.linalg.norm(placed[count:] - (positions[count:] + SHIFT), axis=1).max() < 1e-3


def test_a_piece_whose_skin_is_another_pieces_keeps_the_surfaces_motion():
    outer = cube_sphere(4, 0.3, (0.0, 0.0, 0.0))
    inner = cube_sphere(3, 0.1, (0.0, 0.0, 0.0))  # inside the other piece: the skin round it is the outer one's
    positions, count, plan, follower, target, moved, held = lagging_skin_scene([outer, inner])
    shift = SHIFT
    followed = parts.follow(follower, plan, moved, held)
    registered = []
    placed = parts.follow(follower, plan, moved, held, target, registered)
    assert registered == [plan.pieces[count]]  # the outer piece only
    inner_vertices = np.arange(count + len(outer[0]), len(positions))
    assert np.allclose(placed[inner_vertices], followed[inner_vertices])
    assert (
        np.linalg.norm(
            placed[count : count + len(outer[0])] - positions[count : count + len(outer[0])] - shift, axis=1
        ).max()
        < 1e-3
    )


def test_nearest_distances_agree_with_every_pair_measured():
    rng = np.random.default_rng(3)
    points, others = rng.normal(size=(700, 3)) + 50.0, rng.normal(size=(300, 3)) + 50.0  # far from the origin
    every = np.linalg.norm(points[:, None, :] - others[None, :, :], axis=2)
    distances, indices = part_registration.nearest_distances(points, others)
    assert np.array_equal(indices, every.argmin(axis=1))
    assert np.allclose(distances, every.min(axis=1), rtol=0.0, atol=1e-12)


def test_a_big_piece_is_measured_and_fitted_on_samples_spread_over_it():
    indices = np.arange(10, 10 + 5000)
    chosen = part_registration.sampled(indices, 100)
    assert len(chosen) == 100 and chosen[0] == indices[0] and chosen[-1] == indices[-1]
    assert np.all(np.diff(chosen) > 0) and np.ptp(np.diff(chosen)) <= 1  # evenly spread
    assert np.array_equal(part_registration.sampled(indices[:50], 100), indices[:50])


def test_a_piece_bigger_than_the_samples_is_still_placed_by_its_skin(monkeypatch):
    monkeypatch.setattr(part_registration, "SAMPLES", 20)  # fewer than the ball's 56 vertices and its patch
    test_a_rigid_piece_is_placed_by_its_skin_on_the_target_where_the_wrapped_skin_lags()
