"""What every headless script shares: its own arguments, the add-on enabled (from a checkout or installed as an
extension) and its modules, exit codes and the one-line failure, and outputs written all or nothing.

A script runs both ways:

    python X.py ARGS                        (PyPI ``bpy`` module): everything after the script's path
    blender -b --python X.py -- ARGS        (a real Blender): everything after ``--``
    blender -b --python X.py                no arguments (``sys.argv`` is Blender's own)

This module imports no ``bpy`` at its top (the batch's coordinator uses it without Blender);
``addon_utils`` is imported when the add-on is enabled.
"""

import importlib
import os
import sys
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


# ---------------------------------------------------------------- outputs


def partial_path(final: Path) -> Path:
    """The temporary file an output is written to before it is renamed to ``final``."""
    return final.with_name(f".{final.stem}.partial{final.suffix}")


def write_all_or_nothing(outputs) -> list[Path]:
    """Write every output of ``outputs`` (``(final path or None, write)`` pairs; ``write(temporary path)``
    writes one) to a temporary file beside it, then rename them all: a failure leaves none of them behind.
    The final paths written."""
    temporaries = []
    try:
        for final, write in outputs:
            if final is None:
                continue
            final = Path(final).resolve()
            final.parent.mkdir(parents=True, exist_ok=True)
            temporary = partial_path(final)
            temporaries.append((temporary, final))
            write(temporary)
            if not temporary.is_file():
                raise ScriptError(f"{final}: nothing was written")
        for temporary, final in temporaries:
            os.replace(temporary, final)
    finally:
        for temporary, _final in temporaries:
            temporary.unlink(missing_ok=True)
    return [final for _temporary, final in temporaries]


def write_atomically(final: Path, write) -> Path:
    """One output written all or nothing (see :func:`write_all_or_nothing`)."""
    return write_all_or_nothing([(final, write)])[0]
