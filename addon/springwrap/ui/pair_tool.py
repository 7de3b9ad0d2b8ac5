"""The pair tool in the 3D view's toolbar (Object and Edit Mode of a mesh): its keymap starts the pair tool's
operator (``operators.pair_tool``) on the first mouse move or click in the view; its tool settings show the
layout's Live and Symmetric settings."""

import bpy

OBJECT_TOOL = "springwrap.pair_tool"
EDIT_TOOL = "springwrap.pair_tool_edit"

_KEYMAP = (
    ("springwrap.pair_tool", {"type": "MOUSEMOVE", "value": "ANY"}, None),
    ("springwrap.pair_tool", {"type": "LEFTMOUSE", "value": "PRESS"}, None),
)


def _draw_settings(context, layout, _tool):
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        return
    layout.prop(obj.springwrap, "pair_live")
    layout.prop(obj.springwrap, "anchor_symmetric")


class SpringwrapPairTool(bpy.types.WorkSpaceTool):
    """Anchor pairs with the mouse: click a layout vertex and a target point, drag a pair's ends, X removes"""

    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_idname = OBJECT_TOOL
    bl_label = "Anchor Pairs"
    bl_description = (
        "Click a layout vertex and a target point (either order) to pair them; drag a pair's ends; X removes the "
        "pair under the mouse; Ctrl+click: a point in space; Esc leaves"
    )
    bl_icon = "ops.gpencil.primitive_line"
    bl_keymap = _KEYMAP
    draw_settings = _draw_settings


class SpringwrapPairToolEdit(SpringwrapPairTool):
    """The same tool in Edit Mode's toolbar (it works out of edit mode while it runs)"""

    bl_context_mode = "EDIT_MESH"
    bl_idname = EDIT_TOOL


TOOLS = (SpringwrapPairTool, SpringwrapPairToolEdit)

_registered: list = []


def install() -> None:
    """Add the tools to the toolbars (once; nothing in background mode)."""
    if bpy.app.background or _registered:
        return
    for tool in TOOLS:
        bpy.utils.register_tool(tool, separator=True)
        _registered.append(tool)


def uninstall() -> None:
    """Remove what :func:`install` added."""
    while _registered:
        bpy.utils.unregister_tool(_registered.pop())
