"""The add-on's layers as folders: ``springwrap.core`` imports in a plain Python (numpy and the kernel, no
``bpy``), and no add-on module grows past 500 lines."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import REPOSITORY

ADDON = REPOSITORY / "addon"
PACKAGE = ADDON / "springwrap"
BLENDER_MODULES = {"bpy", "bmesh", "mathutils", "gpu", "gpu_extras", "bpy_extras", "addon_utils"}

IMPORT_CORE = """
import importlib, pkgutil, sys
import springwrap.core as core
for module in pkgutil.iter_modules(core.__path__):
    importlib.import_module("springwrap.core." + module.name)
leaked = sorted(name for name in sys.modules if name.split(".")[0] in {names})
print("LEAKED", leaked)
"""


def imported_modules(path: Path) -> set:
    """Top-level names of the modules a source file imports (absolute imports only)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_core_imports_nothing_of_blender():
    for path in sorted((PACKAGE / "core").glob("*.py")):
        assert not imported_modules(path) & BLENDER_MODULES, path.name


@pytest.mark.skipif(
    os.environ.get("SPRINGWRAP_TEST_LANE") == "blender",
    reason="inside the blender binary sys.executable is Blender itself, not a plain Python",
)
def test_core_imports_in_a_plain_python():
    process = subprocess.run(
        [sys.executable, "-c", IMPORT_CORE.replace("{names}", repr(BLENDER_MODULES))],
        cwd=ADDON,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert process.returncode == 0, process.stderr
    assert "LEAKED []" in process.stdout, process.stdout


def test_no_add_on_module_is_over_500_lines():
    long = {
        str(path.relative_to(PACKAGE)): len(path.read_text().splitlines())
        for path in PACKAGE.rglob("*.py")
        if "_vendor" not in path.parts
    }
    assert {name: count for name, count in long.items() if count > 500} == {}
