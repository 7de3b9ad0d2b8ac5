"""The wrap over time without Blender: ``core.sequence`` (frames, keys, keyframes, the modal's state machine) and
``core.follow`` (which vertices a change concerns, the part of the layout a re-settle works on)."""

import numpy as np
import pytest

from helpers import CORE, core_module

sequence = core_module("sequence")
follow = core_module("follow")
errors = core_module("errors")
layout_state = core_module("layout_state")
subdivision = core_module("subdivision")
wrap_inputs = core_module("wrap_inputs")


def test_modules_do_not_import_bpy():
    for name in ("sequence.py", "follow.py"):
        source = (CORE / name).read_text()
        assert "import bpy" not in source and "mathutils" not in source


def test_frame_range_and_its_refusals():
    assert sequence.frame_range(3, 6) == [3, 4, 5, 6]
    assert sequence.frame_range(1, 7, 3) == [1, 4, 7]
    with pytest.raises(errors.LayoutError, match="empty"):
        sequence.frame_range(5, 4)
    with pytest.raises(errors.LayoutError, match="step"):
        sequence.frame_range(1, 4, 0)


def test_key_names_are_recognised():
    assert sequence.key_name(12) == "Wrap 0012"
    assert sequence.is_sequence_key("Wrap 0012") and sequence.is_sequence_key("Wrap -003")
    assert not sequence.is_sequence_key("Wrap it") and not sequence.is_sequence_key("Smile")
    sequence.refuse_own_keys("L", ["Basis", "Wrap 0001"], "Basis")
    with pytest.raises(errors.LayoutError, match="'Smile'"):
        sequence.refuse_own_keys("L", ["Basis", "Smile"], "Basis")


def test_collection_objects_in_name_order_one_per_frame():
    assert sequence.frame_objects(["c", "a", "b"], [10, 11]) == [1, 2]
    with pytest.raises(errors.LayoutError, match="3 mesh objects for 4 frames"):
        sequence.frame_objects(["c", "a", "b"], [1, 2, 3, 4])


def test_keyframes_show_one_frame_at_a_time_and_blend_between():
    plan = sequence.key_values([1, 2, 3])
    assert plan == [[(1, 1.0), (2, 0.0)], [(1, 0.0), (2, 1.0), (3, 0.0)], [(2, 0.0), (3, 1.0)]]


def test_a_failed_frame_keys_the_shape_before_it():
    outcome = sequence.FrameOutcome
    outcomes = [outcome(1, False, 0.1, 0, "x"), outcome(2, True, 0.1, 5, ""), outcome(3, False, 0.1, 0, "y")]
    before, two = np.zeros((2, 3)), np.ones((2, 3))
    keys = sequence.key_positions(outcomes, {2: two}, before)
    assert [frame for frame, _ in keys] == [1, 2, 3]
    assert keys[0][1] is before and keys[1][1] is two and keys[2][1] is two
    result = sequence.SequenceResult("L", tuple(outcomes), 5, True)
    assert "3 of 5 frames" in result.summary() and "2 failed" in result.summary() and "stopped" in result.summary()


class FakeRun:
    def __init__(self, frames):
        self.frames, self.done_frames, self.finished = frames, 0, None

    @property
    def done(self):
        return self.done_frames >= self.frames

    def advance(self):
        self.done_frames += 1

    def finish(self, stopped=False):
        self.finished = stopped
        return ("result", self.done_frames, stopped)


def test_the_loop_steps_on_timers_and_stops_on_esc_keeping_the_frames():
    run = FakeRun(5)
    loop = sequence.SequenceLoop(run)
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    assert loop.handle("WHEELUPMOUSE") == "PASS_THROUGH"
    assert loop.handle("A", "PRESS") == "RUNNING_MODAL" and run.done_frames == 1  # blocked, nothing run
    assert loop.handle("ESC", "PRESS") == "FINISHED"
    assert loop.result == ("result", 1, True) and loop.handle("TIMER") == "FINISHED"


def test_the_loop_finishes_after_the_last_frame():
    loop = sequence.SequenceLoop(FakeRun(2))
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    assert loop.handle("TIMER") == "FINISHED" and loop.result == ("result", 2, False)


def test_changed_vertices_and_growth():
    before = np.array([0.0, 0.0, 0.5, 0.0, np.nan])
    after = np.array([0.0, 0.2, 0.5, 0.0, 0.0])
    moved = np.array([0.0, 0.0, 0.0, 0.3, 0.0])
    assert follow.changed_vertices(before, after, moved, 1e-3).tolist() == [False, True, False, True, True]
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    mask = np.array([True, False, False, False, False])
    assert follow.grow(mask, edges, 2).tolist() == [True, True, True, False, False]


def strip_topology(cells: int):
    """A strip of ``cells`` quads: vertices 0 .. cells along the bottom, cells + 1 .. along the top."""
    row = cells + 1
    quads = [(i, i + 1, row + i + 1, row + i) for i in range(cells)]
    edges = {tuple(sorted((quad[k], quad[(k + 1) % 4]))) for quad in quads for k in range(4)}
    return subdivision.LayoutTopology(
        2 * row,
        np.array(quads, dtype=np.uint32).ravel(),
        np.full(cells, 4, dtype=np.uint32),
        np.array(sorted(edges), dtype=np.uint32),
        np.zeros((0, 2), dtype=np.uint32),
    )


def strip_inputs(count: int):
    positions = np.arange(count * 3, dtype=np.float32).reshape(count, 3)
    return wrap_inputs.WrapInputs(
        states=np.ones(count, dtype=np.int32),
        triangles=np.arange(count, dtype=np.int32),
        barycentrics=np.tile(np.array([0.2, 0.3, 0.5], dtype=np.float32), (count, 1)),
        positions=positions,
        anchor_vertices=np.array([0, 7], dtype=np.uint32),
        anchor_triangles=np.array([-1, -1], dtype=np.int32),
        anchor_barycentrics=np.zeros((2, 3), dtype=np.float32),
        anchor_positions=positions[[0, 7]],
        unreliable_triangles=None,
    )


def test_a_re_settle_works_on_the_faces_around_the_region_and_holds_the_rest():
    topology = strip_topology(6)  # 14 vertices
    inputs = strip_inputs(14)
    region = np.zeros(14, dtype=bool)
    region[[3, 10]] = True  # the middle column
    held = follow.held(inputs, region)
    assert set(held.anchor_vertices.tolist()) == set(range(14)) - {3, 10}  # the own anchors once, the rest held
    assert np.array_equal(held.rest_positions, inputs.positions)
    restriction, part = follow.restrict(topology, held, region, inputs.positions)
    assert restriction.kept.tolist() == [2, 3, 4, 9, 10, 11]  # the two quads around the column
    assert restriction.topology.vertex_count == 6 and restriction.topology.face_sizes.tolist() == [4, 4]
    assert part.positions.shape == (6, 3) and set(part.anchor_vertices.tolist()) == {0, 2, 3, 5}
    solved = part.positions + 100.0
    state = layout_state.normalized_state(np.zeros(6, np.int32), np.full(6, -1, np.int32), np.zeros((6, 3)))
    positions, whole = follow.scatter(restriction, solved, state)
    moved = np.flatnonzero(np.any(positions != inputs.positions, axis=1))
    assert moved.tolist() == [3, 10]  # the held ones, bit for bit as they were
    assert whole.states[[3, 10]].tolist() == [0, 0] and whole.states[[2, 4, 9, 11]].tolist() == [1, 1, 1, 1]


def test_no_part_is_cut_from_inputs_with_curves():
    inputs = strip_inputs(14)._replace(curve_vertices=np.array([1, 2], dtype=np.uint32))
    assert follow.restrict(strip_topology(6), inputs, np.ones(14, dtype=bool), inputs.positions) is None


def test_the_template_s_share_of_the_rest_is_placed_onto_the_layout_first():
    """The template blended into a re-settle's rest shape is first moved onto the layout by the similarity that fits
    it best: a template that is the layout turned, scaled and moved blends into the layout's own shape."""
    rng = np.random.default_rng(3)
    positions = rng.normal(size=(40, 3)).astype(np.float32)
    angle = 0.7
    turn = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    template = (2.5 * positions.astype(np.float64) @ turn.T + [10.0, -4.0, 2.0]).astype(np.float32)
    assert np.allclose(follow.blended_rest(positions, template, 0.3), positions, atol=1e-4)
    line = np.outer(np.arange(5.0), [1.0, 2.0, 3.0]).astype(np.float32)  # no similarity on a line: itself
    assert np.array_equal(follow.blended_rest(line, line * 2.0, 0.3), line)
    assert np.array_equal(follow.blended_rest(positions, template, 0.0), positions)
    assert np.array_equal(follow.blended_rest(positions, None, 0.3), positions)
    bent = positions.copy()
    bent[:, 2] += positions[:, 0] ** 2  # another shape: the rest lies between the two, by the share
    half = follow.blended_rest(positions, bent, 0.5)
    assert 0.0 < np.abs(half - positions).max() < np.abs(bent - positions).max()


def test_a_re_settle_rests_in_the_layout_with_a_share_of_the_template():
    positions = np.random.default_rng(5).normal(size=(14, 3)).astype(np.float32)
    rest = positions.copy()
    rest[:, 2] += rest[:, 0] ** 2  # the template: another shape
    inputs = strip_inputs(14)._replace(positions=positions, rest_positions=rest)
    region = np.zeros(14, dtype=bool)
    region[[3, 10]] = True
    assert np.array_equal(follow.held(inputs, region).rest_positions, inputs.positions)
    blended = follow.held(inputs, region, follow.TEMPLATE_SHARE).rest_positions
    assert not np.allclose(blended, inputs.positions)
    assert np.allclose(blended, follow.blended_rest(inputs.positions, inputs.rest_positions, follow.TEMPLATE_SHARE))


def test_a_region_starts_again_from_the_template_placed_onto_the_vertices_around_it():
    """Vertices started again from the template become space-points at the template's positions, moved by the
    similarity that fits the template to the vertices around them; the others are untouched; with nothing around
    to fit (the whole layout), the template where it is; the region's springs then rest in the template's shape."""
    topology = strip_topology(6)  # 14 vertices
    template = np.zeros((14, 3), dtype=np.float32)
    template[:7, 0] = template[7:, 0] = np.arange(7)
    template[7:, 1] = 1.0
    template[:, 2] = 0.1 * template[:, 0] ** 2  # not flat: the similarity is fitted in 3D
    angle = 0.4
    turn = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    moved = (2.0 * template.astype(np.float64) @ turn.T + [3.0, -1.0, 0.5]).astype(np.float32)
    warm = moved.copy()
    region = np.zeros(14, dtype=bool)
    region[[3, 10]] = True
    warm[region, 2] += 0.7  # the region as the previous frame left it: off the template's shape
    inputs = strip_inputs(14)._replace(positions=warm, rest_positions=template)
    started = follow.restarted(inputs, region, topology.edges)
    assert np.allclose(started.positions[region], moved[region], atol=1e-4)
    assert np.array_equal(started.positions[~region], warm[~region])
    assert started.states[region].tolist() == [0, 0] and started.triangles[region].tolist() == [-1, -1]
    assert np.array_equal(started.states[~region], inputs.states[~region])
    whole = follow.restarted(inputs, np.ones(14, dtype=bool), topology.edges)
    assert np.array_equal(whole.positions, template)
    without_rest = inputs._replace(rest_positions=None)
    assert follow.restarted(without_rest, region, topology.edges) is without_rest
    rest = follow.held(started, region, follow.TEMPLATE_SHARE, region, warm).rest_positions
    assert np.allclose(rest[region], follow.blended_rest(warm, template, 1.0)[region])
    assert np.allclose(rest[~region], follow.blended_rest(warm, template, follow.TEMPLATE_SHARE)[~region])


def test_a_region_started_again_is_wrapped_global_to_local_unless_a_schedule_was_chosen():
    """The Auto schedule (also the kernel's defaults, no settings given) becomes global to local for a region started
    again from the template with vertices held around it; the other settings are kept, and a schedule the user
    chose is left as it is, as is Auto for the whole layout (nothing held: a wrap from the template)."""
    kernel = pytest.importorskip("springwrap_kernel")
    region = np.array([True, True, False])
    auto = wrap_inputs.WrapParameters(max_iterations=7, settings=kernel.WrapSettings(fairness=0.3))
    restarted = follow.restart_parameters(auto, region)
    assert restarted.settings.schedule == follow.RESTART_SCHEDULE == "GLOBAL_TO_LOCAL"
    assert restarted.max_iterations == 7 and restarted.settings.fairness == pytest.approx(0.3)
    assert follow.restart_parameters(wrap_inputs.WrapParameters(), region).settings.schedule == "GLOBAL_TO_LOCAL"
    local = wrap_inputs.WrapParameters(settings=kernel.WrapSettings(schedule="LOCAL"))
    assert follow.restart_parameters(local, region) is local
    assert follow.restart_parameters(auto, np.ones(3, dtype=bool)) is auto
