"""Every test here runs under Blender (the PyPI ``bpy`` module, or a blender binary through
``tests/run_in_blender.py``): before each, the scene is reset to an empty file and the Springwrap add-on is
enabled, its target cache emptied and undo initialized."""

import runpy

import pytest

from helpers import REPOSITORY


@pytest.fixture(scope="session")
def springwrap_installed():
    """Link the add-on into bpy's add-on folder (idempotent) and check that it enables."""
    import bpy  # noqa: F401  (addon_utils needs bpy imported first)

    import addon_utils

    install = runpy.run_path(str(REPOSITORY / "blender_scripts" / "install_addon.py"))
    assert install["main"]() == 0, "blender_scripts/install_addon.py could not enable the add-on"
    return addon_utils


@pytest.fixture(autouse=True)
def blender_scene(springwrap_installed):
    """An empty scene, the add-on enabled, its target cache empty, undo initialized."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    if not springwrap_installed.check("springwrap")[1]:
        assert springwrap_installed.enable("springwrap", default_set=True, handle_error=None) is not None
    from springwrap.blender import target

    target.clear_target_cache()
    # In background mode undo starts disabled: the first push initializes it.
    bpy.ops.ed.undo_push(message="Springwrap test start")
    yield bpy
    if bpy.context.object is not None and bpy.context.object.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
