"""Regenerate the generated parts of docs/user-guide.md: the operator reference and the CLI's --help.

    .venv/bin/python docs/generate_reference.py            # rewrite the generated sections in place
    .venv/bin/python docs/generate_reference.py --check    # exit 1 (and say which) when they are stale

The operator reference is read from the registered operators' RNA (``bpy.ops.springwrap.<name>
.get_rna_type()``: label, description, and every property with its type, default, range and
items), and the per-object settings from ``bpy.types.Object.springwrap``; so it is what Blender
shows, not a copy kept by hand. The CLI sections are the scripts' own ``--help`` output. Each
generated section sits between ``<!-- BEGIN GENERATED: name -->`` and ``<!-- END GENERATED: name -->``
in the guide; everything else in the guide is written by hand.
"""

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import bpy  # first: the PyPI bpy module

REPOSITORY_ROOT = Path(__file__).resolve().parent.parent
GUIDE = REPOSITORY_ROOT / "docs" / "user-guide.md"
CLI_SCRIPTS = ("retarget.py", "wrap.py", "mirror.py", "detect_features.py")
SKIPPED_PROPERTIES = {"rna_type"}


def enable_addon() -> None:
    """Enable the Springwrap add-on the scripts' way (``blender_scripts/headless.py``), raising when it cannot be."""
    if str(REPOSITORY_ROOT / "blender_scripts") not in sys.path:
        sys.path.insert(0, str(REPOSITORY_ROOT / "blender_scripts"))
    import headless

    headless.enable_addon()


def operator_names() -> list[str]:
    """The registered ``bpy.ops.springwrap`` operators, sorted."""
    return sorted(name for name in dir(bpy.ops.springwrap) if not name.startswith("_"))


def operator_properties(name: str) -> list:
    """The RNA properties of ``bpy.ops.springwrap.<name>`` (without ``rna_type``), in declaration order."""
    rna = getattr(bpy.ops.springwrap, name).get_rna_type()
    return [prop for prop in rna.properties if prop.identifier not in SKIPPED_PROPERTIES]


def _number(value) -> str:
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def _type_text(prop) -> str:
    """``int``, ``float[3]``, ``enum``, ... with the range when there is one."""
    kind = {
        "BOOLEAN": "bool",
        "INT": "int",
        "FLOAT": "float",
        "STRING": "string",
        "ENUM": "enum",
        "POINTER": "pointer",
        "COLLECTION": "collection",
    }.get(prop.type, prop.type.lower())
    if getattr(prop, "is_array", False) and prop.array_length:
        kind += f"[{prop.array_length}]"
    if prop.type == "POINTER":
        kind += f" ({prop.fixed_type.identifier})"
    if prop.type == "COLLECTION":
        kind += f" of {prop.fixed_type.identifier}"
    if prop.type in ("INT", "FLOAT"):
        hard = (prop.hard_min, prop.hard_max)
        soft = (prop.soft_min, prop.soft_max)
        limits = 2**31 - 1 if prop.type == "INT" else 3.0e38
        parts = []
        if abs(hard[0]) < limits * 0.99 or abs(hard[1]) < limits * 0.99:
            parts.append(f"{_bound(hard[0], limits)} to {_bound(hard[1], limits)}")
        if soft != hard and (abs(soft[0]) < limits * 0.99 or abs(soft[1]) < limits * 0.99):
            parts.append(f"slider {_bound(soft[0], limits)} to {_bound(soft[1], limits)}")
        if parts:
            kind += ", " + ", ".join(parts)
    return kind


def _bound(value, limit) -> str:
    if value >= limit * 0.99:
        return "∞"
    if value <= -limit * 0.99:
        return "-∞"
    return _number(value)


def _default_text(prop) -> str:
    if prop.type == "ENUM":
        if prop.is_enum_flag:
            return "{" + ", ".join(f"'{item}'" for item in sorted(prop.default_flag)) + "}"
        return f"`'{prop.default}'`"
    if prop.type in ("POINTER", "COLLECTION"):
        return "none" if prop.type == "POINTER" else "empty"
    if getattr(prop, "is_array", False) and prop.array_length:
        return "`(" + ", ".join(_number(value) for value in prop.default_array) + ")`"
    if prop.type == "STRING":
        return f'`"{prop.default}"`'
    return f"`{_number(prop.default)}`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ").strip()


def _description(prop) -> str:
    text = _cell(prop.description) or _cell(prop.name)
    if prop.type == "ENUM":
        items = "; ".join(
            f"`'{item.identifier}'` {_cell(item.description) or _cell(item.name)}" for item in prop.enum_items
        )
        text = f"{text}. Items: {items}" if text else f"Items: {items}"
    return text


def property_table(properties) -> list[str]:
    """Markdown table rows for ``properties``."""
    if not properties:
        return ["No parameters."]
    lines = ["| parameter | type | default | what it does |", "|---|---|---|---|"]
    for prop in properties:
        lines.append(f"| `{prop.identifier}` | {_type_text(prop)} | {_default_text(prop)} | {_description(prop)} |")
    return lines


def operator_reference() -> str:
    """The operator reference: one sub-section per registered operator."""
    lines = []
    for name in operator_names():
        rna = getattr(bpy.ops.springwrap, name).get_rna_type()
        lines.append(f"#### `bpy.ops.springwrap.{name}` — {rna.name}")
        lines.append("")
        lines.append(_cell(rna.description) + ".")
        lines.append("")
        lines.extend(property_table(operator_properties(name)))
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def settings_reference() -> str:
    """The per-object settings (``object.springwrap``) that the sidebar panel shows and the operators read."""
    rna = bpy.types.Object.bl_rna.properties["springwrap"].fixed_type
    properties = [prop for prop in rna.properties if prop.identifier not in SKIPPED_PROPERTIES]
    return "\n".join(property_table(properties)) + "\n"


def cli_help(script: str) -> str:
    """The ``--help`` output of ``blender_scripts/<script>`` run with this Python, as a fenced block."""
    environment = dict(os.environ, COLUMNS="100")  # argparse wraps to the terminal's width otherwise
    completed = subprocess.run(
        [sys.executable, str(REPOSITORY_ROOT / "blender_scripts" / script), "--help"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPOSITORY_ROOT,
        check=False,
        env=environment,
    )
    if completed.returncode != 0:
        raise RuntimeError(f"{script} --help exited {completed.returncode}: {completed.stderr.strip()}")
    return "```text\n" + completed.stdout.rstrip() + "\n```\n"


def sections(include_cli: bool = True) -> dict[str, str]:
    """Every generated section of the guide, by name."""
    result = {"operators": operator_reference(), "settings": settings_reference()}
    if include_cli:
        for script in CLI_SCRIPTS:
            result[f"cli-{script.removesuffix('.py')}"] = cli_help(script)
    return result


def section_pattern(name: str) -> re.Pattern:
    return re.compile(
        rf"(<!-- BEGIN GENERATED: {re.escape(name)} .*?-->\n)(.*?)(<!-- END GENERATED: {re.escape(name)} -->)",
        re.DOTALL,
    )


def read_section(text: str, name: str) -> str | None:
    """The body of the generated section ``name`` in ``text``, or None when the markers are missing."""
    match = section_pattern(name).search(text)
    return None if match is None else match.group(2)


def replace_sections(text: str, bodies: dict[str, str]) -> str:
    for name, body in bodies.items():
        pattern = section_pattern(name)
        if pattern.search(text) is None:
            raise RuntimeError(f"{GUIDE.name} has no section markers for '{name}'")
        text = pattern.sub(lambda match, body=body: match.group(1) + body + match.group(3), text)
    return text


def main() -> int:
    parser = argparse.ArgumentParser(prog="generate_reference.py", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check; exit 1 when a section is stale")
    arguments = parser.parse_args(sys.argv[1:])
    enable_addon()
    text = GUIDE.read_text(encoding="utf-8")
    bodies = sections()
    if arguments.check:
        stale = [name for name, body in bodies.items() if read_section(text, name) != body]
        if stale:
            print(f"{GUIDE} is stale in: {', '.join(stale)}; run docs/generate_reference.py", file=sys.stderr)
            return 1
        print(f"{GUIDE}: generated sections up to date")
        return 0
    updated = replace_sections(text, bodies)
    if updated != text:
        GUIDE.write_text(updated, encoding="utf-8")
        print(f"rewrote the generated sections of {GUIDE}")
    else:
        print(f"{GUIDE}: already up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
