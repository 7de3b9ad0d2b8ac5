"""Build the two Blender packages of Springwrap into dist/ (``make package``).

    python packaging/build_packages.py [--wheel-dir target/wheels] [--output dist]

- ``springwrap-<version>-extension.zip``, for Blender 4.2 and later: ``blender_manifest.toml``
  (packaging/blender_manifest.toml) and the add-on's files at the root, the kernel wheel in
  ``wheels/`` (Blender installs it into the extension's own site-packages when the extension is
  installed).
- ``springwrap-<version>-legacy.zip``, for Blender 3.4 to 4.1 (Install Add-on from File): the
  ``springwrap/`` folder with ``bl_info``, the kernel wheel unpacked in ``springwrap/_vendor``,
  which the add-on puts on ``sys.path`` when it is imported (``springwrap/__init__.py``):
  nothing is downloaded or installed with pip when it is enabled, so it works offline and the
  kernel is the one built with this add-on.

Neither bundles numpy: the kernel uses the numpy of the Blender it runs in. Checked before
anything is written: the manifest's version is bl_info's, its ``wheels`` entry names exactly the
kernel wheel in the wheel folder, and that wheel's manylinux tag is true (packaging/wheel_glibc.py).
Archives are deterministic (sorted entries, fixed timestamps). Exits non-zero with a message when
a check fails.
"""

import argparse
import ast
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


def check_inputs(manifest: dict, wheel_dir: Path) -> Path:
    """Check the manifest against bl_info and the wheel folder; the kernel wheel to ship."""
    version = bl_info_version(ADDON / "__init__.py")
    if manifest.get("version") != version:
        raise PackageError(f"{MANIFEST}: version {manifest.get('version')!r} is not bl_info's {version!r}")
    wheels = sorted(wheel_dir.glob("springwrap_kernel-*.whl"))
    if len(wheels) != 1:
        raise PackageError(f"{wheel_dir}: expected one springwrap_kernel wheel, found {[w.name for w in wheels]}")
    wheel = wheels[0]
    listed = manifest.get("wheels", [])
    if listed != [f"./wheels/{wheel.name}"]:
        raise PackageError(f"{MANIFEST}: wheels = {listed}, but the kernel wheel is ./wheels/{wheel.name}")
    if f"-{version}-" not in wheel.name:
        raise PackageError(f"{wheel.name} is not version {version}")
    problems = wheel_glibc.check(wheel)
    if problems:
        raise PackageError("; ".join(problems))
    with zipfile.ZipFile(wheel) as archive:
        bundled_numpy = [name for name in archive.namelist() if name.split("/")[0].startswith("numpy")]
    if bundled_numpy:
        raise PackageError(f"{wheel.name} bundles numpy ({bundled_numpy[0]}...): Blender's own must be used")
    return wheel


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


def build(wheel_dir: Path, output: Path) -> tuple[Path, Path]:
    """Write the extension zip and the legacy zip into ``output``; returns their paths."""
    manifest_text = MANIFEST.read_bytes()
    manifest = tomllib.loads(manifest_text.decode())
    wheel = check_inputs(manifest, wheel_dir)
    version = manifest["version"]
    sources = [(str(path.relative_to(ADDON)), path.read_bytes()) for path in addon_files()]

    extension = output / f"springwrap-{version}-extension.zip"
    write_zip(
        extension, [("blender_manifest.toml", manifest_text), (f"wheels/{wheel.name}", wheel.read_bytes()), *sources]
    )

    with zipfile.ZipFile(wheel) as archive:
        vendored = [
            (f"springwrap/_vendor/{name}", archive.read(name)) for name in archive.namelist() if not name.endswith("/")
        ]
    legacy = output / f"springwrap-{version}-legacy.zip"
    write_zip(legacy, [(f"springwrap/{name}", data) for name, data in sources] + vendored)
    return extension, legacy


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument("--wheel-dir", type=Path, default=REPOSITORY / "target" / "wheels")
    parser.add_argument("--output", type=Path, default=REPOSITORY / "dist")
    arguments = parser.parse_args()
    try:
        paths = build(arguments.wheel_dir, arguments.output)
    except (PackageError, OSError, tomllib.TOMLDecodeError) as error:
        print(f"build_packages: {error}", file=sys.stderr)
        return 1
    for path in paths:
        print(f"build_packages: {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
