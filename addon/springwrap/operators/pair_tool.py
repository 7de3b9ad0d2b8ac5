"""The pair tool: anchors made and edited in the 3D view with the mouse (a modal operator; ``ui.pair_tool`` puts it
in the toolbar, the Anchors panel has a button for it).

- Hovering highlights the layout vertex a click takes (the one under the mouse on the screen) and the target
  surface point under the mouse. Two clicks make a pair: a layout vertex, then a target point, or the other way
  round; a pair on a vertex that has one replaces it. Ctrl+click puts the target end in space, at the depth of the
  pair's layout vertex (a space anchor).
- Dragging a pair's target end slides it along the target surface (a ray cast at every mouse move; the end stays
  a triangle and barycentric weights); dragging its layout end moves it to the vertex under the mouse. X or Delete
  removes the pair under the mouse. With the layout's Symmetric setting the twins follow.
- Each edit is one undo step (a whole drag is one). With Live on, an edit re-settles the layout (a wrap from where
  it is, solved in a worker thread; each timer event writes what it solved, so the view stays responsive). An edit
  made while a re-settle runs, or while a live wrap (the Wrap operator) runs on the layout, does not start it anew:
  the anchors as edited are handed to the running solver (``WrapSession.move_anchors``), at every mouse move of a
  drag (the newest wins), so the layout follows the drag; with Live on, a drag that finds nothing running starts
  the re-settle at its first move. Esc or right-click during a drag cancels the drag (the pair back where it was,
  the solver given the anchors as they were; a re-settle the drag started is cancelled, the layout back bit for
  bit). Otherwise Esc (or right-click) cancels a running re-settle (the layout back bit for bit, the edits kept), a
  second Esc leaves the tool; a live wrap's own Esc stops it as it always does. When a re-settle fails, it is
  undone and the edits are kept. Leaving the tool keeps every finished edit.

The tool holds the layout out of edit mode while it runs, as the modal wrap does (the anchors and the layout are
object data, and each edit is one undo step of the object).
"""

import bpy

import numpy as np

from ..blender import live_wraps
from ..blender import pair_tool as pair_data
from ..blender.edit_mode import EditModeGuard
from ..core import anchors, pair_pick
from ..core.errors import ERRORS
from ..ui import anchor_focus, overlays
from ..ui.pair_tool import OBJECT_TOOL
from .base import LayoutOperator
from .pair_tool_live import PairToolLive

DEFAULT_TOOL = "builtin.select_box"
"""The tool set when the pair tool is left with Esc."""
DRAG_PIXELS = 4.0
"""A press that moves farther than this before its release is a drag."""
HELP = (
    "Pair tool: click a layout vertex and a target point (either order)  •  drag an end  •  X: remove  •  "
    "Ctrl+click: point in space  •  Esc: cancel a drag, or leave"
)

_running: list = []
"""The running pair tool (at most one)."""


def running() -> bool:
    """Whether the pair tool is running."""
    return bool(_running)


class SPRINGWRAP_OT_pair_tool(PairToolLive, LayoutOperator, bpy.types.Operator):
    """Anchor pairs with the mouse: click a layout vertex and a target point, drag an end, X removes, Esc leaves"""

    bl_label = "Pair Tool"
    bl_options = set()  # every edit pushes its own undo step

    # ---------------------------------------------------------------- start and end

    def execute(self, context):
        self.report({"ERROR"}, "The pair tool works in a 3D view (scripts: Add Anchor and Remove Anchor)")
        return {"CANCELLED"}

    def invoke(self, context, event):
        if _running:
            return {"PASS_THROUGH"}
        if bpy.app.background or context.area is None or context.area.type != "VIEW_3D":
            self.report({"ERROR"}, "The pair tool works in a 3D view")
            return {"CANCELLED"}
        region = next((region for region in context.area.regions if region.type == "WINDOW"), None)
        if region is None or context.area.spaces.active.region_3d is None:
            self.report({"ERROR"}, "The pair tool works in a 3D view")
            return {"CANCELLED"}
        layout = context.active_object
        self._layout_name = layout.name
        self._area, self._region = context.area, region
        self._region_3d = context.area.spaces.active.region_3d
        if layout.mode == "EDIT":
            _set_tool(context, DEFAULT_TOOL)  # back in edit mode, the select tool (not this one again)
        self._guard = EditModeGuard(layout)
        _set_tool(context, OBJECT_TOOL)
        self._pending = None  # ("LAYOUT", vertex) or ("TARGET", location, on_surface)
        self._press = None  # (mouse, anchor index, end) of a press on an anchor end
        self._dragging = False
        self._drag_start = None  # pair_live.DragStart of the drag in progress
        self._drag_settle = False  # whether the drag in progress started the re-settle
        self._settle = None
        self._timer = None
        self._mouse = None
        _running.append(self)
        # A live wrap lets the tool's clicks through, and has it write its status again when it ends.
        live_wraps.set_tool(self._layout_name, refresh=lambda: self._status(bpy.context))
        context.window_manager.modal_handler_add(self)
        self._status(context)
        return self.modal(context, event) if event.type in {"LEFTMOUSE", "MOUSEMOVE"} else {"RUNNING_MODAL"}

    def _end(self, context, leave_tool: bool) -> None:
        """Stop: a drag in progress kept (one undo step), a running re-settle kept (finished), the drawing and the
        header cleared, the mode put back."""
        live_wraps.set_tool(None)
        if self._dragging:
            self._dragging, self._press, self._drag_start = False, None, None
            bpy.ops.ed.undo_push(message="Pair Tool: Drag Pair")
        if self._settle is not None:
            self._finish_settle(context)
        self._stop_timer(context)
        if leave_tool:
            _set_tool(context, DEFAULT_TOOL)
        layout = self._layout()
        if layout is not None:
            anchor_focus.set_hovered_anchor(layout, anchor_focus.NO_ANCHOR)
        overlays.clear_tool_points()
        pair_data.forget()
        self._area.header_text_set(None)
        self._area.tag_redraw()
        if self in _running:
            _running.remove(self)
        try:
            self._guard.restore()
            if leave_tool:
                _set_tool(context, DEFAULT_TOOL)
        except RuntimeError:  # the context may no longer allow a mode switch
            pass

    def cancel(self, context):
        """Blender ends the tool from outside (window closed, file loaded)."""
        if self in _running:
            self._end(context, leave_tool=False)

    def _layout(self):
        """The layout, found by name (an undo replaces the data blocks); None when it is gone."""
        return bpy.data.objects.get(self._layout_name)

    def _still_on(self, context) -> bool:
        """Whether the tool goes on: the layout is active and in object mode, and the pair tool still chosen."""
        layout = self._layout()
        if layout is None or context.active_object != layout or layout.mode != "OBJECT":
            return False
        tool = context.workspace.tools.from_space_view3d_mode("OBJECT", create=False) if context.workspace else None
        return tool is None or tool.idname == OBJECT_TOOL

    # ---------------------------------------------------------------- events

    def modal(self, context, event):
        try:
            return self._handle(context, event)
        except Exception as error:  # noqa: BLE001 - a modal must not leave a half-done edit or a dead handler
            self._cancel_settle(context)
            self._end(context, leave_tool=False)
            self.report({"ERROR"}, f"The pair tool stopped: {error}")
            return {"CANCELLED"}

    def _handle(self, context, event):
        if event.type == "TIMER":
            self._advance_settle(context)
            return {"PASS_THROUGH"}
        if not self._still_on(context):
            self._end(context, leave_tool=False)
            return {"FINISHED"}
        mouse = (event.mouse_x - self._region.x, event.mouse_y - self._region.y)
        inside = self._over_view(event.mouse_x, event.mouse_y)
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS" and self._dragging:
            self._cancel_drag(context, mouse)
            return {"RUNNING_MODAL"}
        right_click_cancels = (
            event.type == "RIGHTMOUSE" and inside and self._pending is None and self._settle is not None
        )
        if event.value == "PRESS" and (event.type == "ESC" or right_click_cancels):
            if self._settle is None:
                self._end(context, leave_tool=True)
                return {"FINISHED"}
            self._cancel_settle(context)
            self.report({"INFO"}, "Live re-settle cancelled: the layout is back as it was before it")
            return {"RUNNING_MODAL"}
        if event.type == "Z" and event.ctrl and event.value == "PRESS":
            if self._dragging:
                self._cancel_drag(context, mouse)
            self._cancel_settle(context)  # undo steps back over the edit, not into a half-settled layout
            return {"PASS_THROUGH"}
        if not inside and not self._dragging:
            self._hover(context, None)
            return {"PASS_THROUGH"}
        if event.type == "MOUSEMOVE":
            self._mouse = mouse
            if self._press is not None:
                moved = np.hypot(mouse[0] - self._press[0][0], mouse[1] - self._press[0][1])
                if self._dragging or moved > DRAG_PIXELS:
                    self._drag(context, mouse, event.ctrl)
                    return {"RUNNING_MODAL"}
            self._hover(context, mouse)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "PRESS":
            self._press_at(context, mouse, event.ctrl)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "RELEASE":
            self._release(context, mouse, event.ctrl)
            return {"RUNNING_MODAL"}
        if event.type in {"X", "DEL"} and event.value == "PRESS" and not (event.ctrl or event.alt or event.shift):
            self._remove_under(context, mouse)
            return {"RUNNING_MODAL"}
        if event.type == "RIGHTMOUSE" and event.value == "PRESS" and self._pending is not None:
            self._pending = None
            self._hover(context, mouse)
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}

    def _over_view(self, x: int, y: int) -> bool:
        """Whether the window pixel ``(x, y)`` is over the view itself: in the 3D view's main region and not over
        the toolbar, the sidebar or a header drawn over it."""
        for region in self._area.regions:
            within = region.x <= x < region.x + region.width and region.y <= y < region.y + region.height
            if region.type != "WINDOW" and region.width > 1 and region.height > 1 and within:
                return False
        region = self._region
        return region.x <= x < region.x + region.width and region.y <= y < region.y + region.height

    def _view(self) -> pair_pick.View:
        return pair_data.read_view(self._region, self._region_3d)

    def _status(self, context, note: str = "") -> None:
        pending = ""
        if self._pending is not None and self._pending[0] == "LAYOUT":
            pending = f"vertex {self._pending[1]} taken: click its target point  •  "
        elif self._pending is not None:
            pending = "target point taken: click its layout vertex  •  "
        settle = "re-settling…  •  " if self._live() is not None else ""
        self._area.header_text_set(f"{settle}{pending}{note + '  •  ' if note else ''}{HELP}")

    # ---------------------------------------------------------------- hover

    def _hover(self, context, mouse) -> None:
        """Highlight what a click at ``mouse`` takes (None: nothing, the mouse left the view)."""
        layout = self._layout()
        vertex_point = target_point = None
        hovered = anchor_focus.NO_ANCHOR
        if mouse is not None:
            view = self._view()
            anchor_list, starts = pair_data.anchor_ends(layout)
            hovered, _end = pair_pick.pick_end(view, starts, anchor_list.locations, mouse)
            if self._pending is None or self._pending[0] == "TARGET":
                vertex = pair_data.vertex_under_mouse(layout, view, mouse)
                if vertex >= 0:
                    vertex_point = pair_data.layout_picking(layout).world[vertex]
            if self._pending is None or self._pending[0] == "LAYOUT":
                try:
                    target_point = pair_data.target_under_mouse(context, layout, view, mouse)
                except ERRORS:
                    target_point = None
        anchor_focus.set_hovered_anchor(layout, hovered)
        overlays.set_tool_points(layout, vertex_point, target_point, self._pending_point(layout))
        self._area.tag_redraw()

    def _pending_point(self, layout):
        if self._pending is None:
            return None
        if self._pending[0] == "LAYOUT":
            return pair_data.layout_picking(layout).world[self._pending[1]]
        return self._pending[1]

    # ---------------------------------------------------------------- clicks

    def _press_at(self, context, mouse, ctrl: bool) -> None:
        layout = self._layout()
        anchor_list, starts = pair_data.anchor_ends(layout)
        index, end = pair_pick.pick_end(self._view(), starts, anchor_list.locations, mouse)
        if index >= 0 and self._pending is None:
            self._press = (mouse, index, end)  # a drag, or a click when released in place
            self._dragging = False
            return
        self._click(context, mouse, ctrl)

    def _release(self, context, mouse, ctrl: bool) -> None:
        press, self._press = self._press, None
        if self._dragging:
            self._dragging, self._drag_start = False, None
            live_wraps.set_tool(self._layout_name)
            self._edited(context, "Drag Pair")
        elif press is not None:
            self._click(context, press[0], ctrl)

    def _click(self, context, mouse, ctrl: bool) -> None:
        """A click: take the layout vertex or the target point under the mouse; the second one makes the pair."""
        layout = self._layout()
        view = self._view()
        wants_target = self._pending is not None and self._pending[0] == "LAYOUT"
        vertex = -1 if wants_target else pair_data.vertex_under_mouse(layout, view, mouse)
        if vertex >= 0 and not ctrl:
            if self._pending is None:
                self._pending = ("LAYOUT", vertex)
                self._status(context)
            else:
                _kind, location, on_surface = self._pending
                self._make_pair(context, vertex, location, on_surface)
            self._hover(context, mouse)
            return
        try:
            location, on_surface = self._target_point(context, layout, view, mouse, ctrl)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return
        if location is None:
            self._status(context, "nothing under the mouse: click a layout vertex or the target")
            return
        if wants_target:
            self._make_pair(context, self._pending[1], location, on_surface)
        else:
            self._pending = ("TARGET", location, on_surface)
            self._status(context)
        self._hover(context, mouse)

    def _target_point(self, context, layout, view, mouse, in_space: bool, reference=None):
        """``(location, on_surface)`` of a target end at ``mouse``: the target surface under it, or with
        ``in_space`` the point of the mouse ray at the depth of ``reference`` (default: the pending layout
        vertex, else the surface under the mouse, else the layout's centre); ``(None, True)`` when the ray misses."""
        hit = pair_data.target_under_mouse(context, layout, view, mouse)
        if not in_space:
            return hit, True
        if reference is None and self._pending is not None and self._pending[0] == "LAYOUT":
            reference = pair_data.layout_picking(layout).world[self._pending[1]]
        if reference is None:
            reference = hit if hit is not None else np.nanmean(pair_data.layout_picking(layout).world, axis=0)
        origin, direction = pair_pick.mouse_ray(view, mouse)
        return pair_pick.point_at_depth(origin, direction, reference, pair_pick.view_forward(view)), False

    def _make_pair(self, context, vertex, location, on_surface) -> None:
        self._pending = None
        if not self._live_takes_edit(context):
            return
        try:
            outcome = pair_data.place_pair(context, self._layout(), vertex, location, on_surface)
        except ERRORS as error:
            self.report({"ERROR"}, str(error))
            return
        self._send(context)
        number = anchor_focus.pair_number(outcome.active_index)
        self.report({"INFO"}, f"Pair {number}: vertex {vertex}" + ("" if on_surface else " (in space)"))
        self._edited(context, "Add Pair")

    # ---------------------------------------------------------------- drags and removal

    def _drag(self, context, mouse, ctrl: bool) -> None:
        """Move the pressed pair's end to ``mouse``: its target end along the surface (in space with Ctrl, or
        when it is a space anchor), its layout end onto the vertex under the mouse."""
        _start, index, end = self._press
        layout = self._layout()
        view = self._view()
        if not self._dragging and not self._begin_drag(context):
            self._press = None
            return
        anchor_list, starts = pair_data.anchor_ends(layout)
        if index >= anchor_list.vertex_indices.shape[0]:
            return
        if end == pair_pick.LAYOUT_END:
            vertex = pair_data.vertex_under_mouse(layout, view, mouse)
            if vertex >= 0 and vertex != int(anchor_list.vertex_indices[index]):
                pair_data.repick_pair(context, layout, index, vertex)
                self._send(context)
        else:
            in_space = ctrl or int(anchor_list.kinds[index]) != anchors.FACE_ANCHOR
            location, on_surface = self._target_point(
                context, layout, view, mouse, in_space, reference=anchor_list.locations[index]
            )
            if location is not None:
                pair_data.place_pair(context, layout, int(anchor_list.vertex_indices[index]), location, on_surface)
                self._send(context)
        anchor_focus.set_hovered_anchor(layout, index)
        overlays.set_tool_points(layout, None, None, None)
        self._area.tag_redraw()

    def _remove_under(self, context, mouse) -> None:
        layout = self._layout()
        anchor_list, starts = pair_data.anchor_ends(layout)
        index, _end = pair_pick.pick_end(self._view(), starts, anchor_list.locations, mouse)
        if index < 0:
            self._status(context, "no pair under the mouse to remove")
            return
        if not self._live_takes_edit(context):
            return
        pair_data.remove_pair(layout, index)
        self._send(context)
        self.report({"INFO"}, f"Removed pair {anchor_focus.pair_number(index)}")
        self._edited(context, "Remove Pair")
        self._hover(context, mouse)


def _set_tool(context, idname: str) -> None:
    """Make ``idname`` the active tool of the 3D view's current mode (when it is not already)."""
    workspace = context.workspace
    mode = "EDIT_MESH" if context.mode == "EDIT_MESH" else context.mode
    tool = workspace.tools.from_space_view3d_mode(mode, create=False) if workspace is not None else None
    if tool is not None and tool.idname == idname:
        return
    try:
        bpy.ops.wm.tool_set_by_id(name=idname, space_type="VIEW_3D")
    except (RuntimeError, TypeError):  # no such tool in this mode, or no 3D view in the context
        pass


classes = (SPRINGWRAP_OT_pair_tool,)
