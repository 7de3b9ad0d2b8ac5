"""Springwrap: retarget a quad patch layout (and its curves) onto a target mesh.

Each layout vertex is a face-point (on a target triangle) or a space-point (free in 3D). The add-on is
cut by what each part may touch:

- ``core/``: the logic on plain arrays (state, transforms, snapping, the wrap's inputs, anchors, curves,
  alignment, armature maths, mirroring, subdivision); no ``bpy``, importable without Blender;
- ``blender/``: the only modules that read or write Blender data (evaluated meshes, attributes, edit
  mode, the layout, its target, anchors, curves, features, mirror, armature, the wrap session);
- ``operators/``: thin operators (poll, execute / invoke, report) over the two;
- ``ui/``: the sidebar's panels and lists, and the viewport overlay;
- ``properties``: all the add-on's state on ``Object.springwrap``.

The Rust kernel is the ``springwrap_kernel`` package. This file imports ``bpy`` only in :func:`register`,
so ``import springwrap.core`` works in a plain Python.
"""

import sys
import textwrap
from pathlib import Path

bl_info = {
    "name": "Springwrap",
    "author": "Springwrap developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Springwrap",
    "description": "Retarget a patch layout onto a target mesh: detach, snap, project, anchor and wrap",
    "category": "Mesh",
}


def _add_vendored_packages() -> None:
    """Put the add-on's ``_vendor`` folder first on ``sys.path`` when it has one.

    The legacy add-on zip (Blender 3.4 to 4.1, which know no extension wheels) carries the kernel
    wheel unpacked in ``springwrap/_vendor``: nothing is installed or downloaded when the add-on is
    enabled, and the kernel matching this add-on wins over any other copy. The extension (4.2+,
    the wheel installed by Blender) and a development checkout have no such folder.
    """
    vendor = Path(__file__).resolve().parent / "_vendor"
    if vendor.is_dir() and str(vendor) not in sys.path:
        sys.path.insert(0, str(vendor))


_add_vendored_packages()  # the legacy zip's kernel, before anything imports it

_registered_classes = ()
_missing_classes = ()

NUMPY_FIX = "sudo apt-get install python3-numpy"
"""The fix for a Blender whose Python has no numpy (Debian's and Ubuntu's ``blender`` package)."""


MESSAGE_WIDTH = 31
"""Characters a line of the message may have to be read whole in the sidebar at its default width."""


def missing_dependency_lines(error: ImportError) -> list[str]:
    """What the Preferences and the panel say when the add-on cannot start: short lines, the fix included.

    ``error`` is the ImportError of numpy or of the kernel (``springwrap_kernel``); any other module's
    import error is shown as it is. The first line is a title (it gets an icon), the others are
    wrapped to :data:`MESSAGE_WIDTH`, each paragraph on lines of its own.
    """
    missing = (getattr(error, "name", None) or "").split(".")[0]
    if missing == "numpy":
        title = "Springwrap needs numpy,"
        paragraphs = [
            "which this Blender's Python does not have.",
            "Debian's and Ubuntu's Blender:",
            NUMPY_FIX,
            "then disable and enable Springwrap (or restart Blender).",
        ]
    elif missing == "springwrap_kernel" or "springwrap_kernel" in str(error):
        title = "Springwrap's kernel is missing:"
        paragraphs = [
            str(error),
            "Install the package built for this Blender (the extension for 4.2+, the legacy zip for 3.4 to 4.1);",
            "in a checkout: make setup.",
        ]
    else:
        title = "Springwrap could not start:"
        paragraphs = [str(error)]
    return [title] + [line for paragraph in paragraphs for line in textwrap.wrap(paragraph, MESSAGE_WIDTH)]


def register():
    """Register the classes of every part and hang the settings on ``Object.springwrap``.

    Without numpy (Debian's Blender) or without its kernel the add-on cannot work: it then registers
    only a message, in its Preferences and in the sidebar tab, saying what is missing and how to fix
    it, instead of failing with a traceback.
    """
    global _registered_classes
    import bpy

    try:
        import numpy  # noqa: F401  (checked first: every module below needs it, and the kernel too)

        from . import properties  # the kernel: its defaults are read here, and it says so when it is missing
    except ImportError as error:
        _register_missing_dependency(error)
        return
    from . import operators, ui
    from .blender import follow, target_changes

    _registered_classes = properties.classes + operators.classes + ui.classes
    for cls in _registered_classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.springwrap = bpy.props.PointerProperty(type=properties.SpringwrapObjectSettings)
    ui.install()
    target_changes.install()
    follow.install()  # after target_changes: its handlers see the change counted


def _register_missing_dependency(error: ImportError) -> None:
    """Register the Preferences and the sidebar panel that say what is missing (the add-on itself cannot run)."""
    global _missing_classes
    import bpy

    lines = missing_dependency_lines(error)
    print("Springwrap: " + " ".join(lines))

    def draw_message(layout) -> None:
        column = layout.column(align=True)
        column.alert = True
        column.label(text=lines[0], icon="ERROR")
        for line in lines[1:]:
            column.label(text=line)

    class SpringwrapMissingPreferences(bpy.types.AddonPreferences):
        bl_idname = __name__

        def draw(self, context):
            draw_message(self.layout)

    class SPRINGWRAP_PT_missing(bpy.types.Panel):
        """Springwrap cannot start: what is missing and how to fix it"""

        bl_space_type = "VIEW_3D"
        bl_region_type = "UI"
        bl_category = "Springwrap"
        bl_label = "Springwrap"

        def draw(self, context):
            draw_message(self.layout)

    _missing_classes = (SpringwrapMissingPreferences, SPRINGWRAP_PT_missing)
    for cls in _missing_classes:
        bpy.utils.register_class(cls)


def unregister():
    """Undo :func:`register` in reverse order and drop the cached target meshes."""
    global _registered_classes, _missing_classes
    import bpy

    for cls in reversed(_missing_classes):
        bpy.utils.unregister_class(cls)
    _missing_classes = ()
    if not _registered_classes:
        return

    from . import ui
    from .blender import follow, target, target_changes, wrap_session

    follow.uninstall()
    target_changes.uninstall()
    ui.uninstall()
    del bpy.types.Object.springwrap
    for cls in reversed(_registered_classes):
        bpy.utils.unregister_class(cls)
    _registered_classes = ()
    target.clear_target_cache()
    wrap_session.forget_results()
