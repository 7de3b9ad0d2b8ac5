"""Check that a wheel's manylinux tag is true: no shared object in it needs a newer glibc.

    python packaging/wheel_glibc.py target/wheels/springwrap_kernel-*.whl

A ``manylinux_2_28`` wheel promises to load on any Linux with glibc 2.28 or later. What a binary
really needs is written in its ELF version-needs section (``.gnu.version_r``): every versioned
symbol it imports from libc, libm, libpthread... names the glibc version that introduced it
(``GLIBC_2.18``). The newest of those is the oldest glibc the binary loads on; it must not be
newer than the tag's. Prints each shared object's newest ``GLIBC_`` version; exits 1 when the tag
is false (or the wheel has no manylinux tag), 0 when it holds.
"""

import io
import re
import sys
import zipfile
from pathlib import Path

from elftools.elf.elffile import ELFFile
from elftools.elf.gnuversions import GNUVerNeedSection

TAG = re.compile(r"manylinux_(\d+)_(\d+)_")
GLIBC = re.compile(r"^GLIBC_(\d+)\.(\d+)(?:\.(\d+))?$")


def glibc_versions_needed(elf_bytes: bytes) -> set[tuple[int, ...]]:
    """Every ``GLIBC_x.y[.z]`` version an ELF shared object needs, as tuples of ints."""
    elf = ELFFile(io.BytesIO(elf_bytes))
    versions = set()
    for section in elf.iter_sections():
        if not isinstance(section, GNUVerNeedSection):
            continue
        for _library, auxiliaries in section.iter_versions():
            for auxiliary in auxiliaries:
                match = GLIBC.match(auxiliary.name)
                if match:
                    versions.add(tuple(int(part) for part in match.groups() if part is not None))
    return versions


def wheel_glibc(wheel: Path) -> dict[str, tuple[int, ...]]:
    """For each shared object in the wheel: the newest glibc version it needs ((0,) when none)."""
    needed = {}
    with zipfile.ZipFile(wheel) as archive:
        for name in archive.namelist():
            if name.endswith(".so") or ".so." in name:
                versions = glibc_versions_needed(archive.read(name))
                needed[name] = max(versions) if versions else (0,)
    return needed


def tag_glibc(wheel: Path) -> tuple[int, int]:
    """The glibc version of the wheel's manylinux tag; ValueError when it has none."""
    match = TAG.search(wheel.name)
    if not match:
        raise ValueError(f"{wheel.name} has no manylinux_X_Y tag")
    return int(match.group(1)), int(match.group(2))


def check(wheel: Path) -> list[str]:
    """Problems with the wheel's tag (empty when the tag is true); prints what each object needs."""
    try:
        promised = tag_glibc(wheel)
    except ValueError as error:
        return [str(error)]
    needed = wheel_glibc(wheel)
    if not needed:
        return [f"{wheel.name} holds no shared object"]
    problems = []
    for name, newest in sorted(needed.items()):
        shown = ".".join(map(str, newest))
        print(f"wheel_glibc: {name} needs glibc {shown} (tag promises {promised[0]}.{promised[1]})")
        if newest > promised:
            problems.append(f"{name} needs glibc {shown}, newer than its tag's {promised[0]}.{promised[1]}")
    return problems


def main(arguments: list[str]) -> int:
    if not arguments:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    problems = [problem for wheel in arguments for problem in check(Path(wheel))]
    for problem in problems:
        print(f"wheel_glibc: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
