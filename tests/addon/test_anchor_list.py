"""The anchor list and its buttons under Blender (PyPI ``bpy``): Auto Anchors keeps hand anchors unless told to
replace them (the panel's Keep Existing), **+** outside Edit Mode says how to pick a vertex, the list's rows are
never cut, and a click on a row selects (and, in a 3D view, frames) its vertex."""

from types import SimpleNamespace

import bpy

import numpy as np
import pytest
from mathutils import Vector

from bpy_helpers import PanelRecorder, anchor_rows, anchor_snapshot, scene, set_selection

HAND_ANCHORS = ((60, (0.0, 0.0, 3.0)), (5, (0.5, 0.5, 3.0)))
"""Two anchors placed by hand (space anchors: vertex, location) before Auto Anchors runs."""


def place_hand_anchors():
    for vertex, location in HAND_ANCHORS:
        result = bpy.ops.springwrap.anchor_add(
            vertex_index=vertex, location=location, use_location=True, on_surface=False
        )
        assert result == {"FINISHED"}


def anchors_auto_button(layout):
    """The panel's Auto Anchors button: the properties it runs with, as drawn now."""
    from springwrap.ui.panels import SPRINGWRAP_PT_anchors

    recorder = PanelRecorder()
    SPRINGWRAP_PT_anchors.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert "anchor_keep" in recorder.props  # the choice is shown
    return dict(vars(dict(recorder.operators)["springwrap.anchors_auto"]))


# ---------------------------------------------------------------- Auto Anchors keeps the hand anchors


def test_auto_anchors_keeps_hand_anchors_by_default_and_says_how_many(capfd):
    target, layout = scene()
    place_hand_anchors()
    capfd.readouterr()
    assert bpy.ops.springwrap.anchors_auto(spacing=0.5) == {"FINISHED"}
    rows = anchor_rows(layout)
    assert [(row[0], row[1], row[4]) for row in rows[:2]] == [(v, "SPACE", loc) for v, loc in HAND_ANCHORS]
    added = len(rows) - 2
    assert added > 5
    assert f"Kept 2 existing anchors and added {added} anchors (spacing 0.5, CLOSEST)" in capfd.readouterr().out


def test_auto_anchors_replace_says_how_many_it_replaced(capfd):
    target, layout = scene()
    place_hand_anchors()
    capfd.readouterr()
    assert bpy.ops.springwrap.anchors_auto(spacing=0.5, replace=True) == {"FINISHED"}
    rows = anchor_rows(layout)
    assert "SPACE" not in [row[1] for row in rows]
    assert f"Replaced the 2 existing anchors with {len(rows)} anchors (spacing 0.5" in capfd.readouterr().out


@pytest.mark.parametrize("keep", [True, False])
def test_the_panels_keep_existing_changes_what_auto_anchors_does(keep):
    target, layout = scene()
    place_hand_anchors()
    assert layout.springwrap.anchor_keep  # on by default
    layout.springwrap.anchor_keep = keep
    button = anchors_auto_button(layout)
    assert button["replace"] is (not keep)
    assert bpy.ops.springwrap.anchors_auto(**button) == {"FINISHED"}
    vertices = [row[0] for row in anchor_rows(layout)]
    kinds = [row[1] for row in anchor_rows(layout)]
    assert (vertices[:2] == [60, 5] and kinds[:2] == ["SPACE", "SPACE"]) is keep
    assert ("SPACE" in kinds) is keep


# ---------------------------------------------------------------- + outside Edit Mode


def test_add_in_object_mode_says_to_enter_edit_mode_or_use_the_pair_tool():
    target, layout = scene()
    set_selection(layout, np.ones(len(layout.data.vertices), dtype=bool))  # as a fresh mesh: all selected
    before = anchor_snapshot(layout)
    with pytest.raises(RuntimeError, match="Enter Edit Mode and select the layout vertex to anchor.*Pair tool"):
        bpy.ops.springwrap.anchor_add(vertex_index=-1)
    assert anchor_snapshot(layout) == before
    set_selection(layout, np.zeros(len(layout.data.vertices), dtype=bool))
    with pytest.raises(RuntimeError, match="Enter Edit Mode"):
        bpy.ops.springwrap.anchor_add(vertex_index=-1)
    assert anchor_snapshot(layout) == before


# ---------------------------------------------------------------- the list's rows


def test_a_row_shows_six_digit_vertices_twins_mid_plane_and_missing_vertices_whole():
    from springwrap.ui.lists import MISSING, TWIN_MARK, anchor_row

    paired = anchor_row(11, 123456, 123789, 12, "3.12 cm")
    assert [cell.text for cell in paired] == ["12", "v123456", f"{TWIN_MARK}13", "3.12 cm"]
    mid = anchor_row(2, 52960, 52960, -1, "1.5 mm")
    assert [mid.number.text, mid.vertex.text, mid.twin.text] == ["3", "v52960", f"{TWIN_MARK}mid"]
    alone = anchor_row(99_999, 5296, -1, -1, "0 m")
    assert alone.number.text == "100000" and alone.vertex.text == "v5296" and alone.twin is None
    lost_twin = anchor_row(0, 7, 170_001, -1, "1 m")  # the twin anchor is not in the list: its vertex
    assert lost_twin.twin.text == f"{TWIN_MARK}v170001"
    gone = anchor_row(4, 250_000, -1, -1, None)
    assert gone.missing and gone.distance == MISSING and gone.vertex.text == "v250000"


def test_under_the_list_the_active_anchors_vertex_numbers_read_whole():
    from springwrap.ui.lists import TWIN_MARK, vertex_text
    from springwrap.ui.panels import SPRINGWRAP_PT_anchors

    assert vertex_text(123456, 123789, 160_801) == f"123456 {TWIN_MARK} 123789"
    assert vertex_text(52960, 52960, 160_801) == f"52960 {TWIN_MARK} mid"
    assert vertex_text(5296, -1, 160_801) == "5296"
    assert vertex_text(250_000, -1, 160_801) == "250000 missing"
    target, layout = scene()
    place_hand_anchors()
    layout.springwrap.active_anchor_index = 1
    recorder = PanelRecorder()
    SPRINGWRAP_PT_anchors.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
    assert f"Vertex {HAND_ANCHORS[1][0]}" in recorder.labels


WIDTHS = {"default sidebar": 229.0, "wide sidebar": 400.0, "very narrow": 150.0}


@pytest.mark.parametrize("sidebar", list(WIDTHS))
def test_the_columns_fit_the_sidebar_and_no_row_is_cut(sidebar):
    from springwrap.ui.lists import ROW_OVERHEAD, anchor_row, cell_width, columns, row_cells, widest_row

    width = WIDTHS[sidebar] - ROW_OVERHEAD
    rows = [
        anchor_row(0, 123456, 123789, 1, "3.12 cm"),
        anchor_row(1, 123789, 123456, 0, "12.3 cm"),
        anchor_row(2, 52960, 52960, -1, "0 m"),
        anchor_row(3, 5296, -1, -1, "1.02 mm"),
        anchor_row(4, 160_800, -1, -1, "4.56 m"),
    ]
    twins = [row.twin for row in rows if row.twin is not None]
    widest = widest_row(len(rows), 160_800, twins, [row.distance for row in rows])
    shown = columns(widest, width)
    names = [name for name, _size in shown]
    assert names[0] == "number" and names[-1] == "distance"  # always, in that order
    assert sum(size for _name, size in shown) <= width or names == ["number", "distance"]
    expected = {"default sidebar": ["number", "twin", "distance"], "very narrow": ["number", "distance"]}
    assert names == expected.get(sidebar, ["number", "vertex", "twin", "distance"])
    for row in rows:
        for cell, size in row_cells(row, shown):
            assert cell_width(cell) <= size, (sidebar, cell)  # whole: every row fits the widest's columns
    assert columns(widest, None) == columns(widest, 10_000.0)  # unlimited: all columns


def test_a_missing_vertex_widens_the_distance_column():
    from springwrap.ui.lists import MISSING, Cell, cell_width, columns, widest_row

    widest = widest_row(6, 160_808, [], [Cell("3.12 cm"), MISSING])
    assert widest.distance == MISSING and widest.twin is None
    assert dict(columns(widest, None))["distance"] == cell_width(MISSING)


def test_the_distance_samples_hold_the_widest_distance_text():
    from springwrap.ui.lists import Cell, _length_text, cell_width, distance_samples

    random = np.random.default_rng(5)
    distances = 10.0 ** random.uniform(-6, 3, 3000)
    samples = distance_samples(distances)
    assert samples.size <= 10 and set(samples) <= set(distances)
    for system in ("METRIC", "IMPERIAL", "NONE"):
        bpy.context.scene.unit_settings.system = system
        widest = max(cell_width(Cell(_length_text(bpy.context, value))) for value in distances)
        assert max(cell_width(Cell(_length_text(bpy.context, value))) for value in samples) == widest, system


def big_layout(target, anchors):
    """A grid layout of more than 100 000 vertices with ``anchors`` ((vertex, twin vertex), ...; space anchors
    3 cm above their vertices, a vertex out of range: no location)."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=330, y_subdivisions=330, size=2.0)
    layout = bpy.context.active_object
    layout.springwrap.target = target
    vertex_count = len(layout.data.vertices)
    assert vertex_count > 100_000
    for vertex, twin in anchors:
        item = layout.springwrap.anchors.add()
        item.vertex_index, item.twin_vertex, item.target_kind = vertex, twin, "SPACE"
        if vertex < vertex_count:
            item.location = layout.matrix_world @ layout.data.vertices[vertex].co + Vector((0.0, 0.0, 0.03))
    return layout


def sidebar_context(width):
    """What ``draw_item`` reads of a context: the sidebar region (its width), the preferences, the scene."""
    return SimpleNamespace(
        region=SimpleNamespace(width=width, type="UI"), preferences=bpy.context.preferences, scene=bpy.context.scene
    )


@pytest.mark.parametrize("width", [229, 400])
def test_the_list_draws_100k_layouts_whole_at_the_default_sidebar_width(width):
    from springwrap.ui.lists import SPRINGWRAP_UL_anchors

    target, _grid = scene()
    layout = big_layout(target, [(103456, 103789), (103789, 103456), (52960, 52960), (5296, -1)])
    labels = []
    for index, item in enumerate(layout.springwrap.anchors):
        row = PanelRecorder()
        SPRINGWRAP_UL_anchors.draw_item(None, sidebar_context(width), row, layout.springwrap, item, 0, None, "", index)
        labels.append(row.labels)
    vertices = [["v103456"], ["v103789"], ["v52960"], ["v5296"]] if width == 400 else [[]] * 4
    twins = ["\u21942", "\u21941", "\u2194mid", ""]
    for index, row in enumerate(labels):
        assert row == [str(index + 1), *vertices[index], twins[index], "3 cm"]


# ---------------------------------------------------------------- a click on a row


def selected_vertices(layout):
    selection = np.empty(len(layout.data.vertices), dtype=bool)
    layout.data.vertices.foreach_get("select", selection)
    return np.flatnonzero(selection).tolist()


def test_a_click_on_a_row_selects_its_vertex_in_object_mode():
    from springwrap.blender import anchor_view

    target, layout = scene()
    place_hand_anchors()
    set_selection(layout, np.ones(len(layout.data.vertices), dtype=bool))
    sidebar = SimpleNamespace(area=SimpleNamespace(type="VIEW_3D"), region=SimpleNamespace(type="UI"), space_data=None)
    layout.springwrap.active_anchor_index = 1  # a script (no sidebar): nothing else changes
    assert len(selected_vertices(layout)) == len(layout.data.vertices)
    anchor_view.active_anchor_changed(layout.springwrap, sidebar)  # what the list's row click calls
    assert selected_vertices(layout) == [HAND_ANCHORS[1][0]]
    assert bpy.ops.springwrap.anchor_add() == {"FINISHED"}  # + now takes the clicked vertex (Object Mode)
    with anchor_view.quietly():  # the add-on's own writes select nothing
        anchor_view.active_anchor_changed(layout.springwrap, sidebar)
    layout.springwrap.active_anchor_index = 0
    anchor_view.active_anchor_changed(layout.springwrap, sidebar)
    assert selected_vertices(layout) == [HAND_ANCHORS[0][0]]


def test_a_click_on_a_row_selects_and_activates_its_vertex_in_edit_mode():
    import bmesh

    from springwrap.blender import anchor_view

    target, layout = scene()
    place_hand_anchors()
    bpy.ops.object.mode_set(mode="EDIT")
    assert anchor_view.show_anchor(bpy.context, layout, 1)
    editable = bmesh.from_edit_mesh(layout.data)
    assert [vertex.index for vertex in editable.verts if vertex.select] == [HAND_ANCHORS[1][0]]
    assert not any(edge.select for edge in editable.edges) and not any(face.select for face in editable.faces)
    assert editable.select_history.active.index == HAND_ANCHORS[1][0]
    assert bpy.ops.springwrap.anchor_add() == {"FINISHED"}  # + takes the active vertex
    bpy.ops.object.mode_set(mode="OBJECT")
    assert selected_vertices(layout) == [HAND_ANCHORS[1][0]]


def test_a_row_of_a_missing_vertex_selects_nothing():
    from springwrap.blender import anchor_view

    target, layout = scene()
    item = layout.springwrap.anchors.add()
    item.vertex_index = len(layout.data.vertices) + 3
    set_selection(layout, np.arange(len(layout.data.vertices)) < 2)
    assert not anchor_view.show_anchor(bpy.context, layout, 0)
    assert not anchor_view.show_anchor(bpy.context, layout, 5)
    assert selected_vertices(layout) == [0, 1]


def test_a_click_on_a_row_frames_its_vertex_in_the_3d_view():
    views = [
        (window, area)
        for window in bpy.context.window_manager.windows
        for area in window.screen.areas
        if area.type == "VIEW_3D"
    ]
    if not views:
        pytest.skip("no 3D view without Blender's interface: the GUI lane (make test-gui) checks the framing")
    from springwrap.blender import compat

    if compat.property_update(print) is None:
        pytest.skip("the PyPI bpy 4.2 module registers properties without their update (compat.property_update)")
    window, area = views[0]
    target, layout = scene()
    place_hand_anchors()
    sidebar = next(region for region in area.regions if region.type == "UI")
    with bpy.context.temp_override(window=window, area=area, region=sidebar):
        layout.springwrap.active_anchor_index = 1
    vertex = HAND_ANCHORS[1][0]
    world = layout.matrix_world @ layout.data.vertices[vertex].co
    assert (Vector(area.spaces.active.region_3d.view_location) - world).length < 1e-5
    assert selected_vertices(layout) == [vertex]
