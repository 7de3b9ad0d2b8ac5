"""The arguments of a headless script, whichever way it was started.

    python X.py ARGS                        (PyPI ``bpy`` module): everything after the script's path
    blender -b --python X.py -- ARGS        (a real Blender): everything after ``--``
    blender -b --python X.py                no arguments (``sys.argv`` is Blender's own)
"""

from pathlib import Path


def script_arguments(argv: list[str], script_path: str) -> list[str]:
    """The script's own arguments out of ``argv`` (normally ``sys.argv``)."""
    if "--" in argv:
        return argv[argv.index("--") + 1 :]
    if argv and Path(argv[0]).name == Path(script_path).name:
        return argv[1:]
    return []
