"""Plain tests of the add-on's bpy-free proposal logic (``addon/springwrap/core/proposals.py``): accepting and
rejecting proposed pairs on arrays, which anchors a wrap uses, and the list fields surviving the list
operations. No Blender."""

import numpy as np
import pytest

from helpers import core_module

an = core_module("anchors")
pr = core_module("proposals")
errors = core_module("errors")


def listed():
    """Two hand pairs, then three proposed ones."""
    count = 5
    return an.make_anchors(
        np.arange(count) * 10,
        np.full(count, an.FACE_ANCHOR),
        np.arange(count),
        np.tile([1.0, 0.0, 0.0], (count, 1)),
        np.zeros((count, 3)),
        proposed=[False, False, True, True, True],
        confidences=[0.0, 0.0, 0.9, 0.6, 0.4],
    )


def test_the_wrap_uses_hand_and_accepted_pairs_only():
    anchors = listed()
    assert pr.used_by_wrap(anchors).vertex_indices.tolist() == [0, 10]
    accepted, count = pr.accept(anchors, 3)
    assert count == 1
    assert pr.used_by_wrap(accepted).vertex_indices.tolist() == [0, 10, 30]
    assert accepted.confidences.tolist() == pytest.approx([0.0, 0.0, 0.9, 0.6, 0.4])
    every, count = pr.accept(anchors)
    assert count == 3 and an.anchor_count(pr.used_by_wrap(every)) == 5


def test_reject_removes_proposed_pairs_only():
    anchors = listed()
    kept, count = pr.reject(anchors, 2)
    assert count == 1 and kept.vertex_indices.tolist() == [0, 10, 30, 40]
    kept, count = pr.reject(anchors)
    assert count == 3 and kept.vertex_indices.tolist() == [0, 10]
    with pytest.raises(errors.LayoutError, match="not a proposed pair"):
        pr.reject(anchors, 0)
    with pytest.raises(errors.LayoutError, match="no anchor 9"):
        pr.accept(anchors, 9)
    with pytest.raises(errors.LayoutError, match="no proposed pairs"):
        pr.accept(kept)


def test_the_flags_survive_take_concatenate_and_a_new_state():
    anchors = listed()
    both = an.concatenate(an.take(anchors, [4, 0]), an.take(anchors, [2]))
    assert both.proposed.tolist() == [True, False, True]
    assert both.confidences.tolist() == pytest.approx([0.4, 0.0, 0.9])
    restated = an.with_state(both, an.as_state(both))
    assert restated.proposed.tolist() == [True, False, True]
