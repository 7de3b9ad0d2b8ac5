"""docs/architecture.md's module map against the tree: every path it names exists, and every Python and Rust
source file is named by a row (the file, a folder ``x/`` above it, or a ``*`` pattern). No Blender."""

import fnmatch
import re

from helpers import REPOSITORY

ARCHITECTURE = REPOSITORY / "docs" / "architecture.md"
SOURCES = ("*.py", "*.pyi", "*.rs")
SKIPPED = {"__pycache__", "_vendor"}


def module_map() -> dict[str, list[str]]:
    """{root folder: [the paths its table names, relative to it]} from the ``## Module map`` section."""
    text = ARCHITECTURE.read_text()
    section = text.split("\n## Module map\n", 1)[1].split("\n## ", 1)[0]
    parts = re.split(r"^### `([^`]+/)`$", section, flags=re.MULTILINE)
    roots = {}
    for root, body in zip(parts[1::2], parts[2::2]):
        rows = re.findall(r"^\| (.+?) \|", body, flags=re.MULTILINE)
        roots[root] = [entry for row in rows for entry in re.findall(r"`([^`]+)`", row)]
    return roots


def sources(root: str) -> list[str]:
    folder = REPOSITORY / root
    found = []
    for pattern in SOURCES:
        for path in folder.rglob(pattern):
            relative = path.relative_to(folder)
            if not SKIPPED.intersection(relative.parts):
                found.append(relative.as_posix())
    return sorted(found)


def covers(entry: str, path: str) -> bool:
    if entry.endswith("/"):
        return path.startswith(entry)
    return fnmatch.fnmatchcase(path, entry)


def test_the_map_names_every_top_level_source_folder():
    roots = module_map()
    assert {
        "addon/springwrap/",
        "rust_core/kernel/src/",
        "rust_core/python/src/",
        "blender_scripts/",
        "packaging/",
        "benchmarks/",
        "tests/",
        "docs/",
    } <= set(roots)


def test_every_path_in_the_map_exists():
    missing = [
        f"{root}{entry}"
        for root, entries in module_map().items()
        for entry in entries
        if not any(covers(entry, path) for path in sources(root))
    ]
    assert not missing, f"docs/architecture.md's module map names what is not in the tree: {missing}"


def test_every_source_file_is_in_the_map():
    unnamed = [
        f"{root}{path}"
        for root, entries in module_map().items()
        for path in sources(root)
        if not any(covers(entry, path) for entry in entries)
    ]
    assert not unnamed, f"add these to docs/architecture.md's module map: {unnamed}"
