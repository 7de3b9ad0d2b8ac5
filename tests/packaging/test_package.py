"""The Blender packages (``make package``): contents, manifest, and installs into a headless Blender.

The packages are built once per session with packaging/build_packages.py from the kernel wheel in
target/wheels (the one ``make setup`` built and installed) into a temporary folder: seconds, no
compile. The extension is validated by Blender's own extension checker and installed into the
bpy module (5.0) with Blender's extension installer; the legacy zip is installed with "Install
Add-on" into Debian's blender 3.4. Each install runs in a fresh process with its own user folders,
and the venv's copy of the kernel hidden, so the kernel must come from the package.

The other platforms' wheels (windows-x64, macos-arm64, macos-x64) are built by the release workflow
on hosted runners, not here: their packaging is checked with stand-in wheels named for them (the
real Linux wheel's Python files, a placeholder native library), through Blender's own validator.
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


STAND_IN_TAGS = {"windows-x64": "win_amd64", "macos-arm64": "macosx_11_0_arm64", "macos-x64": "macosx_10_12_x86_64"}
NATIVE_NAMES = {"windows-x64": "_native.pyd", "macos-arm64": "_native.abi3.so", "macos-x64": "_native.abi3.so"}


@pytest.fixture(scope="session")
def packages(tmp_path_factory) -> tuple[Path, Path]:
    """(extension zip, legacy zip) of linux-x64, built from target/wheels into a temporary folder."""
    output = tmp_path_factory.mktemp("dist")
    [(platform, extension, legacy)] = build_packages.build(REPOSITORY / "target" / "wheels", output)
    assert platform == "linux-x64"
    assert extension.name == f"springwrap-{extension_version()}-extension-linux_x64.zip"
    assert legacy.name == f"springwrap-{extension_version()}-legacy-linux_x64.zip"
    return extension, legacy


def extension_version() -> str:
    return tomllib.loads(build_packages.MANIFEST.read_text())["version"]


def linux_wheel() -> Path:
    [wheel] = sorted((REPOSITORY / "target" / "wheels").glob("springwrap_kernel-*.whl"))
    return wheel


def stand_in_wheel(folder: Path, platform: str) -> Path:
    """A wheel named for ``platform``: the Linux wheel's files, its native library replaced by a placeholder."""
    source = linux_wheel()
    name = source.name.replace("manylinux_2_28_x86_64", STAND_IN_TAGS[platform])
    wheel = folder / name
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(wheel, "w") as copy:
        for entry in original.namelist():
            data = original.read(entry)
            if entry.endswith("_native.abi3.so"):
                entry, data = f"springwrap_kernel/{NATIVE_NAMES[platform]}", f"stand-in for {platform}".encode()
            elif entry.endswith(".dist-info/WHEEL"):
                data = data.replace(b"manylinux_2_28_x86_64", STAND_IN_TAGS[platform].encode())
            copy.writestr(entry, data)
    return wheel


@pytest.fixture(scope="session")
def every_platform(tmp_path_factory) -> tuple[list, dict[str, Path]]:
    """build() on a folder of four wheels (the Linux one and stand-ins); (its result, wheel by platform)."""
    wheels = tmp_path_factory.mktemp("wheels")
    by_platform = {"linux-x64": wheels / linux_wheel().name}
    shutil.copy(linux_wheel(), by_platform["linux-x64"])
    for platform in STAND_IN_TAGS:
        by_platform[platform] = stand_in_wheel(wheels, platform)
    return build_packages.build(wheels, tmp_path_factory.mktemp("dist")), by_platform


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
    assert wheel_name.endswith("-manylinux_2_28_x86_64.whl")
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


def test_build_refuses_a_manifest_with_its_own_wheels_or_another_version(tmp_path):
    manifest = tomllib.loads(build_packages.MANIFEST.read_text())
    manifest["wheels"] = ["./wheels/springwrap_kernel-0.1.0-cp311-abi3-manylinux_2_17_x86_64.whl"]
    with pytest.raises(build_packages.PackageError, match="wheels is written per platform"):
        build_packages.check_inputs(manifest, REPOSITORY / "target" / "wheels")
    del manifest["wheels"]
    manifest["version"] = "9.9.9"
    with pytest.raises(build_packages.PackageError, match="is not bl_info's"):
        build_packages.check_inputs(manifest, REPOSITORY / "target" / "wheels")


def test_wheel_tags_are_read_as_blenders_platforms():
    read = build_packages.blender_platforms
    assert read("manylinux_2_28_x86_64") == ["linux-x64"]
    assert read("win_amd64") == ["windows-x64"]
    assert read("macosx_11_0_arm64") == ["macos-arm64"]
    assert read("macosx_10_12_x86_64") == ["macos-x64"]
    assert read("macosx_10_12_universal2") == ["macos-x64", "macos-arm64"]
    assert read("manylinux2014_aarch64") == ["linux-arm64"]


def test_build_writes_one_extension_and_one_legacy_zip_per_platform(every_platform, tmp_path):
    built, wheels = every_platform
    version = extension_version()
    assert [platform for platform, _extension, _legacy in built] == list(build_packages.PLATFORMS)
    for platform, extension, legacy in built:
        suffix = platform.replace("-", "_")
        assert extension.name == f"springwrap-{version}-extension-{suffix}.zip"
        assert legacy.name == f"springwrap-{version}-legacy-{suffix}.zip"
        with zipfile.ZipFile(extension) as archive:
            manifest = tomllib.loads(archive.read("blender_manifest.toml").decode())
            shipped = [name for name in archive.namelist() if name.startswith("wheels/")]
            assert archive.read(shipped[0]) == wheels[platform].read_bytes()  # the wheel unmodified
        assert manifest["platforms"] == [platform]
        assert shipped == [f"wheels/{wheels[platform].name}"]
        assert manifest["wheels"] == [f"./{shipped[0]}"]
        native = {"windows-x64": "_native.pyd"}.get(platform, "_native.abi3.so")
        legacy_names = names_in(legacy)
        assert f"springwrap/_vendor/springwrap_kernel/{native}" in legacy_names
        assert len([name for name in legacy_names if "/_native." in name]) == 1  # only its own platform's


def test_build_refuses_two_wheels_for_one_platform_and_unknown_platforms(tmp_path):
    shutil.copy(linux_wheel(), tmp_path / linux_wheel().name)
    shutil.copy(linux_wheel(), tmp_path / linux_wheel().name.replace("manylinux_2_28", "manylinux_2_17"))
    with pytest.raises(build_packages.PackageError, match="two wheels for linux-x64"):
        build_packages.build(tmp_path, tmp_path / "dist")
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(linux_wheel(), other / linux_wheel().name.replace("manylinux_2_28_x86_64", "win32"))
    with pytest.raises(build_packages.PackageError, match="platform win32 is not one of"):
        build_packages.build(other, tmp_path / "dist")
    assert not (tmp_path / "dist").exists()  # nothing written


def test_every_platforms_extension_passes_blenders_own_validation(every_platform):
    checker = blender_extension_checker()
    if checker is None:
        pytest.skip("this bpy module has no extension tool (Blender < 4.2)")
    built, _wheels = every_platform
    for platform, extension, _legacy in built:
        process = subprocess.run(
            [sys.executable, str(checker), "validate", str(extension)],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_SECONDS,
        )
        assert process.returncode == 0 and "Success" in process.stdout, (platform, process.stdout + process.stderr)


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


def test_release_workflow_builds_a_wheel_for_every_platform_and_packages_that_folder():
    """.github/workflows/release.yml (run on GitHub's hosted runners, not here): one wheel job per
    platform build_packages.py packages, then build_packages.py on the folder of their wheels."""
    yaml = pytest.importorskip("yaml")
    workflow = yaml.safe_load((REPOSITORY / ".github" / "workflows" / "release.yml").read_text())
    matrix = workflow["jobs"]["wheels"]["strategy"]["matrix"]["include"]
    assert sorted(entry["platform"] for entry in matrix) == sorted(build_packages.PLATFORMS)
    build = next(step for step in workflow["jobs"]["wheels"]["steps"] if "maturin-action" in step.get("uses", ""))
    assert "-m rust_core/python/Cargo.toml" in build["with"]["args"]
    assert {entry["platform"]: entry["manylinux"] for entry in matrix}["linux-x64"] == "2_28"  # the tag we check
    commands = " ".join(step.get("run", "") for step in workflow["jobs"]["packages"]["steps"])
    assert "packaging/build_packages.py --wheel-dir wheels" in commands


def test_blender_refuses_the_extension_of_another_platform(every_platform, tmp_path):
    """The windows-x64 zip on this Linux machine: Blender's installer names the platforms and installs nothing."""
    if blender_extension_checker() is None:
        pytest.skip("this bpy module has no extension system (Blender < 4.2)")
    built, _wheels = every_platform
    [windows] = [extension for platform, extension, _legacy in built if platform == "windows-x64"]
    script = tmp_path / "install.py"
    script.write_text(
        "import bpy, sys\n"
        "bpy.ops.extensions.package_install_files(filepath=sys.argv[-1], repo='user_default', enable_on_install=True)\n"
    )
    user = tmp_path / "user"
    process = subprocess.run(
        [sys.executable, str(script), str(windows)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SECONDS,
        cwd=tmp_path,
        env={**os.environ, "BLENDER_USER_RESOURCES": str(user)},
    )
    assert "This platform (linux-x64) isn't one of (windows-x64)" in process.stdout + process.stderr
    assert not (user / "extensions" / "user_default" / "springwrap").exists()
