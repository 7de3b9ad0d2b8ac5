"""The sidebar as a workflow: the panels' order and which are closed, the live progress and the
last wrap in the panel, the cage display and its undoing, and the message when numpy is missing.

How it looks at the default sidebar width is checked on screenshots of a real Blender (``make test-gui``).
"""

import json
import subprocess
import sys
import types

import bpy

import pytest

from bpy_helpers import PanelRecorder, RecordingLayout, plane_scene, snapshot, wrap_session
from helpers import REPOSITORY


def draw(panel_class, recorder=None):
    recorder = recorder or PanelRecorder()
    assert panel_class.poll(bpy.context)
    panel_class.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    return recorder


def test_the_steps_come_in_the_artists_order_and_the_point_tools_are_closed():
    from springwrap.ui import panels

    order = [(cls.bl_label, getattr(cls, "bl_parent_id", "")) for cls in panels.classes]
    assert order == [
        ("Springwrap", ""),
        ("Place", "SPRINGWRAP_PT_layout"),
        ("Armature", "SPRINGWRAP_PT_align"),
        ("Anchors", "SPRINGWRAP_PT_layout"),
        ("Curve Constraints", "SPRINGWRAP_PT_anchors"),
        ("Wrap", "SPRINGWRAP_PT_layout"),
        ("Over Time", "SPRINGWRAP_PT_layout"),
        ("Check", "SPRINGWRAP_PT_layout"),
        ("Subdivision Fit", "SPRINGWRAP_PT_check"),
        ("Snap", "SPRINGWRAP_PT_layout"),
        ("Project", "SPRINGWRAP_PT_layout"),
        ("Detach", "SPRINGWRAP_PT_layout"),
        ("Mirror", "SPRINGWRAP_PT_layout"),
        ("Features", "SPRINGWRAP_PT_layout"),
    ]
    closed = {cls.bl_label for cls in panels.classes if "DEFAULT_CLOSED" in getattr(cls, "bl_options", set())}
    assert closed == {
        "Armature",
        "Curve Constraints",
        "Subdivision Fit",
        "Snap",
        "Project",
        "Detach",
        "Mirror",
        "Features",
    }


def test_the_wrap_panel_shows_the_live_progress_instead_of_the_button():
    from springwrap.blender import wrap_session as sessions
    from springwrap.ui.panels import SPRINGWRAP_PT_wrap

    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert draw(SPRINGWRAP_PT_wrap, RecordingLayout()).operators[0] == "springwrap.wrap"
    session = wrap_session(layout)
    sessions.set_running(session)
    try:
        session.advance()
        session.advance()
        recorder = draw(SPRINGWRAP_PT_wrap, RecordingLayout())
    finally:
        sessions.set_running(session, running=False)
        session.cancel()
    assert recorder.operators == ["springwrap.rest_set"]
    assert recorder.labels[:4] == ["Iteration", "2", "Limit", "2000"]
    assert recorder.labels[4] == "Last Move" and "Esc: cancel" in recorder.labels
    assert sessions.running_session(layout) is None


def test_the_check_panel_reads_the_points_and_the_last_wrap():
    from springwrap.ui.panels import SPRINGWRAP_PT_check

    _target, layout, _normal = plane_scene()
    assert draw(SPRINGWRAP_PT_check).labels == ["On Surface", "0", "In Space", str(len(layout.data.vertices))]
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    labels = draw(SPRINGWRAP_PT_check).labels
    on_surface = int(labels[1])
    assert on_surface > 0 and on_surface + int(labels[3]) == len(layout.data.vertices)
    assert labels[4] == "Last Wrap" and labels[5] in ("Converged", "At the limit")
    assert labels[6] == "Iterations" and int(labels[7]) > 0 and labels[8] == "Time"
    assert "Solving" not in labels  # run at once (a script): no frames
    bpy.ops.wm.read_homefile(use_empty=True)  # another file: its "Layout" is not the one wrapped
    _target, layout, _normal = plane_scene()
    assert "Last Wrap" not in draw(SPRINGWRAP_PT_check).labels


def test_the_check_panel_shows_what_last_changed_the_layout():
    """After a fit the panel shows the fit (the cage's points are off the surface by design, not "In Space"),
    after a mirror the mirror, after a snap nothing of the wrap before it."""
    from bpy_helpers import head_scene
    from springwrap.ui.panels import SPRINGWRAP_PT_check

    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchors_auto(spacing=0.5)
    assert bpy.ops.springwrap.wrap() == {"FINISHED"}
    assert "Last Wrap" in draw(SPRINGWRAP_PT_check).labels
    assert bpy.ops.springwrap.fit_subdivision(levels=1, rounds=1) == {"FINISHED"}
    labels = draw(SPRINGWRAP_PT_check).labels
    assert "Last Wrap" not in labels and "In Space" not in labels and "On Surface" not in labels
    assert labels[:2] == ["Cage Points", str(len(layout.data.vertices))]
    assert labels[labels.index("Last Fit") + 1] == "Level 1" and "Surface Max" in labels
    assert bpy.ops.springwrap.snap() == {"FINISHED"}
    labels = draw(SPRINGWRAP_PT_check).labels
    assert labels[0] == "On Surface" and not any(label.startswith("Last ") for label in labels)
    bpy.ops.wm.read_homefile(use_empty=True)
    _target, layout = head_scene()
    assert bpy.ops.springwrap.mirror(axis="X", max_iterations=200) == {"FINISHED"}
    labels = draw(SPRINGWRAP_PT_check).labels
    assert labels[labels.index("Last Mirror") + 1] in ("Converged", "At the limit")


def test_the_place_panel_counts_one_anchor_in_the_singular():
    from springwrap.ui.panels import SPRINGWRAP_PT_align

    _target, layout, _normal = plane_scene()
    assert bpy.ops.springwrap.anchor_add(vertex_index=0) == {"FINISHED"}
    assert draw(SPRINGWRAP_PT_align).labels[0] == "Fit to 1 anchor, then ICP"
    assert bpy.ops.springwrap.anchor_add(vertex_index=1) == {"FINISHED"}
    assert draw(SPRINGWRAP_PT_align).labels[0] == "Fit to 2 anchors, then ICP"


def set_show_cage(layout, value: bool) -> None:
    """The panel's Show Cage checkbox. The PyPI bpy 4.2 module registers the property without its update
    callback (``compat.property_update``: it crashes at exit otherwise), so there the update is called here."""
    from springwrap.blender import cage_display, compat

    layout.springwrap.show_cage = value
    if compat.property_update(cage_display.update_show_cage) is None:
        cage_display.update_show_cage(layout.springwrap, bpy.context)


def test_the_cage_shows_over_the_target_and_puts_the_users_display_back():
    _target, layout, _normal = plane_scene()
    layout.display_type = "SOLID"
    layout.show_in_front = False
    set_show_cage(layout, True)
    assert layout.show_in_front and layout.display_type == "WIRE"
    saved = json.loads(layout.springwrap.cage_saved_display)
    assert saved["show_in_front"] is False and saved["display_type"] == "SOLID"
    layout.display_type = "BOUNDS"  # changed while the cage shows: the setting from before the cage wins
    set_show_cage(layout, False)
    assert not layout.show_in_front and layout.display_type == "SOLID"
    assert layout.springwrap.cage_saved_display == ""


def test_the_cage_survives_save_and_reload(tmp_path):
    _target, layout, _normal = plane_scene()
    layout.show_in_front = True
    set_show_cage(layout, True)
    path = tmp_path / "cage.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    layout = bpy.data.objects["Layout"]
    assert layout.springwrap.show_cage and layout.display_type == "WIRE"
    set_show_cage(layout, False)
    assert layout.show_in_front and layout.display_type == "TEXTURED"


def test_the_cage_turns_the_retopology_overlay_on_in_every_view_and_back():
    from springwrap.blender import cage_display

    if not cage_display.has_retopology_overlay():
        pytest.skip(f"Blender {bpy.app.version_string} has no Retopology overlay (4.0+)")

    def view(show, offset):
        overlay = types.SimpleNamespace(show_retopology=show, retopology_offset=offset)
        return types.SimpleNamespace(type="VIEW_3D", spaces=[types.SimpleNamespace(type="VIEW_3D", overlay=overlay)])

    areas = [view(False, 0.2), types.SimpleNamespace(type="OUTLINER", spaces=[]), view(True, 0.05)]
    screen = types.SimpleNamespace(name="Layout", areas=areas)
    window_manager = types.SimpleNamespace(windows=[types.SimpleNamespace(screen=screen)])
    _target, layout, _normal = plane_scene()
    cage_display.show_cage(layout, window_manager)
    overlays = [areas[0].spaces[0].overlay, areas[2].spaces[0].overlay]
    assert all(o.show_retopology and o.retopology_offset == cage_display.RETOPOLOGY_OFFSET for o in overlays)
    cage_display.hide_cage(layout, window_manager)
    assert (overlays[0].show_retopology, overlays[0].retopology_offset) == (False, 0.2)
    assert (overlays[1].show_retopology, overlays[1].retopology_offset) == (True, 0.05)


def test_showing_the_cage_is_undone_with_the_rest():
    _target, layout, _normal = plane_scene()
    bpy.ops.ed.undo_push(message="before the cage")
    before = snapshot(layout)
    set_show_cage(layout, True)
    bpy.ops.ed.undo_push(message="cage")
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert not layout.springwrap.show_cage and layout.display_type == "TEXTURED" and not layout.show_in_front
    assert snapshot(layout) == before


@pytest.mark.parametrize(
    ("error", "expected"),
    [
        (ModuleNotFoundError("No module named 'numpy'", name="numpy"), "sudo apt-get install python3-numpy"),
        (ImportError("The Springwrap kernel is not available (springwrap_kernel)"), "in a checkout: make setup."),
        (ImportError("something else", name="gpu"), "something else"),
    ],
)
def test_the_missing_dependency_message_says_the_fix(error, expected):
    import springwrap

    lines = springwrap.missing_dependency_lines(error)
    assert expected in " ".join(lines)
    assert all(len(line) <= springwrap.MESSAGE_WIDTH for line in lines)  # read whole in the sidebar (make test-gui)


def test_the_missing_dependency_panel_and_preferences_draw_the_message():
    import springwrap

    springwrap._register_missing_dependency(ModuleNotFoundError("No module named 'numpy'", name="numpy"))
    try:
        panel = PanelRecorder()
        bpy.types.SPRINGWRAP_PT_missing.draw(type("Panel", (), {"layout": panel})(), bpy.context)
        preferences = PanelRecorder()
        preferences_class = springwrap._missing_classes[0]
        assert issubclass(preferences_class, bpy.types.AddonPreferences) and preferences_class.bl_idname == "springwrap"
        preferences_class.draw(type("Preferences", (), {"layout": preferences})(), bpy.context)
    finally:
        for cls in reversed(springwrap._missing_classes):
            bpy.utils.unregister_class(cls)
        springwrap._missing_classes = ()
    assert panel.labels == preferences.labels and springwrap.NUMPY_FIX in " ".join(panel.labels)


HIDE_NUMPY = r"""
import importlib.abc, sys
class HideNumpy(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" or name.startswith("numpy."):
            raise ModuleNotFoundError(f"No module named '{name}'", name=name)
sys.meta_path.insert(0, HideNumpy())
import bpy, addon_utils
module = addon_utils.enable("springwrap", default_set=True, handle_error=None)
print("RESULT", module is not None, hasattr(bpy.types, "SPRINGWRAP_PT_missing"), hasattr(bpy.types, "SPRINGWRAP_OT_wrap"))
addon_utils.disable("springwrap", default_set=True, handle_error=None)
print("DISABLED", hasattr(bpy.types, "SPRINGWRAP_PT_missing"))
"""


def test_enabling_without_numpy_registers_the_message_instead_of_failing():
    """In a fresh Python (the bpy module) where numpy cannot be imported; Debian's Blender: the GUI lane."""
    if bpy.app.binary_path:
        pytest.skip(
            "the bpy module's lanes only (a blender binary: make test-gui plays Debian's Blender without numpy)"
        )
    process = subprocess.run(
        [sys.executable, "-c", HIDE_NUMPY], capture_output=True, text=True, timeout=120, cwd=REPOSITORY, check=False
    )
    assert process.returncode == 0, process.stderr
    assert "RESULT True True False" in process.stdout, process.stdout + process.stderr
    assert "DISABLED False" in process.stdout
    assert "sudo apt-get install python3-numpy" in process.stdout


def test_an_anchor_row_reads_pair_vertex_and_distance_and_flags_a_missing_vertex():
    from springwrap.ui.lists import SPRINGWRAP_UL_anchors

    _target, layout, _normal = plane_scene()
    bpy.ops.springwrap.anchor_add(vertex_index=3, location=(0.0, 0.0, 0.0), use_location=True, on_surface=False)
    item = layout.springwrap.anchors[0]
    row = PanelRecorder()
    SPRINGWRAP_UL_anchors.draw_item(None, bpy.context, row, layout.springwrap, item, 0, None, "", 0)
    distance = (layout.matrix_world @ layout.data.vertices[3].co).length
    value, unit = row.labels[2].split()
    assert row.labels[:2] == ["1", "v3"] and float(value) * {"m": 1.0, "cm": 0.01, "mm": 0.001}[unit] == pytest.approx(
        distance, rel=5e-3
    )
    item.vertex_index = len(layout.data.vertices) + 5  # the layout lost vertices since
    row = PanelRecorder()
    SPRINGWRAP_UL_anchors.draw_item(None, bpy.context, row, layout.springwrap, item, 0, None, "", 0)
    assert row.labels == ["1", f"v{len(layout.data.vertices) + 5}", "missing"]
    assert row.alert


def test_the_subdivision_fit_button_fits_the_whole_layout_or_the_selection():
    from springwrap.ui.panels import SPRINGWRAP_PT_fit_subdivision

    _target, layout, _normal = plane_scene()
    recorder = draw(SPRINGWRAP_PT_fit_subdivision, RecordingLayout())
    assert recorder.operators == ["springwrap.fit_subdivision"]
