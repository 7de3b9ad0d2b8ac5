"""Proposed pairs under Blender: ``springwrap.anchors_propose`` on a bumpy ball whose proportions change (its tips
and pits found again on the target, near their true points), each setting changing the result, Accept and Reject
(one pair, all), the wrap leaving un-accepted pairs out, and a refusal leaving the scene as it was."""

import bpy

import numpy as np
import pytest

from bpy_helpers import PanelRecorder, anchor_snapshot, stretched_ball_scene, world_positions

LOOSE = 0.3
"""A least confidence below the default: the ball, with 3 anchors only, has few pairs above the default."""


def ball_scene(landmarks: int = 3):
    """The target: a finer bumpy ball, stretched; the layout: a coarser one where Align would put it, anchored at
    its first ``landmarks`` tips' true points. (layout, truth: each layout vertex's true point)."""
    return stretched_ball_scene(landmarks)


def proposed_rows(layout):
    return [(item.vertex_index, item.confidence) for item in layout.springwrap.anchors if item.proposed]


def test_proposals_are_added_as_proposed_pairs_near_their_true_points():
    layout, truth = ball_scene()
    assert bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE) == {"FINISHED"}
    items = list(layout.springwrap.anchors)
    assert sum(not item.proposed for item in items) == 3  # the hand pairs, unchanged
    proposed = [item for item in items if item.proposed]
    assert len(proposed) >= 3
    diagonal = np.linalg.norm(np.ptp(truth, axis=0))
    for item in proposed:
        assert 0.0 < item.confidence <= 1.0
        assert item.target_kind == "FACE"
        assert np.linalg.norm(np.array(item.location) - truth[item.vertex_index]) < 0.02 * diagonal
    # Proposing again replaces the earlier proposals (no duplicates).
    assert bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE) == {"FINISHED"}
    assert proposed_rows(layout) == [(item.vertex_index, item.confidence) for item in proposed]


def test_every_setting_changes_the_result():
    layout, _truth = ball_scene()
    bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE)
    every = proposed_rows(layout)
    assert len(every) >= 3
    bpy.ops.springwrap.anchors_propose(max_count=2, min_confidence=LOOSE)
    assert proposed_rows(layout) == every[:2]
    bpy.ops.springwrap.anchors_propose(min_confidence=every[1][1] + 1e-4)
    assert 1 <= len(proposed_rows(layout)) < len(every)
    bpy.ops.springwrap.anchors_propose(search_radius=0.002, min_confidence=LOOSE)
    assert len(proposed_rows(layout)) < len(every)
    bpy.ops.springwrap.anchors_propose(feature_scale=0.015, min_confidence=LOOSE)
    assert proposed_rows(layout) != every
    bpy.ops.springwrap.anchors_propose(accept=True, min_confidence=LOOSE)
    assert proposed_rows(layout) == []
    assert len(layout.springwrap.anchors) == 3 + len(every)


def test_accept_and_reject_one_pair_or_all():
    layout, _truth = ball_scene()
    bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE)
    count = len(proposed_rows(layout))
    settings = layout.springwrap
    settings.active_anchor_index = 3  # the first proposed pair
    first = settings.anchors[3].vertex_index
    assert bpy.ops.springwrap.anchor_accept() == {"FINISHED"}
    assert not settings.anchors[3].proposed and settings.anchors[3].vertex_index == first
    assert len(proposed_rows(layout)) == count - 1
    assert bpy.ops.springwrap.anchor_reject(index=4) == {"FINISHED"}
    assert len(settings.anchors) == 3 + count - 1
    assert len(proposed_rows(layout)) == count - 2
    # A hand pair is neither accepted nor rejected: refused, nothing changed.
    before = anchor_snapshot(layout)
    with pytest.raises(RuntimeError, match="not a proposed pair"):
        bpy.ops.springwrap.anchor_reject(index=0)
    assert anchor_snapshot(layout) == before
    assert bpy.ops.springwrap.anchor_reject(all=True) == {"FINISHED"}
    assert proposed_rows(layout) == [] and len(settings.anchors) == 4
    with pytest.raises(RuntimeError, match="no proposed pairs"):
        bpy.ops.springwrap.anchor_accept(all=True)


def test_the_wrap_leaves_unaccepted_proposals_out():
    from springwrap.core import anchors, proposals

    layout, _truth = ball_scene()
    bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE)
    listed = anchors.anchor_count(bpy_anchor_list(layout))
    used = anchors.anchor_count(proposals.used_by_wrap(bpy_anchor_list(layout)))
    assert used == 3 and listed > 3
    bpy.ops.springwrap.anchor_accept(all=True)
    assert anchors.anchor_count(proposals.used_by_wrap(bpy_anchor_list(layout))) == listed


def wrapped_ball(how: str):
    """The ball wrapped (energy solver, global-to-local schedule) from 3 hand pairs and the proposals: ``'none'``
    rejected, ``'accepted'`` accepted (soft pairs), ``'hand'`` made hand pairs at the same points (confidence 0,
    as a drag makes them). (positions, the proposals' vertices)."""
    layout, _truth = ball_scene()
    bpy.ops.springwrap.anchors_propose(accept=how != "none", min_confidence=LOOSE)
    vertices = [item.vertex_index for item in layout.springwrap.anchors][3:]
    if how == "hand":
        for item in list(layout.springwrap.anchors)[3:]:
            item.confidence = 0.0
    assert bpy.ops.springwrap.wrap(solver="ENERGY", schedule="GLOBAL_TO_LOCAL") == {"FINISHED"}
    return world_positions(layout), vertices


def test_accepted_proposals_pull_as_soft_pairs_in_the_stiff_levels():
    # They change the wrap, and differently from hand pairs at the same points, which the wrap meets exactly.
    none, _ = wrapped_ball("none")
    accepted, vertices = wrapped_ball("accepted")
    hand, _ = wrapped_ball("hand")
    assert len(vertices) >= 3
    assert np.abs(accepted - none).max() > 1e-4
    assert np.abs(accepted - hand).max() > 1e-4


def bpy_anchor_list(layout):
    from springwrap.blender import anchors as anchor_data

    return anchor_data.read_anchors(layout)


def test_too_few_anchors_is_refused_and_nothing_changes():
    layout, _truth = ball_scene(landmarks=2)
    before = anchor_snapshot(layout)
    positions = world_positions(layout)
    with pytest.raises(RuntimeError, match="at least 3 anchors"):
        bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE)
    assert anchor_snapshot(layout) == before
    np.testing.assert_array_equal(world_positions(layout), positions)


def test_the_panel_offers_accept_and_reject_while_there_are_proposals():
    from springwrap.ui.panels import SPRINGWRAP_PT_anchors

    layout, _truth = ball_scene()

    def buttons():
        recorder = PanelRecorder()
        SPRINGWRAP_PT_anchors.draw(type("Panel", (), {"layout": recorder})(), bpy.context)
        return [name for name, _properties in recorder.operators], recorder.labels

    names, _labels = buttons()
    assert "springwrap.anchors_propose" in names and "springwrap.anchor_accept" not in names
    bpy.ops.springwrap.anchors_propose(min_confidence=LOOSE)
    names, labels = buttons()
    assert names.count("springwrap.anchor_accept") == 2 and names.count("springwrap.anchor_reject") == 2
    assert f"{len(proposed_rows(layout))} proposed" in labels
