"""Follow, visibly on: while the active layout follows its target, the 3D view's header shows it (a toggle that
turns it off). Nothing is drawn for a layout that does not follow."""

import bpy


def draw_header(self, context) -> None:
    """Appended to ``VIEW3D_HT_header``: the Follow toggle of the active layout, when it is on."""
    obj = context.active_object
    if obj is None or obj.type != "MESH" or not obj.springwrap.follow:
        return
    row = self.layout.row(align=True)
    row.alert = True
    row.prop(obj.springwrap, "follow", text="Following", toggle=True, icon="LINKED")


def install() -> None:
    """Add the header entry (idempotent)."""
    header = bpy.types.VIEW3D_HT_header
    if draw_header not in getattr(header, "_dyn_ui_initialize", lambda: [])():
        header.append(draw_header)


def uninstall() -> None:
    """Remove it."""
    bpy.types.VIEW3D_HT_header.remove(draw_header)
