"""What every Springwrap operator starts with: why it cannot run (``poll`` and ``execute`` say the same), the
layout and its target checked, a layout with shape keys refused where they cannot be carried over, the add-on's input policy applied to what
the operation reads (:func:`check_inputs`); and the shared run of the operators that edit the layout's lists.

The kernel is imported with the add-on (``properties`` reads its defaults when the add-on is enabled, and
says so when it is missing), so an operator never finds it absent.
"""

import contextlib
import functools

import bpy

import numpy as np

from ..blender import anchors as anchor_data
from ..blender import curves as curve_data
from ..blender import layout as layout_data
from ..blender import retired
from ..blender import shape_keys as shape_key_data
from ..blender import target as target_data
from ..blender.edit_mode import object_mode
from ..core import defaults, input_policy, transforms
from ..core.errors import ERRORS, LayoutError

READS_LAYOUT = frozenset({"positions", "anchors", "curves"})
"""What an operation on the layout reads and :func:`check_inputs` checks by default: the layout's vertices,
its anchors' target points and its curve constraints' target polylines. Only the operators that remove
anchors or constraints (the way out of a broken one) read nothing of it."""


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
    vertices) shape keys: refused when the operator's ``shape_keys`` option says ``'REFUSE'``, carried over
    (by ``layout.write_layout``) when it says ``'TRANSFER'`` or the operator ``carries_shape_keys``,
    refused with ``consequence`` otherwise. The layout, or None after an ERROR report saying why not."""
    problem = layout_problem(context, require_target)
    if problem is not None:
        operator.report({"ERROR"}, problem)
        return None
    layout = context.active_object
    if moves_vertices:
        try:
            chosen = getattr(operator, "shape_keys", None)  # the wrap's and the mirror's option
            if chosen is not None:
                shape_key_data.refuse(layout, chosen, shape_key_data.REFUSED)
            elif not getattr(operator, "carries_shape_keys", False):
                layout_data.refuse_shape_keys(layout, consequence)
        except ERRORS as error:
            operator.report({"ERROR"}, str(error))
            return None
    return layout


def check_inputs(
    context,
    layout: bpy.types.Object,
    reads=READS_LAYOUT,
    with_target: bool = True,
    target_required: bool = True,
    *,
    arrays=None,
    target=None,
    anchors=None,
    curves=None,
) -> input_policy.Extent | None:
    """The add-on's input policy (``core.input_policy``) on what an operation reads; the target's extent.

    Reads the layout's target (when it has one: the extent every coordinate is judged against) and,
    as ``reads`` says, its vertices (world space), its anchors' target points and its curve
    constraints' cached polylines; raises one of ``ERRORS`` naming the first one refused. Object mode
    data: call it inside ``object_mode(layout)``. Writes nothing. ``with_target=False``: the target is
    not read (an operation that does not use it), only finiteness and the absolute limit apply; with
    ``target_required=False`` an unusable target is not this operation's problem and is not judged
    against either (Set Rest Shape with a target that lost its faces). What the caller already by the caller: ``arrays`` (``LayoutArrays``), ``target`` (``Target``), ``anchors`` and ``curves`` (as stored),
    each one given checked instead of read again.
    """
    extent = None
    if target is not None:
        extent = target.extent
    elif with_target and layout.springwrap.target is not None:
        try:
            extent = target_data.read_target(context.evaluated_depsgraph_get(), layout).extent
        except ERRORS:
            if target_required:
                raise
    if "positions" in reads:
        arrays = layout_data.read_layout(layout) if arrays is None else arrays
        if not np.all(np.isfinite(arrays.matrix_world)):
            raise LayoutError(
                f"Layout '{layout.name}' has a NaN or infinite transform: reset its location, rotation and scale"
            )
        input_policy.check_layout_points(layout.name, transforms.world_positions(arrays), extent)
    if "anchors" in reads and len(layout.springwrap.anchors):
        anchor_list = anchor_data.read_anchors(layout) if anchors is None else anchors
        input_policy.check_anchor_points(anchor_list.vertex_indices, anchor_list.locations, extent)
    if "curves" in reads and len(layout.springwrap.curve_constraints):
        curve_list = curve_data.read_curve_constraints(layout) if curves is None else curves
        input_policy.check_curve_points(curve_list, extent)
    return extent


def report_storage_precision(
    operator, layout: bpy.types.Object, extent: input_policy.Extent | None, positions: np.ndarray | None = None
) -> None:
    """A WARNING when the layout's float32 storage cannot hold the result as precisely as it was computed
    (``input_policy.storage_precision_note``); object mode data. ``positions``: the local positions the operation
    just wrote ((N, 3)), used instead of reading them back."""
    if positions is None:
        positions = layout_data.read_layout(layout).positions
    positions = np.asarray(positions, dtype=np.float32).reshape(-1, 3)  # as stored
    note = input_policy.storage_precision_note(
        layout.name, positions, transforms.matrix_array(layout.matrix_world), extent
    )
    if note is not None:
        operator.report({"WARNING"}, note)


class SpringwrapOperator:
    """What every Springwrap operator is: registered with a redo panel (F9) and one undo step, and called by the
    name its class has by Blender's convention (``SPRINGWRAP_OT_snap`` is ``bpy.ops.springwrap.snap``)."""

    bl_options = {"REGISTER", "UNDO"}

    def __init_subclass__(cls, **keywords):
        super().__init_subclass__(**keywords)
        prefix, separator, name = cls.__name__.partition("_OT_")
        if separator:
            cls.bl_idname = f"{prefix.lower()}.{name}"
        for method in ("execute", "invoke"):
            if method in cls.__dict__:
                setattr(cls, method, _refusing_non_finite_settings(cls.__dict__[method]))


def non_finite_setting(operator) -> str | None:
    """Why one of the operator's float settings is refused (``core.input_policy.setting_problem``), or None."""
    properties = operator.properties
    for prop in properties.bl_rna.properties:
        if prop.type == "FLOAT":
            value = getattr(properties, prop.identifier)
            problem = input_policy.setting_problem(
                prop.name or prop.identifier, tuple(value) if prop.is_array else value
            )
            if problem is not None:
                return problem
    return None


def _refusing_non_finite_settings(method):
    """``method`` (an operator's execute or invoke) run only when every float setting is finite: otherwise the
    operator reports why and cancels, having read and written nothing. (Blender counts the arguments of
    ``execute`` and ``invoke``: each wrapper has the method's own.)"""

    def refused(operator) -> bool:
        problem = non_finite_setting(operator)
        if problem is not None:
            operator.report({"ERROR"}, problem)
        return problem is not None

    if method.__code__.co_argcount == 3:

        @functools.wraps(method)
        def checked_invoke(self, context, event):
            return {"CANCELLED"} if refused(self) else method(self, context, event)

        return checked_invoke

    @functools.wraps(method)
    def checked(self, context):
        return {"CANCELLED"} if refused(self) else method(self, context)

    return checked


class LayoutOperator(SpringwrapOperator):
    """Shared ``poll`` of the operators that act on the active layout (and, by default, need its target)."""

    requires_target = True
    reads = READS_LAYOUT  # what check_inputs checks

    @classmethod
    def poll(cls, context):
        return poll_layout(cls, context, cls.requires_target)


class LayoutCollectionOperator(SpringwrapOperator):
    """Shared poll, guard and report of the operators that edit what the layout keeps besides its
    positions: its lists (anchors, curve constraints) and its rest shape.

    A subclass names the list (``collection``) and what to say when it is empty, and implements
    :meth:`run`: compute the complete new list, write it, and return the reports. Everything is
    checked before anything is written; any problem is reported as an error and the list is left
    exactly as it was.
    """

    collection = ""
    """Name of the collection property on ``object.springwrap``."""
    active_index = ""
    """Name of the property on ``object.springwrap`` with the position of the collection's active item."""
    empty_message = ""
    """The poll message when the collection is needed but empty."""
    requires_target = True
    requires_items = False
    reads_layout_mesh = True  # leaves edit mode for the duration, so the mesh data is current
    reads = READS_LAYOUT  # what check_inputs checks (empty for the operators that remove items)

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
                self.extent = (
                    check_inputs(context, layout, self.reads, target_required=self.requires_target)
                    if self.reads
                    else None
                )
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


class RemovesItems:
    """Mixed into the operators that remove items of a layout's list (anchors, curve constraints): the way out of
    a broken item, so they need no target, leave the mesh alone and check nothing; they run while the list has
    items. Put it first among the bases."""

    requires_target = False
    requires_items = True
    reads_layout_mesh = False
    reads = frozenset()

    def chosen_index(self, layout) -> int:
        """The position of the item to remove: the ``index`` property, or the list's active item for -1."""
        return getattr(layout.springwrap, self.active_index) if self.index == -1 else self.index


class RemovesOneItem(RemovesItems):
    """Mixed into the operators that remove one item of a layout's list (put it first among the bases): which one
    (``index``), and :meth:`remove` it."""

    index: bpy.props.IntProperty(
        name="Index", description="Position of the item in the list; -1 for the active one", default=-1, soft_min=-1
    )

    def compute(self, context, layout):
        return self.remove(layout, self.chosen_index(layout))

    def remove(self, layout, index: int):
        """What ``compute`` returns, the list without the item at ``index``; raises ``LayoutError`` when there is
        no such item."""
        raise NotImplementedError


def operator_values(operator, parameters_type, **renamed):
    """``parameters_type`` (a ``NamedTuple`` of an operation's parameters) filled from the operator's properties of
    the same names; ``renamed``: field = property name, where they differ."""
    return parameters_type(**{field: getattr(operator, renamed.get(field, field)) for field in parameters_type._fields})


def topology_change_report(outcome, on_faces: str, in_space: str) -> tuple[set, str] | None:
    """The report of an operation that found the target's topology changed, or None when it had not: how many
    of the points ``on_faces`` ("face anchors") lost their target face and became points ``in_space`` ("space
    anchors"), how many re-attached (``outcome``'s ``topology_detached_count``, ``topology_reattached_count``)."""
    detached, reattached = outcome.topology_detached_count, outcome.topology_reattached_count
    if not (detached or reattached):
        return None
    return (
        {"WARNING"} if detached else {"INFO"},
        f"Target topology changed: {detached} {on_faces} lost their target face and became {in_space}, "
        f"{reattached} re-attached",
    )


def report_retired_solver(operator, layout=None) -> None:
    """Warn when the retired spring solver was asked for: by the operator's ``solver='SPRINGS'`` (an old script or
    preset), or by ``layout``'s panel choice stored in an old ``.blend`` (removed here, so said once:
    ``blender.retired``). It wrapped with the energy solver."""
    if retired.take_retired_solver(layout):
        operator.report({"WARNING"}, defaults.retired_stored_solver_warning(layout.name))
    elif defaults.is_retired_solver(getattr(operator, "solver", "ENERGY")):
        operator.report({"WARNING"}, defaults.RETIRED_SOLVER_WARNING)


def show_modal_status(operator, context, text: str, progress: float) -> None:
    """A modal operator's progress: ``text`` in the status bar and in the header of its area (``operator._area``),
    ``progress`` on the window manager's progress indicator."""
    if context.workspace is not None:
        context.workspace.status_text_set(text)
    if getattr(operator, "_area", None) is not None:
        operator._area.header_text_set(text)
    context.window_manager.progress_update(progress)


def end_modal_display(operator, context) -> None:
    """Remove what a modal operator showed: its timer (``operator._timer``), the progress, the status bar's text and
    its area's header text."""
    window_manager = context.window_manager
    if getattr(operator, "_timer", None) is not None:
        window_manager.event_timer_remove(operator._timer)
        operator._timer = None
    window_manager.progress_end()
    if context.workspace is not None:
        context.workspace.status_text_set(None)
    if getattr(operator, "_area", None) is not None:
        operator._area.header_text_set(None)
        operator._area = None
