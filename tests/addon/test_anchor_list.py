"""The anchor list and its buttons under Blender (PyPI ``bpy``): Auto Anchors keeps hand anchors unless told to
replace them (the panel's Keep Existing), **+** outside Edit Mode says how to pick a vertex, the list's rows are
never cut, and a click on a row selects (and, in a 3D view, frames) its vertex."""

import bpy

import numpy as np
import pytest

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
