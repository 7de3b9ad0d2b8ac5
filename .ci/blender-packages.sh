#!/usr/bin/env bash
# Debian packages of the Blender 3.4 lane (`make test-blender34`): Debian's blender (3.4.1 on
# bookworm, whose Python is the system's 3.11) and the system Python's pytest and numpy, which that
# blender imports. Does nothing when they are all present; otherwise installs the missing ones.
set -euo pipefail
packages=(blender python3-pytest python3-numpy)
bash "$(dirname "$0")/install-missing.sh" blender-packages "${packages[@]}"
