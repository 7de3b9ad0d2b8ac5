"""Build Springwrap's Blender packages, one pair per platform, into dist/ (``make package``).

    python packaging/build_packages.py [--wheel-dir target/wheels] [--output dist]

The wheel folder holds the kernel wheel (``springwrap_kernel-<version>-cp311-abi3-<tag>.whl``) of
each platform to package: ``make setup`` builds the Linux one into target/wheels; the release
workflow (.github/workflows/release.yml) builds all four on hosted runners and passes their folder.
Each wheel's platform tag names its Blender platform, as Blender's own extension tool reads it:
``manylinux_*_x86_64`` linux-x64, ``win_amd64`` windows-x64, ``macosx_*_arm64`` macos-arm64,
``macosx_*_x86_64`` macos-x64. For each platform found:

- ``springwrap-<version>-extension-<platform>.zip``, for Blender 4.2 and later:
  ``blender_manifest.toml`` (packaging/blender_manifest.toml with ``platforms = ["<platform>"]``
  and ``wheels = ["./wheels/<that wheel>"]`` written in) and the add-on's files at the root, the
  platform's kernel wheel in ``wheels/`` (Blender installs it into the extension's own
  site-packages). One zip per platform is what ``blender --command extension build
  --split-platforms`` makes and what the extensions platform takes (one file per platform of a
  version); the native library of the other platforms is not downloaded.
- ``springwrap-<version>-legacy-<platform>.zip``, for Blender 3.4 to 4.1 (Install Add-on from
  File): the ``springwrap/`` folder with ``bl_info``, the platform's kernel wheel unpacked in
  ``springwrap/_vendor``, which the add-on puts on ``sys.path`` when it is imported
  (``springwrap/__init__.py``): nothing is downloaded or installed with pip when it is enabled.

(``<platform>`` with an underscore in the file name, ``linux_x64``, as Blender's tool writes it.)
Neither bundles numpy: the kernel uses the numpy of the Blender it runs in. Checked before
anything is written: the manifest's version is bl_info's and every wheel's; one wheel per platform,
each for a platform Blender knows; a manylinux wheel's tag is true (packaging/wheel_glibc.py).
Archives are deterministic (sorted entries, fixed timestamps). Exits non-zero with a message when
a check fails.
"""

import argparse
import ast
import re
import sys
import zipfile
from pathlib import Path

import tomllib

PACKAGING = Path(__file__).resolve().parent
REPOSITORY = PACKAGING.parent
ADDON = REPOSITORY / "addon" / "springwrap"
MANIFEST = PACKAGING / "blender_manifest.toml"
ZIP_TIME = (1980, 1, 1, 0, 0, 0)

sys.path.insert(0, str(PACKAGING))
import wheel_glibc  # noqa: E402


class PackageError(Exception):
    """A check before packaging failed: the message says what and where."""


def bl_info_version(init_file: Path) -> str:
    """bl_info["version"] of the add-on's ``__init__.py`` as "X.Y.Z" (read, not imported: no bpy needed)."""
    for node in ast.parse(init_file.read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(target, "id", None) == "bl_info" for target in node.targets):
            version = ast.literal_eval(node.value)["version"]
            return ".".join(str(part) for part in version)
    raise PackageError(f"{init_file} has no bl_info")


def addon_files() -> list[Path]:
    """The add-on's files to ship: sources and its README, no caches, no vendored or packaging files."""
    files = []
    for path in sorted(ADDON.rglob("*")):
        relative = path.relative_to(ADDON)
        if not path.is_file() or "__pycache__" in relative.parts or relative.parts[0] == "_vendor":
            continue
        if path.suffix in (".pyc", ".so", ".toml"):
            continue
        files.append(path)
    return files


PLATFORMS = ("linux-x64", "windows-x64", "macos-arm64", "macos-x64")
"""The Blender platforms Springwrap is packaged for (the release workflow builds a wheel for each)."""

WHEEL_NAME = re.compile(
    r"^springwrap_kernel-(?P<version>[^-]+)-(?P<python>[^-]+)-(?P<abi>[^-]+)-(?P<platform>[^-]+)\.whl$"
)


WHEEL_SYSTEMS = {"manylinux": "linux", "musllinux": "linux", "linux": "linux", "win": "windows", "macosx": "macos"}
WHEEL_MACHINES = {"x86_64": ("x64",), "amd64": ("x64",), "arm64": ("arm64",), "aarch64": ("arm64",)}
WHEEL_MACHINES["universal2"] = ("x64", "arm64")


def blender_platforms(wheel_platform: str) -> list[str]:
    """The Blender platforms a wheel's platform tag runs on, as Blender's extension tool reads it:
    ``manylinux_2_28_x86_64`` linux-x64, ``win_amd64`` windows-x64, ``macosx_11_0_arm64``
    macos-arm64, ``macosx_10_12_x86_64`` macos-x64, ``macosx_10_12_universal2`` both macOS ones."""
    found = []
    for tag in wheel_platform.split("."):  # a compressed tag set: macosx_10_12_x86_64.macosx_11_0_arm64
        system, _, rest = tag.partition("_")
        system = re.sub(r"\d+$", "", system)  # manylinux2014 -> manylinux, win32 -> win
        system = WHEEL_SYSTEMS.get(system, system)
        machine = next((name for name in WHEEL_MACHINES if rest == name or rest.endswith("_" + name)), None)
        if machine is None:
            found.append(tag)  # win32, any...: no platform Springwrap is built for
        else:
            found += [f"{system}-{name}" for name in WHEEL_MACHINES[machine]]
    return found


def platform_wheels(wheel_dir: Path, version: str) -> dict[str, Path]:
    """The kernel wheel of each platform in ``wheel_dir``, by Blender platform, in PLATFORMS' order."""
    wheels = sorted(wheel_dir.glob("springwrap_kernel-*.whl"))
    if not wheels:
        raise PackageError(f"{wheel_dir}: no springwrap_kernel wheel (make setup builds the Linux one)")
    by_platform: dict[str, Path] = {}
    for wheel in wheels:
        match = WHEEL_NAME.match(wheel.name)
        if match is None:
            raise PackageError(f"{wheel.name}: not a wheel file name (name-version-python-abi-platform.whl)")
        if match["version"] != version:
            raise PackageError(f"{wheel.name} is not version {version}")
        platforms = blender_platforms(match["platform"])
        unknown = [platform for platform in platforms if platform not in PLATFORMS]
        if unknown:
            raise PackageError(f"{wheel.name}: platform {unknown[0]} is not one of {', '.join(PLATFORMS)}")
        for platform in platforms:
            if platform in by_platform:
                raise PackageError(
                    f"{wheel_dir}: two wheels for {platform}: {by_platform[platform].name}, {wheel.name}"
                )
            by_platform[platform] = wheel
    return {platform: by_platform[platform] for platform in PLATFORMS if platform in by_platform}


def check_wheel(wheel: Path) -> None:
    """A wheel may be shipped: a manylinux tag that is true, no numpy bundled."""
    if "manylinux" in wheel.name:
        problems = wheel_glibc.check(wheel)
        if problems:
            raise PackageError("; ".join(problems))
    with zipfile.ZipFile(wheel) as archive:
        bundled_numpy = [name for name in archive.namelist() if name.split("/")[0].startswith("numpy")]
    if bundled_numpy:
        raise PackageError(f"{wheel.name} bundles numpy ({bundled_numpy[0]}...): Blender's own must be used")


def check_inputs(manifest: dict, wheel_dir: Path) -> dict[str, Path]:
    """Check the manifest against bl_info and the wheel folder; the kernel wheel of each platform."""
    version = bl_info_version(ADDON / "__init__.py")
    if manifest.get("version") != version:
        raise PackageError(f"{MANIFEST}: version {manifest.get('version')!r} is not bl_info's {version!r}")
    written = [key for key in ("platforms", "wheels") if key in manifest]
    if written:
        raise PackageError(f"{MANIFEST}: {written[0]} is written per platform by this script: remove it")
    wheels = platform_wheels(wheel_dir, version)
    for wheel in set(wheels.values()):
        check_wheel(wheel)
    return wheels


def platform_manifest(manifest_text: str, platform: str, wheel: Path) -> str:
    """The manifest of one platform's zip: the template with its ``platforms`` and ``wheels``."""
    lines = manifest_text.rstrip("\n").splitlines()
    table = next((index for index, line in enumerate(lines) if line.lstrip().startswith("[")), len(lines))
    written = [
        "",
        "# Written by packaging/build_packages.py for this platform's zip.",
        f'platforms = ["{platform}"]',
        f'wheels = ["./wheels/{wheel.name}"]',
    ]
    return "\n".join(lines[:table] + written + lines[table:]) + "\n"


def write_zip(path: Path, entries: list[tuple[str, bytes]]) -> None:
    """A deterministic zip: entries sorted by name, fixed timestamps, deflated."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".zip.partial")
    with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, data in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, data)
    partial.replace(path)


def build(wheel_dir: Path, output: Path) -> list[tuple[str, Path, Path]]:
    """Write each platform's extension zip and legacy zip into ``output``.

    Returns (platform, extension zip, legacy zip) per platform, in PLATFORMS' order.
    """
    manifest_text = MANIFEST.read_text()
    manifest = tomllib.loads(manifest_text)
    wheels = check_inputs(manifest, wheel_dir)
    version = manifest["version"]
    sources = [(str(path.relative_to(ADDON)), path.read_bytes()) for path in addon_files()]
    built = []
    for platform, wheel in wheels.items():
        suffix = platform.replace("-", "_")
        extension = output / f"springwrap-{version}-extension-{suffix}.zip"
        text = platform_manifest(manifest_text, platform, wheel)
        write_zip(
            extension,
            [("blender_manifest.toml", text.encode()), (f"wheels/{wheel.name}", wheel.read_bytes()), *sources],
        )
        with zipfile.ZipFile(wheel) as archive:
            vendored = [
                (f"springwrap/_vendor/{name}", archive.read(name))
                for name in archive.namelist()
                if not name.endswith("/")
            ]
        legacy = output / f"springwrap-{version}-legacy-{suffix}.zip"
        write_zip(legacy, [(f"springwrap/{name}", data) for name, data in sources] + vendored)
        built.append((platform, extension, legacy))
    return built


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument(
        "--wheel-dir",
        type=Path,
        default=REPOSITORY / "target" / "wheels",
        help="folder of kernel wheels, one per platform (default target/wheels: the Linux one make setup builds)",
    )
    parser.add_argument("--output", type=Path, default=REPOSITORY / "dist")
    arguments = parser.parse_args()
    try:
        built = build(arguments.wheel_dir, arguments.output)
    except (PackageError, OSError, tomllib.TOMLDecodeError) as error:
        print(f"build_packages: {error}", file=sys.stderr)
        return 1
    for platform, *paths in built:
        for path in paths:
            print(f"build_packages: {platform}: {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
