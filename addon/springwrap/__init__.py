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


def register():
    """Register the classes of every part and hang the settings on ``Object.springwrap``."""
    global _registered_classes
    import bpy

    try:
        import numpy  # noqa: F401  (checked first: every module below needs it, and the kernel too)
    except ImportError as error:
        raise ImportError(
            "Springwrap needs numpy, which this Blender's Python does not have (Debian's and Ubuntu's Blender: "
            "`sudo apt-get install python3-numpy`, then enable the add-on again)"
        ) from error
    from . import properties  # first: it says so when the kernel is missing

    # isort: split
    from . import operators, ui

    _registered_classes = properties.classes + operators.classes + ui.classes
    for cls in _registered_classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.springwrap = bpy.props.PointerProperty(type=properties.SpringwrapObjectSettings)
    ui.overlays.install()


def unregister():
    """Undo :func:`register` in reverse order and drop the cached target meshes."""
    global _registered_classes
    import bpy

    from . import ui
    from .blender import target

    ui.overlays.uninstall()
    del bpy.types.Object.springwrap
    for cls in reversed(_registered_classes):
        bpy.utils.unregister_class(cls)
    _registered_classes = ()
    target.clear_target_cache()
