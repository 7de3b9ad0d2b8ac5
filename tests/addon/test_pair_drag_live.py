"""The pair tool's modal operator driven with synthetic events (no window: the view, the area and the window
manager stood in for), while a wrap runs on the layout: a drag's mouse moves handed to the running solver (the
layout follows before the release, the same run goes on), Esc and right-click cancelling a drag (the pair back, the
solver given the old anchors), a pair removed during the run, a failing re-settle that loses no edit, and the same
with a live wrap of the Wrap operator running. The settled result matches a wrap built anew with the final
anchors."""

import functools
import time
import types

import bpy

import numpy as np
import pytest
from mathutils import Matrix, Vector

from bpy_helpers import FakeUI, addon_module, plane_scene, snapshot, world_positions

WIDTH, HEIGHT = 1000, 800
DRAG_METRES = 0.3
"""How far along the plane a drag takes a pair's target end."""


class _Context:
    """``bpy.context`` with the window manager and the window stood in for, and no workspace (the tool is on)."""

    def __init__(self, ui):
        self.window_manager, self.window, self.workspace = ui, None, None

    def __getattr__(self, name):
        return getattr(bpy.context, name)


def view_matrix(target, normal, distance=5.0, scale=0.35) -> Matrix:
    """The perspective matrix of an orthographic view looking down ``normal`` onto the plane target."""
    camera = Matrix.Translation(target.matrix_world.translation + distance * Vector(normal))
    camera = camera @ target.matrix_world.to_quaternion().to_matrix().to_4x4()
    projection = np.diag([scale * HEIGHT / WIDTH, scale, -2.0 / 100.0, 1.0])
    return Matrix((projection @ np.array(camera.inverted())).tolist())


class Tool:
    """The pair tool's operator as ``invoke`` leaves it, its methods bound to a plain object, and the events."""

    def __init__(self, layout, matrix):
        from springwrap.blender import live_wraps
        from springwrap.blender.edit_mode import EditModeGuard
        from springwrap.operators import pair_tool

        self.ui = FakeUI()
        self.context = _Context(self.ui)
        region = types.SimpleNamespace(type="WINDOW", x=0, y=0, width=WIDTH, height=HEIGHT)
        area = types.SimpleNamespace(regions=[region], header_text_set=self.ui.header_text_set, tag_redraw=lambda: None)
        operator = types.SimpleNamespace(
            _layout_name=layout.name,
            _area=area,
            _region=region,
            _region_3d=types.SimpleNamespace(perspective_matrix=matrix),
            _guard=EditModeGuard(layout),
            _pending=None,
            _press=None,
            _dragging=False,
            _drag_start=None,
            _drag_settle=False,
            _settle=None,
            _timer=None,
            _mouse=None,
            reports=[],
        )
        operator.report = lambda kinds, text: operator.reports.append((set(kinds), text))
        for cls in reversed(pair_tool.SPRINGWRAP_OT_pair_tool.__mro__):
            for name, value in vars(cls).items():
                if isinstance(value, types.FunctionType) and name not in ("__init__", "invoke", "execute"):
                    setattr(operator, name, types.MethodType(value, operator))
        pair_tool._running.append(operator)
        live_wraps.set_tool(layout.name)
        self.operator = operator
        self.view = addon_module("blender.pair_tool").read_view(region, operator._region_3d)

    def event(self, kind, value="NOTHING", mouse=(0.0, 0.0), ctrl=False):
        event = types.SimpleNamespace(
            type=kind, value=value, mouse_x=int(round(mouse[0])), mouse_y=int(round(mouse[1])), ctrl=ctrl
        )
        event.alt = event.shift = False
        return self.operator.modal(self.context, event)

    def pixel(self, point):
        return addon_module("core.pair_pick").project(self.view, np.asarray(point).reshape(1, 3))[0][0]

    def click(self, point):
        mouse = self.pixel(point)
        self.event("LEFTMOUSE", "PRESS", mouse)
        return self.event("LEFTMOUSE", "RELEASE", mouse)

    def frames(self, count=1, seconds=0.03):
        """Timer events for about ``seconds`` each (the worker solves meanwhile)."""
        for _ in range(count):
            self.event("TIMER")
            time.sleep(seconds)

    def settle_to_end(self, seconds=120.0):
        start = time.perf_counter()
        while self.operator._settle is not None and time.perf_counter() - start < seconds:
            self.frames(1, 0.005)
        assert self.operator._settle is None, "the re-settle did not end"

    def end(self):
        from springwrap.operators import pair_tool

        self.operator._end(self.context, leave_tool=False)
        assert self.operator not in pair_tool._running


def anchor_state(layout):
    anchor_list = addon_module("blender.anchors").read_anchors(layout)
    return tuple(np.asarray(field).tobytes() for field in anchor_list)


def assert_same_anchors(layout, state, atol: float = 1e-5) -> None:
    """``layout``'s anchors are ``state`` (:func:`anchor_state`): every field bit for bit but the locations,
    within ``atol`` (a location found again from its triangle and barycentric coordinates differs by float32
    rounding: up to 2e-6 on this 2.2 m plane in Blender 3.4)."""
    anchor_list = addon_module("blender.anchors").read_anchors(layout)
    for name, field, stored in zip(anchor_list._fields, anchor_list, state, strict=True):
        field = np.asarray(field)
        if name == "locations":
            expected = np.frombuffer(stored, dtype=field.dtype).reshape(field.shape)
            np.testing.assert_allclose(field, expected, rtol=0, atol=atol)
        else:
            assert field.tobytes() == stored, name


ITERATION_SECONDS = 0.02
"""What each of the re-settle's iterations costs at least here (the plane's own take a fraction of a millisecond,
and the re-settle would end before a drag's second move)."""


class _Slowed:
    """A solver whose iterations take at least :data:`ITERATION_SECONDS` each (the rest of it as it was)."""

    def __init__(self, solver):
        self._solver = solver

    def step(self, iterations, **keywords):
        time.sleep(ITERATION_SECONDS * max(int(iterations), 1))
        return self._solver.step(iterations, **keywords)

    def __getattr__(self, name):
        return getattr(self._solver, name)


def slowed_settle(context, layout, display_seconds=None, start_settle=None):
    """``blender.pair_tool.start_settle`` with its solver slowed (:class:`_Slowed`)."""
    session = start_settle(context, layout, display_seconds)
    session.solver = _Slowed(session.solver)
    return session


@pytest.fixture
def scene(monkeypatch):
    """The plane scene with three pairs (each target end a little off its vertex, so the two ends are apart on the
    screen), Live on (the re-settle slowed), a copy of the layout as it is (for a wrap built anew), and the tool."""
    pair_data = addon_module("blender.pair_tool")
    slowed = functools.partial(slowed_settle, start_settle=pair_data.start_settle)
    monkeypatch.setattr(pair_data, "start_settle", slowed)
    target, layout, normal = plane_scene()
    copy = layout.copy()
    copy.data = layout.data.copy()
    copy.name = "Layout copy"
    bpy.context.collection.objects.link(copy)
    along = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    along /= np.linalg.norm(along)
    world = world_positions(layout)
    tool_data = addon_module("blender.pair_tool")
    for vertex in (30, 84, 138):
        tool_data.place_pair(bpy.context, layout, vertex, world[vertex] - 0.3 * np.asarray(normal) + 0.08 * along)
    layout.springwrap.pair_live = True
    bpy.ops.ed.undo_push(message="pairs placed")
    tool = Tool(layout, view_matrix(target, normal))
    yield types.SimpleNamespace(
        target=target, layout=layout, normal=np.asarray(normal), along=along, copy=copy, tool=tool
    )
    if addon_module("operators.pair_tool").running():
        tool.end()


def start_re_settle(s):
    """Two clicks make a pair on vertex 60 (Live on: the re-settle starts); its first frame."""
    world = world_positions(s.layout)
    before = snapshot(s.layout)
    s.tool.click(world[60])
    s.tool.click(world[60] - 0.3 * s.normal + 0.05 * s.along)
    assert len(s.layout.springwrap.anchors) == 4
    session = s.tool.operator._settle
    assert session is not None, s.tool.operator.reports
    s.tool.frames(2)
    assert session.worker is not None, (s.tool.operator._settle, s.tool.operator.reports, session.total_iterations)
    return session, before


def drag(s, pair, moves, release=True, seconds=0.03):
    """Press on pair ``pair``'s target end and move it ``DRAG_METRES`` along the plane in ``moves`` moves, timer
    events between them; the target points the moves went to."""
    item = s.layout.springwrap.anchors[pair]
    start = np.array(item.location)
    away = s.tool.pixel(start) - s.tool.pixel(world_positions(s.layout)[item.vertex_index])
    nudge = 3.0 * away / max(np.linalg.norm(away), 1e-9)  # pixels off the layout end (the settle brings it near)
    s.tool.event("LEFTMOUSE", "PRESS", s.tool.pixel(start) + nudge)
    assert s.tool.operator._press is not None and s.tool.operator._press[1:] == (pair, "TARGET")
    points = []
    for step in range(1, moves + 1):
        point = start + DRAG_METRES * step / moves * s.along
        s.tool.event("MOUSEMOVE", mouse=s.tool.pixel(point) + nudge)
        points.append(np.array(s.layout.springwrap.anchors[pair].location))
        s.tool.frames(1, seconds)
    if release:
        s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(points[-1]))
    return points


def start_live_wrap(layout):
    """A live wrap of ``layout`` as the Wrap operator runs it (its first frame, then its worker), marked as running;
    (its ``WrapSession``, its ``WrapLoop``)."""
    from springwrap.blender import wrap_session
    from springwrap.core.wrap_run import WrapLoop

    session = addon_module("blender.pair_tool").start_settle(bpy.context, layout)
    loop = WrapLoop(session)
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    session.start_worker()
    wrap_session.set_running(session)
    return session, loop


def along_offset(s, vertex, origin):
    return float((world_positions(s.layout)[vertex] - origin) @ s.along)


def test_a_drag_during_a_re_settle_moves_the_running_solver_and_the_layout_follows_before_the_release(scene):
    s = scene
    session, _before = start_re_settle(s)
    pair, vertex = 1, 84
    origin = np.array(s.layout.springwrap.anchors[pair].location)
    bpy.ops.ed.undo_push(message="before the drag")
    before_drag = anchor_state(s.layout)
    start_offset = along_offset(s, vertex, origin)
    points = drag(s, pair, moves=10, release=False)
    assert s.tool.operator._settle is session  # the same run goes on: not finished, not started anew
    assert s.tool.operator._dragging
    np.testing.assert_allclose(points[-1], origin + DRAG_METRES * s.along, atol=0.03)  # under the mouse
    deadline = time.perf_counter() + 30.0
    while not np.allclose(session.anchors.locations[pair], points[-1]) and time.perf_counter() < deadline:
        s.tool.frames(1)
    # the solver has it (to float32 rounding: the location found again from its triangle and barycentric coordinates)
    np.testing.assert_allclose(session.anchors.locations[pair], points[-1], rtol=0, atol=1e-5)
    s.tool.frames(10)
    moved = along_offset(s, vertex, origin) - start_offset
    assert moved > 0.1, f"the layout followed the drag by only {moved:.3f} before the release"
    s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(points[-1]))
    assert s.tool.operator._settle is session and not s.tool.operator._dragging
    released = anchor_state(s.layout)
    s.tool.settle_to_end()
    assert_same_anchors(s.layout, released)  # the re-settle's end wrote the anchors as dragged
    final = world_positions(s.layout)
    np.testing.assert_allclose(final[vertex], points[-1], atol=2e-3)  # the vertex on its dragged target point
    # The drag is one undo step (the re-settle's end another): two undos go back to before the drag.
    bpy.ops.ed.undo()
    assert anchor_state(bpy.data.objects["Layout"]) == released
    bpy.ops.ed.undo()
    assert anchor_state(bpy.data.objects["Layout"]) == before_drag


def test_the_re_settled_layout_equals_a_wrap_built_anew_with_the_final_anchors(scene):
    s = scene
    start_re_settle(s)
    drag(s, 1, moves=6)
    drag(s, 2, moves=4, seconds=0.01)
    s.tool.settle_to_end()
    final_anchors = addon_module("blender.anchors").read_anchors(s.layout)
    addon_module("blender.anchors").write_anchors(s.copy, final_anchors, -1, s.layout.springwrap.anchors_signature)
    anew = addon_module("blender.pair_tool").start_settle(bpy.context, s.copy)
    anew.run()
    anew.finish()
    difference = np.linalg.norm(world_positions(s.layout) - world_positions(s.copy), axis=1)
    assert difference.max() < 2e-3, f"{difference.max():.2e} m from a wrap built anew (layout 2.2 m wide)"


@pytest.mark.parametrize("cancel", ["ESC", "RIGHTMOUSE"])
def test_esc_or_right_click_during_a_drag_puts_the_pair_back_and_the_solver_gets_the_old_anchors(scene, cancel):
    s = scene
    session, before_settle = start_re_settle(s)
    before_drag = anchor_state(s.layout)
    old = np.array(session.anchors.locations)
    drag(s, 1, moves=5, release=False)
    assert anchor_state(s.layout) != before_drag
    assert s.tool.event(cancel, "PRESS", s.tool.pixel(old[1])) == {"RUNNING_MODAL"}
    assert anchor_state(s.layout) == before_drag  # bit for bit
    assert s.tool.operator._settle is session and not s.tool.operator._dragging
    assert ({"INFO"}, "Drag cancelled: the pair is back where it was") in s.tool.operator.reports
    deadline = time.perf_counter() + 30.0
    while not np.array_equal(session.anchors.locations, old) and time.perf_counter() < deadline:
        s.tool.frames(1)
    np.testing.assert_array_equal(session.anchors.locations, old)  # the running solver was given them back
    s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(old[1]))  # the release after a cancel: nothing
    assert anchor_state(s.layout) == before_drag
    # Then Esc (or right-click) cancels the running re-settle as before: the layout back, the edits kept.
    assert s.tool.event(cancel, "PRESS", s.tool.pixel(old[1])) == {"RUNNING_MODAL"}
    assert s.tool.operator._settle is None
    assert snapshot(s.layout) == before_settle and anchor_state(s.layout) == before_drag
    assert s.tool.event("ESC", "PRESS") == {"FINISHED"}  # a second Esc leaves the tool


def test_a_drag_with_nothing_running_starts_the_re_settle_and_its_esc_undoes_both_bit_for_bit(scene):
    s = scene
    before = snapshot(s.layout)
    drag(s, 0, moves=4, release=False)
    session = s.tool.operator._settle
    assert session is not None and s.tool.operator._drag_settle  # started at the drag's first move
    s.tool.frames(5)
    assert snapshot(s.layout)["positions"] != before["positions"]  # the layout moved while the drag goes on
    s.tool.event("ESC", "PRESS")
    assert s.tool.operator._settle is None and snapshot(s.layout) == before


def test_a_pair_removed_during_the_re_settle_goes_to_the_same_run(scene):
    s = scene
    session, _before = start_re_settle(s)
    location = np.array(s.layout.springwrap.anchors[2].location)
    s.tool.event("X", "PRESS", s.tool.pixel(location))
    assert len(s.layout.springwrap.anchors) == 3 and s.tool.operator._settle is session
    deadline = time.perf_counter() + 30.0
    while len(session.anchors.locations) != 3 and time.perf_counter() < deadline:
        s.tool.frames(1)
    assert len(session.anchors.locations) == 3
    s.tool.settle_to_end()
    assert len(s.layout.springwrap.anchors) == 3


class _Failing:
    """A solver whose steps fail (the rest of it as it was)."""

    def __init__(self, solver):
        self._solver = solver

    def step(self, *args, **kwargs):
        raise RuntimeError("simulated solver failure")

    def __getattr__(self, name):
        return getattr(self._solver, name)


def test_a_re_settle_failing_mid_drag_is_undone_and_the_drag_loses_nothing(scene):
    s = scene
    session, before_settle = start_re_settle(s)
    drag(s, 1, moves=3, release=False)
    session.solver = _Failing(session.solver)
    s.tool.frames(20)
    assert s.tool.operator._settle is None  # failed: undone
    assert any("simulated solver failure" in text for kinds, text in s.tool.operator.reports if "ERROR" in kinds)
    assert snapshot(s.layout) == before_settle
    assert s.tool.operator._dragging  # the drag goes on
    points = drag(s, 1, moves=2)
    np.testing.assert_allclose(s.layout.springwrap.anchors[1].location, points[-1], atol=1e-6)
    assert addon_module("operators.pair_tool").running()


def test_a_drag_while_a_live_wrap_runs_is_handed_to_its_solver(scene):
    from springwrap.blender import live_wraps, wrap_session

    s = scene
    session, loop = start_live_wrap(s.layout)
    try:
        assert live_wraps.tool_takes(s.layout, "LEFTMOUSE", "PRESS")  # the wrap lets the tool's click through
        assert not live_wraps.tool_takes(s.layout, "ESC", "PRESS")  # Esc stops the wrap...
        points = drag(s, 1, moves=4, release=False)
        assert live_wraps.tool_takes(s.layout, "ESC", "PRESS")  # ...but cancels a drag
        assert s.tool.operator._settle is None  # no re-settle of the tool's own
        s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(points[-1]))
        assert s.tool.operator._settle is None
        outcome = "RUNNING_MODAL"
        deadline = time.perf_counter() + 120.0
        while outcome == "RUNNING_MODAL" and time.perf_counter() < deadline:
            outcome = loop.handle("TIMER")
            time.sleep(0.005)
        assert outcome == "FINISHED"
        np.testing.assert_allclose(s.layout.springwrap.anchors[1].location, points[-1], atol=1e-6)
        np.testing.assert_allclose(world_positions(s.layout)[84], points[-1], atol=2e-3)
    finally:
        wrap_session.set_running(session, running=False)
        session.stop_worker(raise_error=False)


def test_a_re_settle_done_during_a_drag_waits_for_its_next_move_the_drag_stays_one_undo_step(scene):
    s = scene
    before = anchor_state(s.layout)
    item = s.layout.springwrap.anchors[0]
    start = np.array(item.location)
    away = s.tool.pixel(start) - s.tool.pixel(world_positions(s.layout)[item.vertex_index])
    nudge = 3.0 * away / np.linalg.norm(away)
    s.tool.event("LEFTMOUSE", "PRESS", s.tool.pixel(start) + nudge)
    s.tool.event("MOUSEMOVE", mouse=s.tool.pixel(start + 0.1 * s.along) + nudge)
    session = s.tool.operator._settle
    deadline = time.perf_counter() + 120.0
    while not (session.done and session.worker is None) and time.perf_counter() < deadline:
        s.tool.frames(1, 0.01)
    assert session.done and s.tool.operator._settle is session  # done, not finished: no undo step mid-drag
    end = start + 0.2 * s.along
    s.tool.event("MOUSEMOVE", mouse=s.tool.pixel(end) + nudge)
    assert not session.done and session.worker is not None  # the next move revived it in a new worker
    s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(end) + nudge)
    released = anchor_state(s.layout)
    s.tool.settle_to_end()
    dragged = np.array(s.layout.springwrap.anchors[0].location)
    assert np.linalg.norm(dragged - start) > 0.15
    np.testing.assert_allclose(
        world_positions(s.layout)[s.layout.springwrap.anchors[0].vertex_index], dragged, atol=2e-3
    )
    bpy.ops.ed.undo()  # over the re-settle's end
    assert anchor_state(bpy.data.objects["Layout"]) == released
    bpy.ops.ed.undo()  # over the drag: one step
    assert anchor_state(bpy.data.objects["Layout"]) == before


def test_esc_of_a_live_wrap_puts_the_layout_back_and_keeps_the_pairs_dragged_during_it(scene):
    from springwrap.blender import wrap_session

    s = scene
    before = snapshot(s.layout)
    session, loop = start_live_wrap(s.layout)
    try:
        points = drag(s, 1, moves=3)
        dragged = anchor_state(s.layout)
        assert loop.handle("ESC", "PRESS") == "CANCELLED"
    finally:
        wrap_session.set_running(session, running=False)
    assert snapshot(s.layout) == before
    assert_same_anchors(s.layout, dragged)
    np.testing.assert_allclose(s.layout.springwrap.anchors[1].location, points[-1], atol=1e-6)


def test_a_pair_s_layout_end_dragged_to_another_vertex_during_the_re_settle_goes_to_the_same_run(scene):
    s = scene
    session, _before = start_re_settle(s)
    item = s.layout.springwrap.anchors[1]
    world = world_positions(s.layout)
    layout_end = s.tool.pixel(world[item.vertex_index])
    away = layout_end - s.tool.pixel(np.array(item.location))
    s.tool.event("LEFTMOUSE", "PRESS", layout_end + 3.0 * away / np.linalg.norm(away))
    assert s.tool.operator._press[1:] == (1, "LAYOUT")
    s.tool.event("MOUSEMOVE", mouse=s.tool.pixel(world[86]))
    s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(world[86]))
    assert s.layout.springwrap.anchors[1].vertex_index == 86 and s.tool.operator._settle is session
    deadline = time.perf_counter() + 30.0
    while 86 not in session.anchors.vertex_indices and time.perf_counter() < deadline:
        s.tool.frames(1)
    assert 86 in session.anchors.vertex_indices and 84 not in session.anchors.vertex_indices
    s.tool.settle_to_end()
    np.testing.assert_allclose(world_positions(s.layout)[86], s.layout.springwrap.anchors[1].location, atol=2e-3)


def test_a_wrap_started_while_the_re_settle_runs_keeps_the_re_settle_and_runs_alone(scene):
    from springwrap.blender import live_wraps, wrap_session

    s = scene
    session, before_settle = start_re_settle(s)
    s.tool.frames(3)
    edited = anchor_state(s.layout)
    live_wraps.take_over(bpy.context, s.layout)  # what the Wrap operator does first
    assert s.tool.operator._settle is None and session.worker is None  # kept as far as it got, its worker stopped
    assert wrap_session.running_session(s.layout) is None and wrap_session.last_result(s.layout) is not None
    kept = snapshot(s.layout)
    assert kept["positions"] != before_settle["positions"]
    assert bpy.ops.springwrap.wrap("EXEC_DEFAULT", True) == {"FINISHED"}  # alone on the layout
    assert wrap_session.running_session(s.layout) is None and s.tool.operator._settle is None
    assert snapshot(s.layout) != kept
    assert_same_anchors(s.layout, edited)
    bpy.ops.ed.undo()  # over the wrap: the re-settle as it was kept
    assert snapshot(bpy.data.objects["Layout"]) == kept
    bpy.ops.ed.undo()  # over the re-settle: the layout as the edit left it
    assert snapshot(bpy.data.objects["Layout"]) == before_settle
    assert anchor_state(bpy.data.objects["Layout"]) == edited


def test_the_wrap_operator_hands_the_re_settle_over_itself(scene):
    from springwrap.blender import wrap_session

    s = scene
    session, _before = start_re_settle(s)
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    assert s.tool.operator._settle is None and session.worker is None
    assert wrap_session.running_session(s.layout) is None
    assert wrap_session.last_result(s.layout).frames == 0  # the wrap's own (run at once), not the re-settle's


def test_a_wrap_started_during_a_drag_of_the_re_settle_is_refused_and_the_re_settle_goes_on(scene):
    from springwrap.blender import wrap_session

    s = scene
    session, _before = start_re_settle(s)
    drag(s, 1, moves=2, release=False)
    with pytest.raises(RuntimeError, match="dragging a pair of 'Layout'.*release the pair"):
        bpy.ops.springwrap.wrap()
    assert s.tool.operator._settle is session and wrap_session.running_session(s.layout) is session
    assert s.tool.operator._dragging
    s.tool.event("LEFTMOUSE", "RELEASE", s.tool.pixel(s.layout.springwrap.anchors[1].location))
    s.tool.settle_to_end()


@pytest.mark.parametrize("operator", ["wrap", "mirror"])
def test_a_second_wrap_on_a_layout_with_a_live_wrap_running_is_refused(scene, operator):
    from springwrap.blender import wrap_session

    s = scene
    session, loop = start_live_wrap(s.layout)
    try:
        with pytest.raises(RuntimeError, match="A wrap is already running on 'Layout'"):
            getattr(bpy.ops.springwrap, operator)()
        assert wrap_session.running_session(s.layout) is session and session.worker is not None
        assert loop.handle("ESC", "PRESS") == "CANCELLED"
    finally:
        wrap_session.set_running(session, running=False)
        session.stop_worker(raise_error=False)


def test_the_tool_writes_its_status_again_after_a_live_wrap_cleared_the_header(scene):
    from springwrap.blender import live_wraps
    from springwrap.operators import wrap

    s = scene
    live_wraps.set_tool(s.layout.name, refresh=lambda: s.tool.operator._status(s.tool.context))
    live_wraps.set_tool(s.layout.name, dragging=True)  # the tool's later calls keep the way back
    live_wraps.set_tool(s.layout.name)
    wrap_ui = FakeUI()
    ended = types.SimpleNamespace(
        _loop=None, _timer=None, _area=types.SimpleNamespace(header_text_set=wrap_ui.header_text_set)
    )
    ended._restore_mode = lambda: None
    s.tool.ui.calls.clear()
    wrap.SPRINGWRAP_OT_wrap._end(ended, s.tool.context)
    assert ("header_text_set", (None,)) in wrap_ui.calls  # the wrap's end cleared the header...
    texts = [args[0] for name, args in s.tool.ui.calls if name == "header_text_set"]
    assert texts and texts[-1].endswith("Esc: cancel a drag, or leave")  # ...and the tool wrote its status again
    live_wraps.set_tool(None)
    s.tool.ui.calls.clear()
    live_wraps.refresh_tool()
    assert not [call for call in s.tool.ui.calls if call[0] == "header_text_set"]
