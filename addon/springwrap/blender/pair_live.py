"""The pair tool's edits while a wrap runs on the layout (its own Live re-settle, or a live wrap of the Wrap
operator): each edit of the anchor list, as written, handed to the running ``WrapSession`` (``move_anchors``: applied
between two of the solver's iterations, a move not applied yet replaced by the newest), so the layout follows a drag
while it settles; and what a drag remembers to put its pair back (Esc, right-click)."""

from typing import NamedTuple

import bpy

from ..core import anchors
from . import anchors as anchor_data
from .live_wraps import running_session


class DragStart(NamedTuple):
    """The anchor list and its active pair as they were when a drag began."""

    anchors: anchors.Anchors
    active_index: int


def live_session(layout: bpy.types.Object | None, settle):
    """The wrap an edit of ``layout``'s anchors goes to: the pair tool's re-settle ``settle`` when one runs, else a
    live wrap running on the layout; None for none."""
    if settle is not None or layout is None:
        return settle
    return running_session(layout)


def written_anchors(session, layout: bpy.types.Object) -> anchors.Anchors:
    """The layout's anchor list as written, resolved on ``session``'s target (what the solver is given)."""
    anchor_list, _resolution = anchors.resolve(
        anchor_data.read_anchors(layout), session.target, layout.springwrap.anchors_signature
    )
    return anchor_list


def takes_edits(session, layout: bpy.types.Object) -> bool:
    """Whether ``session`` can take the layout's anchors moved while it runs (``WrapSession.can_move_anchors``)."""
    return session.can_move_anchors(written_anchors(session, layout))


def send(session, layout: bpy.types.Object) -> bool:
    """Hand the layout's anchor list as written to the running ``session``; whether it took it. A session whose
    worker had ended (it was done) solves on in a new one."""
    taken = session.move_anchors(written_anchors(session, layout))
    if taken and session.worker is None and session.frames:
        session.start_worker()
    return taken


def remember(layout: bpy.types.Object) -> DragStart:
    """The anchor list and active pair now, to put back when a drag is cancelled."""
    return DragStart(anchor_data.read_anchors(layout), layout.springwrap.active_anchor_index)


def put_back(layout: bpy.types.Object, start: DragStart) -> None:
    """Write the anchor list and active pair a drag began with."""
    anchor_data.write_anchors(layout, start.anchors, start.active_index)


def cancel_keeping_anchors(session, layout: bpy.types.Object) -> None:
    """Cancel a running re-settle (``WrapSession.cancel``: the layout back bit for bit) and keep the anchor list as
    it is now: an edit is never taken back with the re-settle."""
    kept = anchor_data.read_anchors(layout)
    active = layout.springwrap.active_anchor_index
    session.cancel()
    anchor_data.write_anchors(layout, kept, active)
