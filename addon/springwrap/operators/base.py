"""What every Springwrap operator starts with: why it cannot run (``poll`` and ``execute`` say the same), the
layout and its target checked, a layout with shape keys refused; and the shared run of the operators that
edit the layout's lists.

The kernel is imported with the add-on (``properties`` reads its defaults when the add-on is enabled, and
says so when it is missing), so an operator never finds it absent.
"""

import contextlib

import bpy

from ..blender import layout as layout_data
from ..blender.edit_mode import object_mode
from ..core.errors import ERRORS


def layout_problem(context, require_target=True) -> str | None:
    """Why the operators cannot run on the active object, or None when they can."""
    layout = context.active_object
    if layout is None or layout.type != "MESH":
        return "No active mesh object (the layout)"
    target = layout.springwrap.target
    if target is None:
        return "No target set (Springwrap panel in the sidebar)" if require_target else None
    if target == layout:
        return "The target is the layout itself"
    if target.type != "MESH":
        return f"Target '{target.name}' is not a mesh"
    return None


def poll_layout(cls, context, require_target=True) -> bool:
    """A layout operator's ``poll``: whether it can run, with the reason set when not."""
    problem = layout_problem(context, require_target)
    if problem is not None:
        cls.poll_message_set(problem)
        return False
    return True


def open_layout(
    operator,
    context,
    require_target=True,
    moves_vertices=False,
    consequence: str = layout_data.SHAPE_KEYS_CONSEQUENCE,
) -> bpy.types.Object | None:
    """The common opening of a layout operator's ``execute``: :func:`layout_problem`, then (when it moves
    vertices) the refusal of shape keys. The layout, or None after an ERROR report saying why not."""
    problem = layout_problem(context, require_target)
    if problem is not None:
        operator.report({"ERROR"}, problem)
        return None
    layout = context.active_object
    if moves_vertices:
        try:
            layout_data.refuse_shape_keys(layout, consequence)
        except ERRORS as error:
            operator.report({"ERROR"}, str(error))
            return None
    return layout


class LayoutOperator:
    """Shared ``poll`` of the operators that act on the active layout (and, by default, need its target)."""

    requires_target = True

    @classmethod
    def poll(cls, context):
        return poll_layout(cls, context, cls.requires_target)


class LayoutCollectionOperator:
    """Shared poll, guard and report of the operators that edit what the layout keeps besides its
    positions: its lists (anchors, curve constraints) and its rest shape.

    A subclass names the list (``collection``) and what to say when it is empty, and implements
    :meth:`run`: compute the complete new list, write it, and return the reports. Everything is
    checked before anything is written; any problem is reported as an error and the list is left
    exactly as it was.
    """

    collection = ""
    """Name of the collection property on ``object.springwrap``."""
    empty_message = ""
    """The poll message when the collection is needed but empty."""
    requires_target = True
    requires_items = False
    reads_layout_mesh = True  # leaves edit mode for the duration, so the mesh data is current

    @classmethod
    def problem(cls, context):
        """Why the operator cannot run on the active object, or None when it can."""
        problem = layout_problem(context, cls.requires_target)
        if problem is not None:
            return problem
        if cls.requires_items and not len(getattr(context.active_object.springwrap, cls.collection)):
            return cls.empty_message
        return None

    @classmethod
    def poll(cls, context):
        problem = cls.problem(context)
        if problem is not None:
            cls.poll_message_set(problem)
            return False
        return True

    def execute(self, context):
        problem = self.problem(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return {"CANCELLED"}
        layout = context.active_object
        try:
            with object_mode(layout) if self.reads_layout_mesh else contextlib.nullcontext():
                reports = self.run(context, layout)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        for level, message in reports:
            self.report(level, message)
        return {"FINISHED"}

    def run(self, context, layout):
        """Compute and write the new list; return ``[(report level set, message), ...]``.

        Raises one of ``core.errors.ERRORS`` on bad input, before writing anything."""
        raise NotImplementedError
