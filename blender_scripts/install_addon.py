"""Link the Springwrap add-on into the running Blender's add-on folder and check it enables.

Runs both ways:
    python blender_scripts/install_addon.py            (PyPI ``bpy`` module, e.g. .venv/bin/python)
    blender -b --python blender_scripts/install_addon.py
Exits non-zero when the add-on cannot be enabled.
"""

import os
import sys
from pathlib import Path

import bpy  # noqa: F401  (must come first: addon_utils needs a running bpy)

import addon_utils

ADDON_SOURCE = Path(__file__).resolve().parent.parent / "addon" / "springwrap"


def main() -> int:
    # A real Blender lists its system add-on folder first: with BLENDER_USER_SCRIPTS set, link there instead.
    user_scripts = os.environ.get("BLENDER_USER_SCRIPTS")
    addon_dir = Path(user_scripts) / "addons" if user_scripts else Path(addon_utils.paths()[0])
    addon_dir.mkdir(parents=True, exist_ok=True)
    link = addon_dir / "springwrap"
    if link.is_symlink() or link.exists():
        if link.resolve() != ADDON_SOURCE:
            print(f"install_addon: {link} exists and is not this checkout's add-on", file=sys.stderr)
            return 1
    else:
        os.symlink(ADDON_SOURCE, link, target_is_directory=True)
    addon_utils.modules_refresh()
    module = addon_utils.enable("springwrap", default_set=True, handle_error=None)
    if module is None:
        print("install_addon: addon_utils.enable('springwrap') failed", file=sys.stderr)
        return 1
    print(f"install_addon: springwrap enabled from {link} -> {ADDON_SOURCE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
