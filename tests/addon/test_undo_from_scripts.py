"""Undo from scripts, as the guide's *Scripting* section says.

Blender pushes an undo step for an operator called from Python only when the call asks for it: the positional
``undo`` argument after the execution context (``bpy.ops.springwrap.snap('EXEC_DEFAULT', True, ...)``). A plain
call adds no step of its own, so that a script can make many calls one step (``bpy.ops.ed.undo_push``). In a
headless session undo starts disabled; the conftest's first ``undo_push`` turns it on, as a script's must.
"""

import bpy

import pytest

from bpy_helpers import anchor_snapshot, plane_scene, snapshot


@pytest.mark.parametrize(
    "operation",
    [
        ("snap", {"mode": "SURFACE"}),
        ("project", {"direction": "-Z"}),
        ("anchors_auto", {"spacing": 0.5}),
        ("wrap", {"max_iterations": 50}),
    ],
    ids=lambda operation: operation[0],
)
def test_an_undoable_call_is_one_undo_step(operation):
    name, properties = operation
    _target, layout, _normal = plane_scene()
    if name == "wrap":
        bpy.ops.springwrap.anchors_auto(spacing=0.5)
    bpy.ops.ed.undo_push(message="before")
    before = (snapshot(layout), anchor_snapshot(layout))
    assert getattr(bpy.ops.springwrap, name)("EXEC_DEFAULT", True, **properties) == {"FINISHED"}
    layout = bpy.data.objects["Layout"]
    assert (snapshot(layout), anchor_snapshot(layout)) != before
    bpy.ops.ed.undo()
    layout = bpy.data.objects["Layout"]
    assert (snapshot(layout), anchor_snapshot(layout)) == before


def test_a_plain_call_adds_no_undo_step_of_its_own():
    _target, layout, _normal = plane_scene()
    bpy.ops.ed.undo_push(message="before")
    before = snapshot(layout)
    assert bpy.ops.springwrap.snap("EXEC_DEFAULT", True) == {"FINISHED"}
    snapped = snapshot(bpy.data.objects["Layout"])
    assert bpy.ops.springwrap.detach() == {"FINISHED"}  # plain: no step of its own
    assert snapshot(bpy.data.objects["Layout"]) != snapped
    bpy.ops.ed.undo()
    # One undo goes back past the snap: the plain detach was not a step between them.
    assert snapshot(bpy.data.objects["Layout"]) == before
