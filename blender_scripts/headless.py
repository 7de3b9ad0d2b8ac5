"""What every headless script shares: its own arguments, the add-on enabled (from a checkout or installed as an
extension) and its modules, exit codes and the one-line failure, and outputs written all or nothing.

A script runs both ways:

    python X.py ARGS                        (PyPI ``bpy`` module): everything after the script's path
    blender -b --python X.py -- ARGS        (a real Blender): everything after ``--``
    blender -b --python X.py                no arguments (``sys.argv`` is Blender's own)

This module imports no ``bpy`` at its top (the batch's coordinator uses it without Blender);
``addon_utils`` is imported when the add-on is enabled.
"""

import errno
import importlib
import os
import sys
import tempfile
import traceback
from pathlib import Path

EXIT_OK = 0
"""Done."""
EXIT_FAILED = 1
"""The run failed: one line ``<script>: FAILED: ...`` on stderr says why."""
EXIT_USAGE = 2
"""Bad command-line arguments (``argparse``'s own code)."""
EXIT_BATCH_FAILURES = 3
"""A batch in which at least one mesh failed (the others are written)."""
EXIT_INTERRUPTED = 130
"""Stopped by Ctrl-C."""


class ScriptError(Exception):
    """A problem with the input or the run: the message is the one line printed, naming the file."""


def script_arguments(argv: list[str], script_path: str) -> list[str]:
    """The script's own arguments out of ``argv`` (normally ``sys.argv``)."""
    if "--" in argv:
        return argv[argv.index("--") + 1 :]
    if argv and Path(argv[0]).name == Path(script_path).name:
        return argv[1:]
    return []


# ---------------------------------------------------------------- the add-on


def enable_addon():
    """Enable Springwrap, the classic add-on or an installed extension (``bl_ext.<repository>.springwrap``),
    unless it is on already; its package. Raises :class:`ScriptError` when it cannot be enabled."""
    import addon_utils

    names = ["springwrap"] + [
        module.__name__ for module in addon_utils.modules() if module.__name__.endswith(".springwrap")
    ]
    for name in names:
        if addon_utils.check(name)[1]:  # already on (a batch worker's second mesh)
            return sys.modules[name]
    for name in names:
        if addon_utils.enable(name, default_set=True, handle_error=None) is not None:
            return sys.modules[name]
    raise ScriptError("the Springwrap add-on cannot be enabled (run `make setup`, or install it in Blender)")


def addon_module(name: str):
    """The add-on's module ``name`` (``"blender.wrap_session"``...), whichever way the add-on is installed
    (enabled first when it is not)."""
    return importlib.import_module(f"{enable_addon().__name__}.{name}")


# ---------------------------------------------------------------- ending


def failed(script: str, error: BaseException) -> int:
    """Say why the run failed, in one line on stderr (after a traceback for an error that is not a
    :class:`ScriptError`); :data:`EXIT_FAILED`."""
    if isinstance(error, ScriptError):
        print(f"{script}: FAILED: {error}", file=sys.stderr)
    else:
        traceback.print_exc()
        print(f"{script}: FAILED: {type(error).__name__}: {error}", file=sys.stderr)
    return EXIT_FAILED


# ---------------------------------------------------------------- the files' frame

AXES = ("X", "Y", "Z", "NEGATIVE_X", "NEGATIVE_Y", "NEGATIVE_Z")
"""As Blender's importers and exporters spell them; ``-Z`` is also taken (``--forward-axis=-Z``)."""
DEFAULT_UP_AXIS = "Z"
DEFAULT_FORWARD_AXIS = "Y"


def script_main(name: str, parse_arguments, run) -> int:
    """A script's ``main``: ``run(parse_arguments(sys.argv))``; any failure is one line and a non-zero exit code
    (:func:`failed`), also under ``blender -b``."""
    try:
        run(parse_arguments(sys.argv))
    except Exception as error:  # noqa: BLE001 - any failure must become a non-zero exit code, also under `blender -b`
        return failed(name, error)
    return EXIT_OK


def finite_number(text: str) -> float:
    """An argparse ``type`` for a number option: a finite float (the add-on's input policy for a number the user
    sets, ``core.input_policy.setting_problem``: NaN is never "automatic" nor "unlimited", and neither is inf)."""
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, not {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, not {text}")
    return value


def axis_name(text: str) -> str:
    """An axis as given on the command line (``y``, ``-Z``, ``NEGATIVE_Z``) in Blender's spelling."""
    text = text.strip().upper()
    return f"NEGATIVE_{text[1:]}" if text.startswith("-") else text


def signed_axis(axis: str) -> str:
    """An axis as ``bpy_extras.io_utils.axis_conversion`` spells it: ``NEGATIVE_Z`` is ``-Z``."""
    return "-" + axis.removeprefix("NEGATIVE_") if axis.startswith("NEGATIVE_") else axis


def add_frame_arguments(parser) -> None:
    """``--up-axis`` and ``--forward-axis``: the one convention every mesh file is read in and every output
    written back in (see :func:`check_frame_arguments`)."""
    parser.add_argument(
        "--up-axis",
        type=axis_name,
        choices=AXES,
        default=DEFAULT_UP_AXIS,
        help="the mesh files' up axis: every input file is read with it and every output file written back "
        "with it; the anchors file is in that frame too (default %(default)s: coordinates as written, "
        "Blender's own frame; Y-up files, e.g. Blender's OBJ export: --up-axis Y --forward-axis NEGATIVE_Z)",
    )
    parser.add_argument(
        "--forward-axis",
        type=axis_name,
        choices=AXES,
        default=DEFAULT_FORWARD_AXIS,
        help="the mesh files' forward axis (default %(default)s)",
    )


def add_shape_keys_argument(parser) -> None:
    """``--shape-keys TRANSFER|REFUSE``: the wrap's and the mirror's ``shape_keys`` option."""
    parser.add_argument(
        "--shape-keys",
        type=str.upper,
        choices=("TRANSFER", "REFUSE"),
        default="TRANSFER",
        help="a layout with shape keys: wrap its basis and carry the other keys over onto the result, or refuse "
        "it (default %(default)s)",
    )


def shape_keys_report(layout, mode: str) -> dict | None:
    """The report's entry on the layout's shape keys (None without any): the option and the keys' names."""
    keys = layout.data.shape_keys
    if keys is None:
        return None
    return {"mode": mode, "keys": [block.name for block in keys.key_blocks]}


def check_frame_arguments(parser, arguments) -> None:
    """Up and forward must be two different axes (argparse's error, exit code 2)."""
    if arguments.up_axis.removeprefix("NEGATIVE_") == arguments.forward_axis.removeprefix("NEGATIVE_"):
        parser.error(f"--up-axis {arguments.up_axis} and --forward-axis {arguments.forward_axis} are the same axis")


# ---------------------------------------------------------------- outputs


def check_output_arguments(parser, outputs: dict, inputs: list) -> None:
    """Outputs (``{option: path or None}``) that cannot be what was meant (argparse's error, exit code 2): a
    wrong suffix, two outputs on one file, an output that would replace an input."""
    suffixes = {"--output-blend": ".blend", "--output-obj": ".obj", "--output": ".blend"}
    seen = {}
    for option, path in outputs.items():
        if path is None:
            continue
        wanted = suffixes.get(option)
        if wanted is not None and Path(path).suffix.lower() != wanted:
            parser.error(f"{option} {path}: the file name must end with {wanted}")
        resolved = Path(path).resolve()
        if resolved in seen:
            parser.error(f"{seen[resolved]} and {option} name the same file ({path})")
        seen[resolved] = option
    for path in inputs:
        if path is not None and Path(path).resolve() in seen:
            parser.error(f"{seen[Path(path).resolve()]} {path} would replace an input")


def check_output_folder(folder: Path) -> None:
    """Refuse (:class:`ScriptError`) a folder that cannot be written, before any work: its nearest existing
    ancestor must be a folder in which a file can be created (tried, then removed)."""
    folder = Path(folder).resolve()
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ScriptError(f"{existing}: is a file, not a folder, so {folder} cannot be written")
    try:
        handle, probe = tempfile.mkstemp(prefix=".springwrap-probe-", dir=existing)
    except OSError as error:
        # The system's reason, except where it misleads: a folder that exists but takes no new files (/proc, a
        # virtual file system) answers "No such file or directory".
        reason = "" if error.errno == errno.ENOENT else f" ({error.strerror or error})"
        raise ScriptError(f"{existing}: not writable: no file can be created in this folder{reason}") from None
    os.close(handle)
    os.unlink(probe)


def check_output_paths(paths) -> None:
    """Refuse (:class:`ScriptError`) output files that cannot be written, before any work: a path that is a
    folder, a folder that cannot be written."""
    for path in paths:
        if path is None:
            continue
        path = Path(path)
        if path.is_dir():
            raise ScriptError(f"{path}: is a folder; name the output file")
        if path.exists() and not path.is_file():
            raise ScriptError(f"{path}: exists and is not a regular file")
        check_output_folder(path.resolve().parent)


def partial_path(final: Path) -> Path:
    """The temporary file an output is written to before it is renamed to ``final``."""
    return final.with_name(f".{final.stem}.partial{final.suffix}")


def previous_path(final: Path) -> Path:
    """Where an output's earlier file is kept while the new ones are renamed into place."""
    return final.with_name(f".{final.stem}.previous{final.suffix}")


def _remove_temporary(temporary: Path) -> None:
    temporary.unlink(missing_ok=True)
    temporary.with_name(temporary.name + "@").unlink(missing_ok=True)  # Blender saves to FILE@, then renames


def write_all_or_nothing(outputs) -> list[Path]:
    """Write every output of ``outputs`` (``(final path or None, write)`` pairs; ``write(temporary path)``
    writes one) to a temporary file beside it, then rename them all into place: a failure at any point,
    also while renaming, leaves none of them behind, the files they would have replaced as they were, and
    no folder it created. The final paths written."""
    temporaries, created, renamed, kept = [], [], [], []
    try:
        for final, write in outputs:
            if final is None:
                continue
            final = Path(final).resolve()
            missing = [folder for folder in (final.parent, *final.parent.parents) if not folder.exists()]
            for folder in reversed(missing):
                folder.mkdir()
                created.append(folder)
            temporary = partial_path(final)
            temporaries.append((temporary, final))
            write(temporary)
            if not temporary.is_file():
                raise ScriptError(f"{final}: nothing was written")
        for temporary, final in temporaries:
            if final.exists():
                os.replace(final, previous_path(final))
                kept.append(final)
            os.replace(temporary, final)
            renamed.append(final)
    except BaseException:
        for final in renamed:
            final.unlink(missing_ok=True)
        for final in kept:
            os.replace(previous_path(final), final)
        for temporary, _final in temporaries:
            _remove_temporary(temporary)
        for folder in reversed(created):
            try:
                folder.rmdir()
            except OSError:
                pass
        raise
    for final in kept:
        previous_path(final).unlink(missing_ok=True)
    return [final for _temporary, final in temporaries]


def write_atomically(final: Path, write) -> Path:
    """One output written all or nothing (see :func:`write_all_or_nothing`)."""
    return write_all_or_nothing([(final, write)])[0]
