"""The Blender packages (``make package``): contents, manifest, and installs into a headless Blender.

The packages are built once per session with packaging/build_packages.py from the kernel wheel in
target/wheels (the one ``make setup`` built and installed) into a temporary folder: seconds, no
compile. The extension is validated by Blender's own extension checker and installed into the
bpy module (5.0) with Blender's extension installer; the legacy zip is installed with "Install
Add-on" into Debian's blender 3.4. Each install runs in a fresh process with its own user folders,
and the venv's copy of the kernel hidden, so the kernel must come from the package.
"""

import ast
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import tomllib

import build_packages
import wheel_glibc
from helpers import REPOSITORY

ADDON = REPOSITORY / "addon" / "springwrap"

WHEEL_NAME = re.compile(r"^springwrap_kernel-(?P<version>[\d.]+)-cp311-abi3-manylinux_2_28_x86_64\.whl$")
TIMEOUT_SECONDS = 180

# Run in a fresh Blender (bpy module or blender binary): install a package, enable it, run two
# operators on a generated scene, print what happened as JSON. The kernel may only be imported from
# outside HIDDEN (the venv's site-packages), so it must come from the package.
INSTALL_AND_RUN = r'''
import importlib.abc, importlib.machinery, json, os, sys
arguments = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
form, package, hidden = arguments

class HideKernel(importlib.abc.MetaPathFinder):
    """springwrap_kernel only from sys.path entries outside ``hidden``."""
    def find_spec(self, name, path=None, target=None):
        if name != "springwrap_kernel":
            return None
        entries = [entry for entry in sys.path if not os.path.realpath(entry or ".").startswith(hidden)]
        spec = importlib.machinery.PathFinder.find_spec(name, entries)
        if spec is None:
            raise ModuleNotFoundError("springwrap_kernel: not in the package")
        return spec

sys.meta_path.insert(0, HideKernel())
import bpy, addon_utils
if form == "extension":
    result = bpy.ops.extensions.package_install_files(filepath=package, repo="user_default", enable_on_install=True)
    module_name = "bl_ext.user_default.springwrap"
else:
    result = bpy.ops.preferences.addon_install(filepath=package)
    addon_utils.modules_refresh()
    addon_utils.enable("springwrap", default_set=True, handle_error=None)
    module_name = "springwrap"
module = sys.modules[module_name]
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
target = bpy.context.active_object
bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=1.0, location=(0.0, 0.0, 1.5))
layout = bpy.context.active_object
layout.springwrap.target = target
detached = bpy.ops.springwrap.detach()
snapped = bpy.ops.springwrap.snap(mode="SURFACE")
states = [value.value for value in layout.data.attributes["springwrap_state"].data]
import springwrap_kernel
print("RESULT" + json.dumps({
    "install": sorted(result), "module_file": module.__file__, "kernel_file": springwrap_kernel.__file__,
    "operators": [sorted(detached), sorted(snapped)], "face_points": sum(states), "vertices": len(states),
    "version": bpy.app.version_string,
}))
'''


@pytest.fixture(scope="session")
def packages(tmp_path_factory) -> tuple[Path, Path]:
    """(extension zip, legacy zip), built from target/wheels into a temporary folder."""
    output = tmp_path_factory.mktemp("dist")
    return build_packages.build(REPOSITORY / "target" / "wheels", output)


def names_in(archive_path: Path) -> list[str]:
    with zipfile.ZipFile(archive_path) as archive:
        return archive.namelist()


def addon_sources() -> list[str]:
    return sorted(str(path.relative_to(ADDON)) for path in ADDON.rglob("*.py") if "_vendor" not in path.parts)


def bl_info() -> dict:
    for node in ast.parse((ADDON / "__init__.py").read_text()).body:
        if isinstance(node, ast.Assign) and node.targets[0].id == "bl_info":
            return ast.literal_eval(node.value)
    raise AssertionError("no bl_info")


def test_extension_holds_the_manifest_the_addon_and_the_kernel_wheel(packages, tmp_path):
    extension, _legacy = packages
    names = names_in(extension)
    with zipfile.ZipFile(extension) as archive:
        manifest = tomllib.loads(archive.read("blender_manifest.toml").decode())
        [wheel_name] = [name for name in names if name.startswith("wheels/")]
        wheel = tmp_path / Path(wheel_name).name
        wheel.write_bytes(archive.read(wheel_name))
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == "springwrap" and manifest["type"] == "add-on"
    assert manifest["version"] == ".".join(map(str, bl_info()["version"]))
    assert manifest["blender_version_min"] == "4.2.0"
    assert manifest["license"] == ["SPDX:GPL-3.0-or-later"]
    assert manifest["platforms"] == ["linux-x64"]
    assert manifest["wheels"] == [f"./{wheel_name}"]
    assert WHEEL_NAME.match(wheel.name).group("version") == manifest["version"]
    for source in addon_sources():  # at the root, beside the manifest
        assert source in names
    assert not [name for name in names if "__pycache__" in name or name.endswith((".pyc", ".so"))]
    assert not [name for name in names if name.startswith("_vendor")]
    with zipfile.ZipFile(wheel) as archive:
        assert not [name for name in archive.namelist() if name.startswith("numpy")]  # Blender's numpy is used
        assert "springwrap_kernel/_native.abi3.so" in archive.namelist()
    assert wheel_glibc.check(wheel) == []  # the manylinux_2_28 tag is true


def test_kernel_needs_no_glibc_newer_than_2_28(packages, tmp_path):
    extension, _legacy = packages
    with zipfile.ZipFile(extension) as archive:
        [wheel_name] = [name for name in archive.namelist() if name.startswith("wheels/")]
        wheel = tmp_path / Path(wheel_name).name
        wheel.write_bytes(archive.read(wheel_name))
    needed = wheel_glibc.wheel_glibc(wheel)
    assert set(needed) == {"springwrap_kernel/_native.abi3.so"}
    newest = needed["springwrap_kernel/_native.abi3.so"]
    assert (2, 17) <= newest <= (2, 28), newest  # it does use versioned glibc symbols, none after 2.28


def test_wheel_check_refuses_a_tag_older_than_what_the_library_needs(packages, tmp_path):
    extension, _legacy = packages
    with zipfile.ZipFile(extension) as archive:
        [wheel_name] = [name for name in archive.namelist() if name.startswith("wheels/")]
        relabelled = tmp_path / Path(wheel_name).name.replace("manylinux_2_28", "manylinux_2_17")
        relabelled.write_bytes(archive.read(wheel_name))
    [problem] = wheel_glibc.check(relabelled)
    assert "newer than its tag's 2.17" in problem


def test_build_refuses_a_manifest_naming_another_wheel(tmp_path, monkeypatch):
    manifest = tomllib.loads(build_packages.MANIFEST.read_text())
    manifest["wheels"] = ["./wheels/springwrap_kernel-0.1.0-cp311-abi3-manylinux_2_17_x86_64.whl"]
    with pytest.raises(build_packages.PackageError, match="but the kernel wheel is"):
        build_packages.check_inputs(manifest, REPOSITORY / "target" / "wheels")
    manifest["version"] = "9.9.9"
    with pytest.raises(build_packages.PackageError, match="is not bl_info's"):
        build_packages.check_inputs(manifest, REPOSITORY / "target" / "wheels")


def test_legacy_zip_holds_the_addon_folder_and_the_vendored_kernel(packages):
    _extension, legacy = packages
    names = names_in(legacy)
    assert all(name.startswith("springwrap/") for name in names)
    for source in addon_sources():
        assert f"springwrap/{source}" in names
    assert "springwrap/_vendor/springwrap_kernel/__init__.py" in names
    assert "springwrap/_vendor/springwrap_kernel/_native.abi3.so" in names
    assert not [name for name in names if "numpy" in name or "__pycache__" in name or name.endswith(".toml")]
    assert bl_info()["blender"] == (3, 4, 0)


def test_addon_imports_itself_only_relatively():
    """The extension is imported as ``bl_ext.<repository>.springwrap``: ``import springwrap...`` would fail there."""
    absolute = []
    for path in ADDON.rglob("*.py"):
        name = path.relative_to(ADDON)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                absolute += [
                    f"{name}: import {alias.name}" for alias in node.names if alias.name.split(".")[0] == "springwrap"
                ]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module.split(".")[0] == "springwrap":
                absolute.append(f"{name}: from {node.module} import ...")
    assert absolute == []


def blender_extension_checker() -> Path | None:
    """Blender's own extension command-line tool (``blender --command extension``), from the bpy module."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        return None
    found = sorted(Path(spec.submodule_search_locations[0]).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    return found[-1] if found else None


def test_extension_passes_blenders_own_validation(packages):
    checker = blender_extension_checker()
    if checker is None:
        pytest.skip("this bpy module has no extension tool (Blender < 4.2)")
    extension, _legacy = packages
    process = subprocess.run(
        [sys.executable, str(checker), "validate", str(extension)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
    )
    assert process.returncode == 0, process.stdout + process.stderr
    assert "Success" in process.stdout


def install_and_run(command: list[str], form: str, package: Path, home: Path, environment: dict) -> dict:
    """Run INSTALL_AND_RUN in a fresh process with the user folders under ``home``; its JSON."""
    script = home / "install_and_run.py"
    script.write_text(INSTALL_AND_RUN)
    hidden = os.path.realpath(Path(importlib.util.find_spec("numpy").origin).parent.parent)  # site-packages
    arguments = [form, str(package), hidden]
    full = (
        [*command, str(script), *arguments]
        if command[0] == sys.executable
        else [*command, str(script), "--", *arguments]
    )
    process = subprocess.run(
        full, capture_output=True, text=True, timeout=TIMEOUT_SECONDS, cwd=home, env={**os.environ, **environment}
    )
    output = process.stdout + process.stderr
    assert process.returncode == 0, output[-4000:]
    assert "RESULT" in process.stdout, output[-4000:]
    return json.loads(process.stdout.split("RESULT", 1)[1].splitlines()[0])


def test_extension_installs_and_runs_in_the_bpy_module(packages, tmp_path):
    if blender_extension_checker() is None:
        pytest.skip("this bpy module has no extension system (Blender < 4.2)")
    extension, _legacy = packages
    user = tmp_path / "user"
    found = install_and_run([sys.executable], "extension", extension, tmp_path, {"BLENDER_USER_RESOURCES": str(user)})
    assert found["install"] == ["FINISHED"]
    assert found["module_file"] == str(user / "extensions" / "user_default" / "springwrap" / "__init__.py")
    # Blender installed the bundled wheel into the extensions' own site-packages.
    assert found["kernel_file"].startswith(str(user / "extensions" / ".local"))
    assert found["operators"] == [["FINISHED"], ["FINISHED"]]
    assert found["face_points"] == found["vertices"] == 49


def test_legacy_zip_installs_and_runs_in_debian_blender_3_4(packages, tmp_path):
    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("no `blender` on PATH (Debian's blender 3.4: .ci/blender-packages.sh installs it)")
    version = subprocess.run([blender, "--version"], capture_output=True, text=True, timeout=60).stdout
    if not version.startswith("Blender 3.4"):
        pytest.skip(f"`blender` is {version.splitlines()[0]!r}, not Debian's 3.4")
    _extension, legacy = packages
    scripts = tmp_path / "scripts"
    (scripts / "addons").mkdir(parents=True)
    found = install_and_run(
        [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python"],
        "legacy",
        legacy,
        tmp_path,
        {"BLENDER_USER_SCRIPTS": str(scripts)},
    )
    assert found["version"].startswith("3.4")
    assert found["install"] == ["FINISHED"]
    assert found["module_file"] == str(scripts / "addons" / "springwrap" / "__init__.py")
    assert found["kernel_file"] == str(
        scripts / "addons" / "springwrap" / "_vendor" / "springwrap_kernel" / "__init__.py"
    )
    assert found["operators"] == [["FINISHED"], ["FINISHED"]]
    assert found["face_points"] == found["vertices"] == 49
