"""Run the pytest suite inside a real Blender (the Debian ``blender`` 3.4 lane).

    blender -b --factory-startup --python-exit-code 1 --python tests/run_in_blender.py -- [pytest args]

Blender's Python must already see pytest and numpy (Debian: python3-pytest, python3-numpy). The
kernel wheel is found on ``SPRINGWRAP_KERNEL_PATH`` (a folder the wheel was unpacked or installed
into, e.g. ``pip install --target``); the add-on is linked into ``$BLENDER_USER_SCRIPTS/addons`` by
the tests' conftest. Exits with pytest's exit code (non-zero on any failure or collection error).
"""

import os
import sys
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parent.parent


def main() -> int:
    arguments = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    import bpy

    kernel_path = os.environ.get("SPRINGWRAP_KERNEL_PATH")
    if kernel_path:
        sys.path.insert(0, kernel_path)
        # Scripts the tests start in their own blender (`--python-use-system-env`) find it there too.
        os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [kernel_path, os.environ.get("PYTHONPATH")]))
    os.environ["SPRINGWRAP_TEST_LANE"] = "blender"
    os.environ["SPRINGWRAP_BLENDER"] = bpy.app.binary_path
    os.chdir(REPOSITORY)
    import pytest

    return int(pytest.main(["-p", "no:cacheprovider", *arguments]))


if __name__ == "__main__":
    code = main()
    # Blender's own exit code is 0 after a script that returned; only an exception or sys.exit sets it.
    sys.stdout.flush()
    sys.exit(code)
