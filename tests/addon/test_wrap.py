"""The wrap (paper, section 2.5) under Blender (PyPI ``bpy``): ``springwrap.wrap`` and its modal logic.

Scenes are generated: a grid layout above a (tilted, moved) plane target, the same plane with a
round hole cut under the layout, and a UV-sphere target with a sphere-cap layout around it. The
results are checked independently of the kernel: distances with ``mathutils`` BVHTree on the
evaluated target, flips against the analytic surface normal, edge lengths against the template.
The modal operator's logic is driven without a window through ``WrapSession`` / ``WrapLoop``.
"""

import bpy

import numpy as np
import pytest

from bpy_helpers import (
    HOLE_CENTER,
    HOLE_RADIUS,
    SPHERE_CENTER,
    SPHERE_RADIUS,
    TOLERANCE,
    FakeUI,
    RecordingLayout,
    Reference,
    activate_layout,
    anchor_snapshot,
    anchor_targets,
    assert_no_flipped_quads,
    assert_wrapped_onto,
    curves_layout,
    edge_lengths,
    edges_of,
    local_positions,
    plane_scene,
    plane_target,
    radial,
    read_state,
    snapshot,
    sphere_scene,
    surface_distances,
    world_positions,
    wrap_session,
    wrap_with_anchors,
    wrapped_at_once,
)

# ---------------------------------------------------------------- scenes


# ---------------------------------------------------------------- registration


def test_wrap_operator_panel_and_setting_are_registered():
    rna = bpy.ops.springwrap.wrap.get_rna_type()
    assert rna.identifier == "SPRINGWRAP_OT_wrap" and rna.description
    assert bpy.types.SPRINGWRAP_OT_wrap.bl_options == {"REGISTER", "UNDO"}
    properties = rna.properties
    assert properties["max_iterations"].default == 2000
    for name in ("tolerance", "fairness", "arc_length", "thin_plate", "constraint", "folding", "schedule"):
        assert name in properties  # their defaults are the kernel's: test_wrap_defaults
    assert "only_selected" not in properties
    settings = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    assert settings.properties["unreliable_group"].type == "STRING"


def test_wrap_panel_searches_the_targets_vertex_groups():
    from springwrap.ui.panels import SPRINGWRAP_PT_wrap

    target, layout, _normal = plane_scene()
    assert SPRINGWRAP_PT_wrap.bl_parent_id == "SPRINGWRAP_PT_layout" and SPRINGWRAP_PT_wrap.poll(bpy.context)
    recorder = RecordingLayout()
    SPRINGWRAP_PT_wrap.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.operators == ["springwrap.wrap", "springwrap.rest_set"]
    layout_groups = [
        (name, "Layout", "vertex_groups")
        for name in ("stiffness_group", "free_group", "follow_group", "follow_soft_group", "surface_group")
    ]
    assert recorder.searches == [("unreliable_group", "Target", "vertex_groups"), *layout_groups]
    layout.springwrap.target = None
    recorder = RecordingLayout()
    SPRINGWRAP_PT_wrap.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert recorder.searches == layout_groups and recorder.props == [
        ("wrap_schedule", True),
        ("unreliable_group", False),
        ("find_parts", False),  # one recorder stands for every row: the disabled row before it leaves it so
    ]


def test_poll_needs_a_target():
    plane_scene()
    bpy.context.active_object.springwrap.target = None
    assert not bpy.ops.springwrap.wrap.poll()
    with pytest.raises(RuntimeError, match="No target set"):
        bpy.ops.springwrap.wrap()


# ---------------------------------------------------------------- wraps


def test_grid_above_a_plane_wraps_onto_it(capfd):
    target, layout, normal = plane_scene()
    template = world_positions(layout)
    reference = Reference(target)
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)  # no hole: the whole sheet lands
    assert_wrapped_onto(
        layout, reference, template, lambda points: np.tile(normal, (len(points), 1)), (0.5, 2.0), check_flips=False
    )
    assert layout.springwrap.target_signature == reference.signature()
    output = capfd.readouterr().out
    assert "(converged)" in output and f"{len(states)} face-points, 0 space-points" in output


def test_grid_over_a_hole_caps_it_with_space_points():
    target, layout, normal = plane_scene(hole=True)
    template = world_positions(layout)
    reference = Reference(target)
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    world = world_positions(layout)
    assert_wrapped_onto(
        layout, reference, template, lambda points: np.tile(normal, (len(points), 1)), (0.4, 2.5), check_flips=False
    )
    space = states == 0
    assert space.sum() >= 4
    # Space-points are over the hole (within one layout edge of its rim) and on the plane it was cut from.
    hole_center = np.array(target.matrix_world @ HOLE_CENTER)
    in_plane = world - hole_center - np.outer((world - hole_center) @ normal, normal)
    edge = np.median(edge_lengths(world, edges_of(layout)))
    assert np.linalg.norm(in_plane[space], axis=1).max() < HOLE_RADIUS + edge
    assert np.abs((world[space] - hole_center) @ normal).max() < 1e-3
    # ... and no point over the hole is a face-point.
    assert np.all(space[np.linalg.norm(in_plane, axis=1) < HOLE_RADIUS - edge])


@pytest.mark.parametrize("scene", ["plane", "hole", "sphere"])
def test_wraps_flip_no_quad(scene):
    if scene == "sphere":
        target, layout = sphere_scene()
        spacing = 0.6

        def surface_normals(points):
            return radial(points)

    else:
        target, layout, normal = plane_scene(hole=scene == "hole")
        spacing = 0.5

        def surface_normals(points):
            return np.tile(normal, (len(points), 1))

    wrap_with_anchors(layout, spacing=spacing)
    assert_no_flipped_quads(layout, surface_normals)


def test_grid_over_a_hole_converges(capfd):
    plane_scene(hole=True)
    wrap_with_anchors(bpy.context.active_object, spacing=0.5, max_iterations=3000)
    assert "(converged)" in capfd.readouterr().out


def test_sphere_cap_wraps_onto_a_sphere():
    target, layout = sphere_scene()
    template = world_positions(layout)
    reference = Reference(target)
    assert wrap_with_anchors(layout, spacing=0.6) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert_wrapped_onto(layout, reference, template, radial, (0.5, 2.0), check_flips=False)
    radii = np.linalg.norm(world_positions(layout) - np.array(SPHERE_CENTER), axis=1)
    assert radii.max() <= SPHERE_RADIUS + 1e-5 and radii.min() > 0.99 * SPHERE_RADIUS  # on the facets


def test_exec_default_runs_to_convergence_and_writes_once(capfd):
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    capfd.readouterr()
    assert bpy.ops.springwrap.wrap("EXEC_DEFAULT") == {"FINISHED"}
    output = capfd.readouterr().out
    assert "iterations (converged)" in output
    assert bpy.ops.springwrap.wrap("INVOKE_DEFAULT") == {"FINISHED"}  # background: invoke runs at once too


def test_iteration_limit_keeps_the_result_and_warns(capfd):
    target, layout, _normal = plane_scene()
    template = local_positions(layout).copy()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert bpy.ops.springwrap.wrap(max_iterations=3) == {"FINISHED"}
    output = capfd.readouterr().out
    assert "Warning: Wrapped 'Layout' in 3 iterations (stopped at the iteration limit)" in output
    assert local_positions(layout).tobytes() != template.tobytes()


def test_wrap_in_edit_mode_returns_to_edit_mode():
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    assert layout.mode == "EDIT"
    bpy.ops.object.mode_set(mode="OBJECT")
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert surface_distances(Reference(target), world_positions(layout)).max() <= TOLERANCE


def test_undo_after_a_wrap_restores_the_template():
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto("EXEC_DEFAULT", True, spacing=0.5)
    before = snapshot(layout)
    anchors_before = anchor_snapshot(layout)
    bpy.ops.springwrap.wrap("EXEC_DEFAULT", True)
    assert snapshot(bpy.data.objects["Layout"]) != before
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]  # undo replaced the data blocks: fetch again
    assert snapshot(layout) == before
    assert anchor_snapshot(layout) == anchors_before


def test_curves_and_seams_are_wrapped_too():
    """A layout of a quad strip with a seam and a loose edge chain (a curve): all of it lands."""
    target, _normal = plane_target()
    layout = curves_layout(target, shift=0.037)
    assert wrap_with_anchors(layout, spacing=0.35) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)
    assert surface_distances(Reference(target), world_positions(layout)).max() <= TOLERANCE


def test_space_points_next_to_anchors_on_target_vertices_fold():
    """Anchors exactly on target vertices (one-hot barycentrics): their neighbours still fold (a kernel fix)."""
    target, _normal = plane_target()
    layout = curves_layout(target, shift=0.0)  # every other vertex, the anchored ones, is over a target vertex
    assert wrap_with_anchors(layout, spacing=0.35) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)


# ---------------------------------------------------------------- the modal logic, without a window


@pytest.mark.parametrize("start", ["fresh", "with_state"])
def test_cancel_restores_positions_and_attributes_bit_for_bit(start):
    from springwrap.core.wrap_run import WrapLoop

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    if start == "with_state":
        layout.data.vertices.foreach_set("select", np.arange(len(layout.data.vertices)) % 3 == 0)
        bpy.ops.springwrap.project(direction="NORMAL", only_selected=True)  # a hybrid: some face-points
    before = snapshot(layout)
    anchors_before = anchor_snapshot(layout)
    loop = WrapLoop(wrap_session(layout))
    for _ in range(3):  # frames of one iteration each (wrap_session)
        assert loop.handle("TIMER") == "RUNNING_MODAL"
    assert loop.session.frames == 3
    assert snapshot(layout)["positions"] != before["positions"]  # the frames were written
    assert read_state(layout) is not None
    assert loop.handle("MOUSEMOVE") == "PASS_THROUGH"
    assert loop.handle("A", "PRESS") == "RUNNING_MODAL"  # blocked, not acted on
    assert loop.handle("ESC", "PRESS") == "CANCELLED"
    assert loop.error is None and loop.result is None
    assert snapshot(layout) == before
    assert anchor_snapshot(layout) == anchors_before
    assert loop.handle("TIMER") == "CANCELLED"  # nothing runs after a cancel


def test_right_click_cancels_too():
    from springwrap.core.wrap_run import WrapLoop

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    loop = WrapLoop(wrap_session(layout))
    loop.handle("TIMER")
    assert loop.handle("RIGHTMOUSE", "RELEASE") == "RUNNING_MODAL"
    assert loop.handle("RIGHTMOUSE", "PRESS") == "CANCELLED"
    assert snapshot(layout) == before


def test_modal_loop_finishes_with_the_same_result_as_exec():
    """Frames of a few iterations each end exactly where one synchronous run ends (the solver is deterministic)."""
    from springwrap.core.wrap_run import WrapLoop

    plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    loop = WrapLoop(wrap_session(bpy.context.active_object))
    outcome = "RUNNING_MODAL"
    while outcome == "RUNNING_MODAL":
        outcome = loop.handle("TIMER")
    assert outcome == "FINISHED" and loop.result.converged and loop.result.frames > 2
    live = snapshot(bpy.data.objects["Layout"])
    assert live == wrapped_at_once()


def test_the_schedule_changes_the_wrap():
    """The global-to-local schedule ends elsewhere than the local one (the energy solver's setting)."""
    results = {}
    for schedule in ("LOCAL", "GLOBAL_TO_LOCAL"):
        bpy.ops.wm.read_homefile(use_empty=True)
        plane_scene()
        bpy.ops.springwrap.anchors_auto(spacing=0.5)
        assert bpy.ops.springwrap.wrap(schedule=schedule) == {"FINISHED"}
        results[schedule] = snapshot(bpy.data.objects["Layout"])
    assert results["LOCAL"] != results["GLOBAL_TO_LOCAL"]


def test_the_automatic_schedule_follows_the_anchors():
    """Automatic wraps as Global to Local with a few anchors and as Local with many on a small change of
    shape (anchors straight below a grid over a plane: a similarity of the template places them)."""
    for spacing, count_ok, chosen in (
        (1.2, lambda count: 3 <= count < 12, "GLOBAL_TO_LOCAL"),
        (0.3, lambda count: count >= 12, "LOCAL"),
    ):
        results = {}
        for schedule in ("AUTO", "LOCAL", "GLOBAL_TO_LOCAL"):
            bpy.ops.wm.read_homefile(use_empty=True)
            plane_scene()
            bpy.ops.springwrap.anchors_auto(spacing=spacing)
            count = len(bpy.data.objects["Layout"].springwrap.anchors)
            assert count_ok(count), count
            assert bpy.ops.springwrap.wrap(schedule=schedule) == {"FINISHED"}
            results[schedule] = snapshot(bpy.data.objects["Layout"])
        assert results["LOCAL"] != results["GLOBAL_TO_LOCAL"], spacing
        assert results["AUTO"] == results[chosen], spacing


def test_an_error_mid_way_restores_the_layout():
    from springwrap.core.wrap_run import WrapLoop

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    session = wrap_session(layout)

    class FailingSolver:
        """The real solver for two frames, then a kernel error."""

        def __init__(self, solver):
            self.solver, self.calls = solver, 0

        def step(self, iterations, **keywords):
            self.calls += 1
            if self.calls > 2:
                import springwrap_kernel

                raise springwrap_kernel.InternalError("simulated failure")
            return self.solver.step(iterations, **keywords)

        def __getattr__(self, name):
            return getattr(self.solver, name)

    session.solver = FailingSolver(session.solver)
    loop = WrapLoop(session)
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    assert loop.handle("TIMER") == "RUNNING_MODAL"
    assert snapshot(layout) != before
    assert loop.handle("TIMER") == "CANCELLED"
    assert "simulated failure" in str(loop.error)
    assert snapshot(layout) == before


def _rest_bytes(layout):
    rest = layout.data.attributes.get("springwrap_rest")
    if rest is None:
        return None
    values = np.empty(len(rest.data) * 3, dtype=np.float32)
    rest.data.foreach_get("vector", values)
    return values.tobytes()


@pytest.mark.parametrize("start", ["fresh", "snapped, stale signature"])
def test_a_failure_inside_finish_leaves_rest_signature_anchors_and_layout_as_they_were(start, monkeypatch):
    """finish() writes the layout (positions, state, the rest shape when there is none), the target signature,
    then the anchors: a failure at its last write must put every one of them back."""
    from springwrap.blender import anchors as anchor_data
    from springwrap.blender import wrap_session as session_module

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    if start != "fresh":
        assert bpy.ops.springwrap.snap() == {"FINISHED"}
        layout.springwrap.target_signature = "stale"  # as if the target's faces had changed since
    before, anchors_before, rest_before = snapshot(layout), anchor_snapshot(layout), _rest_bytes(layout)
    assert (rest_before is None) == (start == "fresh")
    real_write_anchors = anchor_data.write_anchors
    calls = []

    def failing_write_anchors(*args, **kwargs):
        calls.append(args)
        if len(calls) == 1:  # finish()'s write fails half-way: the list cleared, nothing written back
            args[0].springwrap.anchors.clear()
            raise RuntimeError("injected failure in finish")
        return real_write_anchors(*args, **kwargs)

    monkeypatch.setattr(session_module.anchor_data, "write_anchors", failing_write_anchors)
    with pytest.raises(RuntimeError, match="The wrap failed: injected failure in finish"):
        bpy.ops.springwrap.wrap()
    assert len(calls) == 2  # finish's write, then the restore
    assert snapshot(layout) == before  # positions, state attributes, attribute names, target signature
    assert layout.springwrap.target_signature == before["signature"]
    assert _rest_bytes(layout) == rest_before
    assert anchor_snapshot(layout) == anchors_before


def test_modal_frames_each_write_the_layout_and_run_paced_iterations():
    """Every timer event is one frame: some iterations (for as long as the pacer says), then the mesh written.

    The frame rate itself is a speed target: ``benchmarks/wrap_speed.py`` measures it (live wrap), and the GUI
    lane (``make test-gui``) the share of a live wrap spent solving under software OpenGL.
    """
    from springwrap.core.wrap_run import WrapLoop

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=60, y_subdivisions=60, size=4)
    target = bpy.context.active_object
    # Large enough (about 40,000 points at the fine stage) that the wrap takes several frames.
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=100, y_subdivisions=100, size=3, location=(0.0, 0.0, 0.2))
    layout = activate_layout(bpy.context.active_object, target)
    bpy.ops.springwrap.anchors_auto(spacing=0.3)
    loop = WrapLoop(wrap_session(layout, paced=True, tolerance=1e-9, max_iterations=100_000, spring_resolution=2))
    before = local_positions(layout).copy()
    iterations, state = [], "RUNNING_MODAL"
    for _ in range(20):
        done_before = loop.session.total_iterations
        state = loop.handle("TIMER")
        iterations.append(loop.session.total_iterations - done_before)
        if state != "RUNNING_MODAL":
            break
    assert loop.session.frames == len(iterations) >= 3
    assert all(count >= 1 for count in iterations)
    assert not np.array_equal(local_positions(layout), before)  # frames are written into the mesh
    if state == "RUNNING_MODAL":
        loop.cancel()
        np.testing.assert_array_equal(local_positions(layout), before)
    else:
        assert state == "FINISHED" and loop.result.converged


def _operator_standing_in(loop, ui):
    """An object with the wrap operator's methods bound to it, as ``invoke`` leaves them (no window needed)."""
    import types

    from springwrap.operators.wrap import SPRINGWRAP_OT_wrap

    operator = types.SimpleNamespace(_loop=loop, _area=ui, _timer="timer", _mode=None, reports=[])
    operator.report = lambda kinds, text: operator.reports.append((set(kinds), text))
    for name in ("modal", "cancel", "_ended", "_show_status", "_end", "_restore_mode", "_report_result"):
        setattr(operator, name, types.MethodType(getattr(SPRINGWRAP_OT_wrap, name), operator))
    context = types.SimpleNamespace(window_manager=ui, workspace=ui, area=None, screen=types.SimpleNamespace(areas=[]))
    return operator, context


@pytest.mark.parametrize("ending", ["finish", "escape"])
def test_operator_modal_shows_progress_and_cleans_up(ending):
    from springwrap.core.wrap_run import WrapLoop

    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    ui = FakeUI()
    operator, context = _operator_standing_in(WrapLoop(wrap_session(layout)), ui)
    event = lambda kind, value="NOTHING": type("Event", (), {"type": kind, "value": value})()  # noqa: E731
    assert operator.modal(context, event("TIMER")) == {"RUNNING_MODAL"}
    assert operator.modal(context, event("MIDDLEMOUSE", "PRESS")) == {"PASS_THROUGH"}
    status = [args[0] for name, args in ui.calls if name == "status_text_set"]
    assert status and status[-1].startswith("Springwrap: iteration 1 / 2000")
    assert ("progress_update", (1,)) in ui.calls
    if ending == "escape":
        assert operator.modal(context, event("ESC", "PRESS")) == {"CANCELLED"}
        assert snapshot(layout) == before
        assert operator.reports == [({"INFO"}, "Wrap cancelled: the layout is back as it was")]
    else:
        result = {"RUNNING_MODAL"}
        while result == {"RUNNING_MODAL"}:
            result = operator.modal(context, event("TIMER"))
        assert result == {"FINISHED"}
        kinds, text = operator.reports[0]
        assert kinds == {"INFO"} and text.startswith("Wrapped 'Layout' in ") and "(converged)" in text
    ends = [name for name, _args in ui.calls[-4:]]
    assert ends == ["event_timer_remove", "progress_end", "status_text_set", "header_text_set"]
    assert ui.calls[-1] == ("header_text_set", (None,)) and ui.calls[-2] == ("status_text_set", (None,))
    assert operator._timer is None


def test_modal_actions():
    from springwrap.core.wrap_run import modal_action

    assert modal_action("ESC", "PRESS") == "CANCEL"
    assert modal_action("RIGHTMOUSE", "PRESS") == "CANCEL"
    assert modal_action("ESC", "RELEASE") == "BLOCK"
    assert modal_action("TIMER", "NOTHING") == "STEP"
    for navigation in ("MIDDLEMOUSE", "WHEELUPMOUSE", "MOUSEMOVE", "TRACKPADPAN", "NUMPAD_5"):
        assert modal_action(navigation, "PRESS") == "PASS"
    assert modal_action("LEFTMOUSE", "PRESS") == "BLOCK"
    assert modal_action("Z", "PRESS") == "BLOCK"


def test_frame_pacer_gives_the_solver_its_share_of_the_measured_frame():
    from springwrap.core.wrap_run import FramePacer

    pacer = FramePacer(frame_rate=30.0, solver_share=0.6, max_solve_seconds=2.0)
    assert pacer.solve_seconds() == pytest.approx(1 / 30)  # nothing measured: a frame at 30 per second
    pacer.record_display(0.005)  # a GPU: the rest of the 1/30 s frame
    assert pacer.solve_seconds() == pytest.approx(1 / 30 - 0.005)
    slow = FramePacer(max_solve_seconds=2.0, display_seconds=1.0)  # software OpenGL: 60 %, 1.5 s for a 1 s redraw
    assert slow.solve_seconds() == pytest.approx(1.5)
    slow.record_display(3.0)  # smoothed: (1 + 3) / 2 = 2 s of display, 3 s of solving, capped
    assert slow.display_seconds == pytest.approx(2.0) and slow.solve_seconds() == pytest.approx(2.0)
    assert FramePacer(display_seconds=1 / 30).solve_seconds() == pytest.approx(0.05)  # never below its share

    # Chunks within a frame: one iteration to measure it, then what fits in the time left.
    assert pacer.next_count(100_000, 0.03) == 1
    pacer.record_step(1, 0.001)
    assert pacer.next_count(100_000, 0.02) == 20
    assert pacer.next_count(7, 0.02) == 7  # never beyond what remains
    assert pacer.next_count(100_000, 0.0001) == 1  # time left, less than an iteration: still one
    assert pacer.next_count(100_000, 0.0) == 0  # the frame's time is used
    assert pacer.next_count(0, 1.0) == 0
    pacer.new_stage()  # a finer spring mesh: its iterations are measured again, from one
    assert pacer.iteration_seconds is None and pacer.next_count(100_000, 0.02) == 1
    with pytest.raises(ValueError, match="solver_share"):
        FramePacer(solver_share=1.0)


def test_a_slow_display_gets_long_solving_frames_and_a_fast_one_short_ones():
    """The frame's solve time follows the measured display: 0.4 s of display gives 0.6 s of solving, none 1/30 s."""
    from springwrap.core.wrap_run import FramePacer

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=60, y_subdivisions=60, size=4)
    target = bpy.context.active_object
    # Large enough (about 200,000 points at the fine stage) that the wrap outlasts a 0.6 s frame.
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=150, y_subdivisions=150, size=3, location=(0.0, 0.0, 0.2))
    layout = activate_layout(bpy.context.active_object, target)
    bpy.ops.springwrap.anchors_auto(spacing=0.3)
    before = snapshot(layout)
    session = wrap_session(layout, paced=True, tolerance=1e-9, max_iterations=1_000_000, spring_resolution=3)
    session.pacer = FramePacer(display_seconds=0.4)
    session.advance()
    assert session.frames == 1 and not session.done
    assert session.kernel_seconds >= 0.45  # 0.6 s of solving (less the frame's writing and chunking)
    slow_iterations = session.total_iterations
    session.pacer.display_seconds = 0.0
    session.advance()
    fast_iterations = session.total_iterations - slow_iterations
    # A 1/30 s frame: much less work, or the one iteration every frame runs and a second when the first took less
    # than the frame (all a loaded machine fits in 0.6 s may be a few iterations: 5 against 2 on a lane run beside
    # two others).
    assert fast_iterations <= 2 or fast_iterations < slow_iterations / 4, (slow_iterations, fast_iterations)
    session.cancel()
    assert snapshot(layout) == before


def test_the_fine_stage_starts_with_one_measured_iteration_not_the_coarse_stages_pace():
    """A frame that ends the coarse stage (cheap iterations) does not run the fine one (many times dearer) to its end
    on the coarse stage's cost: the fine stage's first call is one iteration, then what fits the frame."""
    from springwrap.core.wrap_run import FramePacer

    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    session = wrap_session(layout, paced=True, tolerance=1e-9, spring_resolution=6)
    session.pacer = FramePacer(display_seconds=0.05)  # frames of about 0.075 s of solving
    asked, step = [], session.step

    def recorded(count):
        report = step(count)
        asked.append((session.stage, count))  # the stage the call ran in (a call may start the fine stage)
        return report

    session.step = recorded
    while session.stage == "coarse" or len([stage for stage, _count in asked if stage == "fine"]) < 2:
        session.advance()
    first_fine = next(index for index, (stage, _count) in enumerate(asked) if stage == "fine")
    assert asked[first_fine][1] == 1, asked
    session.cancel()
    assert snapshot(layout) == before


# ---------------------------------------------------------------- unreliable data


UNRELIABLE_RADIUS = 0.7


def _unreliable_group(target, radius=UNRELIABLE_RADIUS, weight=1.0):
    """A vertex group on the plane target: the vertices within ``radius`` of the hole centre."""
    coordinates = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
    target.data.vertices.foreach_get("co", coordinates)
    inside = np.linalg.norm(coordinates.reshape(-1, 3)[:, :2] - np.array(HOLE_CENTER[:2]), axis=1) < radius
    group = target.vertex_groups.new(name="Noise")
    group.add(np.flatnonzero(inside).tolist(), weight, "REPLACE")
    return group, inside


def _node_group_dropping(group_name, subdivide=False):
    """Geometry nodes removing a vertex group (after subdividing the mesh once when ``subdivide``)."""
    tree = bpy.data.node_groups.new("Drop group", "GeometryNodeTree")
    if hasattr(tree, "interface"):  # Blender 4.0 and later
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
    geometry = tree.nodes.new("NodeGroupInput").outputs[0]
    if subdivide:
        subdivision = tree.nodes.new("GeometryNodeSubdivideMesh")
        tree.links.new(geometry, subdivision.inputs["Mesh"])
        geometry = subdivision.outputs["Mesh"]
    remove = tree.nodes.new("GeometryNodeRemoveAttribute")
    remove.inputs["Name"].default_value = group_name
    tree.links.new(geometry, remove.inputs["Geometry"])
    tree.links.new(remove.outputs["Geometry"], tree.nodes.new("NodeGroupOutput").inputs[0])
    return tree


def _unreliable_region_mask(layout, target, radius):
    local = np.array(target.matrix_world.inverted())
    world = world_positions(layout)
    in_target = world @ local[:3, :3].T + local[:3, 3]
    return np.linalg.norm(in_target[:, :2] - np.array(HOLE_CENTER[:2]), axis=1) < radius


# Before Blender 4.0 the Named Attribute node has no "Exists" output: a vertex group the target's
# modifiers drop cannot be told from one with zero weights, so it reads as weight 0 everywhere.
NEEDS_GROUP_EXISTS = pytest.mark.skipif(
    bpy.app.version < (4, 0, 0), reason="Blender < 4.0 cannot tell a dropped vertex group (no Named Attribute 'Exists')"
)


@pytest.mark.parametrize("modifier", [None, "SUBSURF", pytest.param("REMOVE_GROUP", marks=NEEDS_GROUP_EXISTS)])
def test_points_on_unreliable_triangles_stay_space_points(modifier):
    target, layout, normal = plane_scene()
    _unreliable_group(target)
    if modifier == "SUBSURF":  # the evaluated target's weights are interpolated ones
        target.modifiers.new("Subdivision", "SUBSURF").levels = 1
    elif modifier == "REMOVE_GROUP":  # the evaluated mesh loses the group: the base mesh's weights are used
        target.modifiers.new("Drop", "NODES").node_group = _node_group_dropping("Noise")
    layout.springwrap.unreliable_group = "Noise"
    assert bpy.ops.springwrap.anchors_auto(spacing=0.5) == {"FINISHED"}
    anchored, _locations = anchor_targets(layout)
    assert bpy.ops.springwrap.wrap(max_iterations=600) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    edge = np.median(edge_lengths(world_positions(layout), edges_of(layout)))
    # Unreliable triangles have all three corners in the group: the disk less a target edge (0.1).
    deep_inside = _unreliable_region_mask(layout, target, UNRELIABLE_RADIUS - 0.1 - edge)
    deep_inside[anchored] = False  # an anchor is a constraint: it lands on its target whatever the data
    assert deep_inside.sum() >= 4
    assert np.all(states[deep_inside] == 0)
    outside = ~_unreliable_region_mask(layout, target, UNRELIABLE_RADIUS + edge)
    assert np.all(states[outside] == 1)


def test_without_the_unreliable_group_the_same_points_land():
    target, layout, _normal = plane_scene()
    _unreliable_group(target)
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)


def test_low_weights_are_reliable():
    target, layout, _normal = plane_scene()
    _unreliable_group(target, weight=0.5)  # not more than 0.5: reliable
    layout.springwrap.unreliable_group = "Noise"
    assert wrap_with_anchors(layout, spacing=0.5) == {"FINISHED"}
    states, _faces, _barycentrics = read_state(layout)
    assert np.all(states == 1)


def test_unreliable_triangles_need_all_three_corners_heavy():
    from springwrap.core.wrap_inputs import unreliable_triangles

    triangles = np.array([[0, 1, 2], [1, 2, 3], [2, 3, 4]])
    weights = np.array([0.9, 0.6, 0.51, 0.5, 1.0])
    assert unreliable_triangles(triangles, weights).tolist() == [True, False, False]


# ---------------------------------------------------------------- bad input


def _no_faces_no_edges(target, layout):
    mesh = bpy.data.meshes.new("Points")
    mesh.from_pydata([(0.0, 0.0, 0.3), (0.5, 0.0, 0.3)], [], [])
    layout.data = mesh
    return "has no faces and no edges"


def _zero_length_edge(target, layout):
    coordinates = local_positions(layout).copy()
    coordinates[1] = coordinates[0]
    layout.data.vertices.foreach_set("co", coordinates.reshape(-1))
    layout.data.update()
    return "zero length"


def _anchor_on_a_missing_vertex(target, layout):
    layout.springwrap.anchors.add().vertex_index = 9999
    layout.springwrap.anchors[-1].location = (0.0, 0.0, 0.0)
    # The last anchor: how many anchors_auto spread before it depends on the Blender version's grid.
    last = len(layout.springwrap.anchors) - 1
    return (
        rf"1 anchors are on vertices the layout no longer has \(it has 169\): anchor {last} \(vertex 9999\): the "
        r"layout lost vertices after they were anchored. Remove those anchors \(or Clear Anchors\) and anchor again; "
        r"Update Anchors re-reads target points only"
    )


def _nan_layout_vertex(target, layout):
    coordinates = local_positions(layout).copy()
    coordinates[7, 1] = np.nan
    layout.data.vertices.foreach_set("co", coordinates.reshape(-1))
    layout.data.update()
    return "Layout vertex 7 has a NaN"


def _target_without_triangles(target, layout):
    mesh = bpy.data.meshes.new("Edges only")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1), (1, 2)], [])
    target.data = mesh
    return "has no faces"


def _missing_group(target, layout):
    layout.springwrap.unreliable_group = "Nowhere"
    return "no vertex group 'Nowhere'"


BAD_INPUTS = {
    "no faces and no edges": (_no_faces_no_edges, {}),
    "zero-length edge": (_zero_length_edge, {}),
    "anchor on a missing vertex": (_anchor_on_a_missing_vertex, {}),
    "NaN layout vertex": (_nan_layout_vertex, {}),
    "target without triangles": (_target_without_triangles, {}),
    "missing unreliable group": (_missing_group, {}),
    # Weights beyond their range are clamped by Blender to the kernel's range (tests/addon/test_ranges.py);
    # a tolerance of 0 is the one value the properties let through and the kernel refuses.
    "zero tolerance": (None, {"tolerance": 0.0}),
}
_WEIGHT_MESSAGES = {
    "zero tolerance": r"tolerance must be within \(0, 1\], not 0",
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_is_reported_and_leaves_the_layout_untouched(case):
    target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    spoil, properties = BAD_INPUTS[case]
    message = spoil(target, layout) if spoil is not None else _WEIGHT_MESSAGES[case]
    before = snapshot(layout)
    anchors_before = anchor_snapshot(layout)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.springwrap.wrap(**properties)
    assert snapshot(layout) == before
    assert anchor_snapshot(layout) == anchors_before
    assert set(bpy.data.objects.keys()) == {"Target", "Layout"}  # no leftover probe object


@NEEDS_GROUP_EXISTS
def test_unreliable_group_dropped_with_a_changed_vertex_count_is_an_error():
    target, layout, _normal = plane_scene()
    _unreliable_group(target)
    target.modifiers.new("Drop", "NODES").node_group = _node_group_dropping("Noise", subdivide=True)
    layout.springwrap.unreliable_group = "Noise"
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="drop the vertex group 'Noise'"):
        bpy.ops.springwrap.wrap()
    assert snapshot(layout) == before
    assert set(bpy.data.node_groups.keys()) == {"Drop group"} and set(bpy.data.objects.keys()) == {"Target", "Layout"}
