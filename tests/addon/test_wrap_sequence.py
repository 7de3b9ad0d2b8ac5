"""Wrap Sequence: the layout wrapped at every frame of a range onto the target as it is at that frame (shape-key
animation, a Mesh Sequence Cache, one object per frame from a collection), one shape key per frame keyed so that
playback shows the layout following; Esc keeps the frames done, a failing frame keeps the previous frame's shape,
the whole sequence is one undo step."""

import bpy

import numpy as np
import pytest

from bpy_helpers import (
    SEQUENCE_FRAMES as FRAMES,
)
from bpy_helpers import (
    Reference,
    addon_module,
    animated_target,
    snapshot,
    surface_distances,
)
from bpy_helpers import (
    make_sphere_layout as make_inner_layout,
)

ON_SURFACE = 1e-4


def sequence_scene():
    target = animated_target()
    layout = make_inner_layout(target)
    bpy.context.scene.frame_set(1)
    return target, layout


def run_sequence(**properties):
    options = {"use_scene_range": False, "frame_start": FRAMES[0], "frame_end": FRAMES[-1]} | properties
    return bpy.ops.springwrap.wrap_sequence("EXEC_DEFAULT", True, **options)


def key_names(layout):
    keys = layout.data.shape_keys
    return [] if keys is None else [block.name for block in keys.key_blocks]


def key_positions(layout, name):
    block = layout.data.shape_keys.key_blocks[name]
    points = np.empty(len(block.data) * 3, dtype=np.float32)
    block.data.foreach_get("co", points)
    return points.reshape(-1, 3)


def shown_positions(layout, frame):
    """World positions of the layout as playback shows it at ``frame`` (its shape keys mixed)."""
    bpy.context.scene.frame_set(frame)
    evaluated = layout.evaluated_get(bpy.context.evaluated_depsgraph_get())
    points = np.array([tuple(vertex.co) for vertex in evaluated.data.vertices], dtype=np.float64)
    matrix = np.array(layout.matrix_world, dtype=np.float64)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def assert_follows(layout, target_at_frame):
    """At each frame the layout playback shows lies on the target as it is at that frame."""
    for frame in FRAMES:
        shown = shown_positions(layout, frame)
        reference = Reference(target_at_frame(frame))
        assert surface_distances(reference, shown).max() < ON_SURFACE * reference.diagonal, frame


def test_a_shape_key_animation_is_followed_frame_by_frame():
    target, layout = sequence_scene()
    assert run_sequence() == {"FINISHED"}
    assert key_names(layout) == ["Basis", "Wrap 0001", "Wrap 0002", "Wrap 0003"]
    assert_follows(layout, lambda frame: target)
    first, last = key_positions(layout, "Wrap 0001"), key_positions(layout, "Wrap 0003")
    assert np.ptp(last[:, 0]) > 1.3 * np.ptp(first[:, 0])  # the layout stretched with the target
    assert np.array_equal(key_positions(layout, "Basis"), first)  # the first frame is the layout's own wrap
    assert bpy.context.scene.frame_current == FRAMES[-1]  # set by the check above; the run set it back
    assert layout.springwrap.target_signature


def test_the_scene_frame_is_set_back():
    _target, _layout = sequence_scene()
    bpy.context.scene.frame_set(2)
    run_sequence()
    assert bpy.context.scene.frame_current == 2


def has_alembic() -> bool:
    """Whether this Blender was built with Alembic (its exporter is registered)."""
    try:
        bpy.ops.wm.alembic_export.get_rna_type()
    except (KeyError, AttributeError):
        return False
    return True


@pytest.mark.skipif(not has_alembic(), reason="this Blender was built without Alembic")
def test_a_mesh_sequence_cache_is_followed(tmp_path):
    source, _ = sequence_scene()
    path = str(tmp_path / "target.abc")
    bpy.ops.object.select_all(action="DESELECT")
    source.select_set(True)
    assert bpy.ops.wm.alembic_export(filepath=path, start=FRAMES[0], end=FRAMES[-1], selected=True) == {"FINISHED"}
    bpy.data.objects.remove(source)
    before = set(bpy.data.objects)
    assert bpy.ops.wm.alembic_import(filepath=path) == {"FINISHED"}
    (cached,) = [obj for obj in set(bpy.data.objects) - before if obj.type == "MESH"]
    assert any(modifier.type == "MESH_SEQUENCE_CACHE" for modifier in cached.modifiers)
    assert not cached.data.shape_keys  # the motion comes from the cache alone
    layout = bpy.data.objects["Layout"]
    layout.springwrap.target = cached
    bpy.context.view_layer.objects.active = layout
    assert run_sequence() == {"FINISHED"}
    assert_follows(layout, lambda frame: cached)


def frame_collection(empty=None):
    """A collection of one sphere per frame, each larger along x, the third of another resolution (a new
    topology); the one at index ``empty`` without faces (a frame that fails)."""
    collection = bpy.data.collections.new("Frames")
    bpy.context.scene.collection.children.link(collection)
    objects = []
    for index, (segments, rings) in enumerate(((32, 16), (32, 16), (24, 12))):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=rings, radius=1.5)
        obj = bpy.context.active_object
        obj.name = f"Frame {index + 1}"
        obj.scale = (1.0 + 0.15 * index, 1.0, 1.0)
        for owner in obj.users_collection:
            owner.objects.unlink(obj)
        collection.objects.link(obj)
        objects.append(obj)
    if empty is not None:
        import bmesh

        mesh = bmesh.new()
        mesh.from_mesh(objects[empty].data)
        bmesh.ops.delete(mesh, geom=list(mesh.faces), context="FACES_ONLY")
        mesh.to_mesh(objects[empty].data)
        mesh.free()
    return objects


def test_one_object_per_frame_even_when_the_topology_changes():
    objects = frame_collection()
    layout = make_inner_layout(objects[0])
    assert run_sequence(source="COLLECTION", collection="Frames") == {"FINISHED"}
    assert key_names(layout) == ["Basis", "Wrap 0001", "Wrap 0002", "Wrap 0003"]
    assert_follows(layout, lambda frame: objects[frame - 1])


def test_a_failing_frame_keeps_the_previous_shape_and_says_so():
    objects = frame_collection(empty=1)
    layout = make_inner_layout(objects[0])
    sequence = addon_module("blender.wrap_sequence")
    run = sequence.SequenceRun(bpy.context, layout, _parameters(), list(FRAMES), bpy.data.collections["Frames"])
    while not run.done:
        run.advance()
    result = run.finish()
    assert [outcome.ok for outcome in result.outcomes] == [True, False, True]
    assert "no faces" in result.outcomes[1].message
    assert "1 failed" in result.summary()
    assert np.array_equal(key_positions(layout, "Wrap 0002"), key_positions(layout, "Wrap 0001"))
    reference = Reference(objects[2])
    bpy.context.scene.frame_set(3)
    assert surface_distances(reference, shown_positions(layout, 3)).max() < ON_SURFACE * reference.diagonal


def _parameters(**settings):
    import springwrap_kernel

    return addon_module("core.wrap_inputs").WrapParameters(settings=springwrap_kernel.WrapSettings(**settings))


def test_esc_keeps_the_frames_done_and_nothing_half_written():
    _target, layout = sequence_scene()
    sequence = addon_module("blender.wrap_sequence")
    loop = addon_module("core.sequence").SequenceLoop(
        sequence.SequenceRun(bpy.context, layout, _parameters(), list(FRAMES))
    )
    assert loop.handle("TIMER") == "RUNNING_MODAL"  # frame 1
    assert loop.handle("MOUSEMOVE") == "PASS_THROUGH"
    assert loop.handle("TIMER") == "RUNNING_MODAL"  # frame 2
    assert loop.handle("ESC", "PRESS") == "FINISHED"
    assert loop.result.stopped and len(loop.result.outcomes) == 2
    assert key_names(layout) == ["Basis", "Wrap 0001", "Wrap 0002"]
    assert np.array_equal(key_positions(layout, "Basis"), key_positions(layout, "Wrap 0001"))
    assert bpy.context.scene.frame_current == 1


def test_the_sequence_is_one_undo_step():
    _target, layout = sequence_scene()
    bpy.ops.ed.undo_push(message="The scene")
    before = snapshot(layout)
    run_sequence()
    assert key_names(bpy.data.objects["Layout"])
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert key_names(layout) == []
    assert snapshot(layout) == before


def test_a_second_run_replaces_the_keys_of_the_first():
    _target, layout = sequence_scene()
    run_sequence()
    assert run_sequence(frame_end=2) == {"FINISHED"}
    assert key_names(layout) == ["Basis", "Wrap 0001", "Wrap 0002"]


def test_later_frames_rest_in_the_previous_frame_or_the_template():
    target, layout = sequence_scene()
    run_sequence(warm_rest="PREVIOUS")
    previous = key_positions(layout, "Wrap 0003")
    bpy.data.objects.remove(layout)
    layout = make_inner_layout(target)
    run_sequence(warm_rest="TEMPLATE")
    assert not np.allclose(key_positions(layout, "Wrap 0003"), previous, atol=1e-6)
    assert_follows(layout, lambda frame: target)


def test_template_frames_are_each_the_wrap_of_that_frame_alone():
    """Later Frames: Template wraps every frame from the layout as it was before the sequence, so each key is the
    shape a single wrap onto that frame gives, whatever the frames before it did."""
    target, layout = sequence_scene()
    run_sequence(warm_rest="TEMPLATE")
    keys = {frame: key_positions(layout, f"Wrap {frame:04d}") for frame in FRAMES}
    session_module = addon_module("blender.wrap_session")
    parameters = addon_module("core.wrap_inputs").WrapParameters()
    for frame in FRAMES[1:]:
        bpy.context.scene.frame_set(frame)
        alone = make_inner_layout(target, name=f"Alone {frame}")
        session = session_module.WrapSession(bpy.context, alone, parameters)
        session.run()
        session.finish()
        single = np.array([tuple(vertex.co) for vertex in alone.data.vertices], dtype=np.float32)
        assert np.allclose(keys[frame], single, atol=1e-5), frame
    assert not np.allclose(keys[FRAMES[-1]], keys[FRAMES[0]], atol=1e-3)


@pytest.mark.parametrize(
    ("properties", "message"),
    [
        ({"frame_end": 0}, "empty"),
        ({"source": "COLLECTION", "collection": "Missing"}, "No collection"),
    ],
)
def test_bad_input_is_refused_and_nothing_written(properties, message):
    _target, layout = sequence_scene()
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match=message):
        run_sequence(**properties)
    assert snapshot(layout) == before and key_names(layout) == []


def test_shape_keys_of_the_layout_s_own_are_refused():
    _target, layout = sequence_scene()
    layout.shape_key_add(name="Basis")
    layout.shape_key_add(name="Smile")
    with pytest.raises(RuntimeError, match="shape keys of its own"):
        run_sequence()
    assert key_names(layout) == ["Basis", "Smile"]


def test_a_first_frame_that_fails_writes_nothing():
    objects = frame_collection(empty=0)
    layout = make_inner_layout(objects[1])
    before = snapshot(layout)
    with pytest.raises(RuntimeError, match="first frame"):
        run_sequence(source="COLLECTION", collection="Frames")
    assert snapshot(layout) == before and key_names(layout) == []


def has_exporter(file_format) -> bool:
    """Whether this Blender was built with the exporter of ``file_format``."""
    return bool(getattr(bpy.app.build_options, "alembic" if file_format == "ALEMBIC" else "usd", False))


def imported_positions(path, frame):
    """World positions, at ``frame``, of the mesh a point cache file imports as (the import removed after)."""
    before = set(bpy.data.objects)
    importer = bpy.ops.wm.alembic_import if path.endswith(".abc") else bpy.ops.wm.usd_import
    assert importer(filepath=path) == {"FINISHED"}
    (imported,) = [obj for obj in set(bpy.data.objects) - before if obj.type == "MESH"]
    try:
        assert any(modifier.type == "MESH_SEQUENCE_CACHE" for modifier in imported.modifiers)
        return shown_positions(imported, frame)
    finally:
        for obj in set(bpy.data.objects) - before:
            bpy.data.objects.remove(obj)


def export_sequence(path, file_format):
    return bpy.ops.springwrap.export_sequence("EXEC_DEFAULT", filepath=str(path), file_format=file_format)


@pytest.mark.parametrize(("file_format", "suffix"), [("ALEMBIC", ".abc"), ("USD", ".usdc")])
def test_the_sequence_exports_as_a_point_cache_that_reads_back_frame_for_frame(tmp_path, file_format, suffix):
    if not has_exporter(file_format):
        pytest.skip(f"this Blender was built without {file_format}")
    _target, layout = sequence_scene()
    other = make_inner_layout(bpy.data.objects["Target"])  # selected, not exported
    other.select_set(True)
    bpy.context.view_layer.objects.active = layout
    run_sequence()
    scene = bpy.context.scene
    scene.frame_set(2)
    settings = (scene.frame_start, scene.frame_end, [obj.name for obj in bpy.context.selected_objects])
    assert export_sequence(tmp_path / "layout", file_format) == {"FINISHED"}
    path = str(tmp_path / f"layout{suffix}")  # the format's extension added
    assert (scene.frame_current, scene.frame_start, scene.frame_end) == (2, settings[0], settings[1])
    assert [obj.name for obj in bpy.context.selected_objects] == settings[2]
    expected = {frame: shown_positions(layout, frame) for frame in FRAMES}
    for frame in FRAMES:
        assert np.abs(imported_positions(path, frame) - expected[frame]).max() < 1e-5, frame
    assert not np.allclose(expected[FRAMES[0]], expected[FRAMES[-1]], atol=1e-3)  # the frames differ


def test_a_layout_without_sequence_keys_exports_nothing(tmp_path):
    _target, _layout = sequence_scene()
    with pytest.raises(RuntimeError, match="no sequence keys"):
        export_sequence(tmp_path / "layout.abc", "ALEMBIC")
    assert not list(tmp_path.iterdir())


def test_each_frame_s_steps_are_timed():
    _target, layout = sequence_scene()
    sequence_module = addon_module("blender.wrap_sequence")
    parameters = addon_module("core.wrap_inputs").WrapParameters()
    run = sequence_module.SequenceRun(bpy.context, layout, parameters, FRAMES)
    while not run.done:
        run.advance()
    run.finish()
    assert set(run.step_seconds[FRAMES[0]]) == {"target", "session", "solve", "write"}  # an ordinary wrap
    assert set(run.step_seconds[FRAMES[-1]]) == {"target", "region", "session", "solve", "write"}
    assert all(seconds >= 0.0 for steps in run.step_seconds.values() for seconds in steps.values())


def test_the_over_time_panel_offers_the_export():
    from bpy_helpers import PanelRecorder
    from springwrap.ui import panels

    sequence_scene()
    recorder = PanelRecorder()
    panels.SPRINGWRAP_PT_over_time.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert "springwrap.export_sequence" in [idname for idname, _button in recorder.operators]


def test_a_slow_change_adds_up_until_the_layout_follows_it():
    """Each frame moves the target by less than a change that counts (1e-5 of its size), two frames by more, and
    renumbers its vertices (a new topology, as a scan's would be: the face-points are found again): the vertices
    held on one frame are settled once their distance's change since they were last settled counts."""
    step = 3e-5  # the target's diagonal is about 5.2, so a change counts above about 5.2e-5
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.5)
    sphere = bpy.context.active_object
    points = np.array([tuple(vertex.co) for vertex in sphere.data.vertices])
    faces = [list(polygon.vertices) for polygon in sphere.data.polygons]
    bpy.data.objects.remove(sphere)
    collection = bpy.data.collections.new("Frames")
    bpy.context.scene.collection.children.link(collection)
    objects = []
    for index in range(4):
        order = np.random.default_rng(index).permutation(len(points))  # new vertex numbers every frame
        number = np.argsort(order)
        mesh = bpy.data.meshes.new(f"Frame {index + 1}")
        renumbered = [number[face].tolist() for face in faces]
        mesh.from_pydata((points[order] + [index * step, 0.0, 0.0]).tolist(), [], renumbered)
        obj = bpy.data.objects.new(f"Frame {index + 1}", mesh)
        collection.objects.link(obj)
        objects.append(obj)
    layout = make_inner_layout(objects[0])
    options = {"use_scene_range": False, "frame_start": 1, "frame_end": 4, "source": "COLLECTION"}
    assert run_sequence(**options, collection="Frames") == {"FINISHED"}
    last = surface_distances(Reference(objects[-1]), shown_positions(layout, 4))
    assert last.max() < 1.7 * step  # settled on frame 3 (two steps), one step behind at most
    assert np.abs(shown_positions(layout, 4) - shown_positions(layout, 1)).max() > 1.5 * step  # it followed


def test_a_target_back_in_its_first_shape_gives_the_first_frame_s_wrap_again():
    """A target stretched and let go again (frames 1 to 5): where it changed, a re-settle starts from the
    template's shape as a wrap from the template does, so that on the last frame (the target as on the first)
    the layout is the first frame's wrap again, not one carried over from the stretched frames."""
    target, layout = sequence_scene()
    stretch = target.data.shape_keys.key_blocks["Stretch"]
    for frame, value in ((4, 0.5), (5, 0.0)):
        stretch.value = value
        stretch.keyframe_insert("value", frame=frame)
    assert run_sequence(frame_end=5) == {"FINISHED"}
    first, last = key_positions(layout, "Wrap 0001"), key_positions(layout, "Wrap 0005")
    # measured 2e-7 (float32 rounding); carried over from the stretched frames it was 0.008 mean, 0.024 at most
    assert np.linalg.norm(last - first, axis=1).max() < 1e-5


@pytest.mark.parametrize(("schedule", "later"), [("AUTO", "GLOBAL_TO_LOCAL"), ("LOCAL", "LOCAL")])
def test_later_frames_wrap_the_region_started_again_global_to_local_unless_a_schedule_was_chosen(
    monkeypatch, schedule, later
):
    """The first frame is an ordinary wrap with the chosen schedule; a later frame's changed region, started again
    from the template with vertices held around it (the target pushed out on one side), is wrapped global to local
    when the schedule is Auto, with the chosen one otherwise, over the changed vertices grown by three rings of
    layout edges."""
    module = addon_module("blender.wrap_sequence")
    made = []

    def spy(context, layout, parameters, **options):
        region = options.get("region")
        part = None if region is None else not region.all()
        made.append((part, parameters.settings.schedule))
        return session_class(context, layout, parameters, **options)

    def region_spy(*arguments):
        rings.append(arguments[6])
        return changed_region(*arguments)

    session_class, changed_region, rings = module.WrapSession, module.follow.changed_region, []
    monkeypatch.setattr(module, "WrapSession", spy)
    monkeypatch.setattr(module.follow, "changed_region", region_spy)
    target, _layout = sequence_scene()
    keys = target.data.shape_keys
    keys.animation_data_clear()
    keys.key_blocks["Stretch"].value = 0.0
    bump = target.shape_key_add(name="Bump", from_mix=False)  # the side at +x alone pushed out
    points = np.empty(len(bump.data) * 3, dtype=np.float32)
    bump.data.foreach_get("co", points)
    points = points.reshape(-1, 3)
    points[points[:, 0] > 1.0] *= 1.1
    bump.data.foreach_set("co", points.reshape(-1))
    for frame, value in zip(FRAMES, (0.0, 0.5, 1.0)):
        bump.value = value
        bump.keyframe_insert("value", frame=frame)
    assert run_sequence(schedule=schedule) == {"FINISHED"}
    assert made[0] == (None, schedule)
    assert [part for part, _used in made[1:]] == [True, True]
    assert {used for _part, used in made[1:]} == {later}
    assert rings == [module.follow.RESTART_RINGS] * 2  # the changed vertices grown by three rings
