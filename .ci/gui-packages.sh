#!/usr/bin/env bash
# Debian packages of the GUI lane (`make test-gui`): a virtual X server for Blender's interface
# (xvfb, and xauth for xvfb-run) on top of the Blender 3.4 lane's packages (.ci/blender-packages.sh:
# blender, python3-numpy). Software OpenGL comes with Mesa (libgl1-mesa-dri, a dependency of blender).
# Does nothing when they are all present; otherwise installs the missing ones.
set -euo pipefail
bash "$(dirname "$0")/blender-packages.sh"
packages=(xvfb xauth libgl1-mesa-dri)
bash "$(dirname "$0")/install-missing.sh" gui-packages "${packages[@]}"
