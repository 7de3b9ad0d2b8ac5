"""Springwrap: retarget a quad patch layout (and its curves) onto a target mesh.

Each layout vertex is a face-point (on a target triangle) or a space-point (free in 3D). The
operators (``operators``) detach, snap and project layout vertices; the anchor operators
(``anchor_operators``) pair layout vertices with target points, the curve operators
(``curve_operators``) pair layout edge chains with target curves, both drawn in the 3D view by
``anchor_drawing``; the wrap (``wrap_operator``) pulls the whole layout onto the target with
springs; ``bridge`` is the one module that moves data between Blender and the Rust
kernel (``springwrap_kernel``).
"""

bl_info = {
    "name": "Springwrap",
    "author": "Springwrap developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Springwrap",
    "description": "Retarget a patch layout onto a target mesh: detach, snap, project, anchor and wrap",
    "category": "Mesh",
}

import bpy

from . import compat

compat.add_vendored_packages()  # the legacy zip's kernel, before bridge imports it

try:
    import numpy  # noqa: F401  (checked first: every module below needs it, and the kernel too)
except ImportError as _error:
    raise ImportError(
        "Springwrap needs numpy, which this Blender's Python does not have (Debian's and Ubuntu's Blender: "
        "`sudo apt-get install python3-numpy`, then enable the add-on again)"
    ) from _error

from . import (  # noqa: E402
    align_operator,
    anchor_drawing,
    anchor_operators,
    armature_operator,
    curve_operators,
    feature_operators,
    mirror_operator,
    operators,
    properties,
    ui,
    wrap_operator,
)

_modules = (
    properties,
    operators,
    align_operator,
    anchor_operators,
    curve_operators,
    wrap_operator,
    armature_operator,
    feature_operators,
    mirror_operator,
    ui,
)


def register():
    """Register the classes of every submodule and hang the settings on ``Object.springwrap``."""
    for module in _modules:
        for cls in module.classes:
            bpy.utils.register_class(cls)
    bpy.types.Object.springwrap = bpy.props.PointerProperty(type=properties.SpringwrapObjectSettings)
    anchor_drawing.install()


def unregister():
    """Undo :func:`register` in reverse order and drop the cached target meshes."""
    anchor_drawing.uninstall()
    del bpy.types.Object.springwrap
    for module in reversed(_modules):
        for cls in reversed(module.classes):
            bpy.utils.unregister_class(cls)
    import sys

    bridge = sys.modules.get(f"{__name__}.bridge")
    if bridge is not None:
        bridge.clear_target_cache()
