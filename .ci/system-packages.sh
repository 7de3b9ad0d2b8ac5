#!/usr/bin/env bash
# Debian packages the project needs beyond the base image: the shared libraries the PyPI `bpy`
# module links against. Does nothing when they are all present; otherwise installs the missing
# ones with apt-get (as root, or through sudo).
set -euo pipefail
packages=(libgl1 libglx0 libx11-6 libxext6 libxfixes3 libxi6 libxkbcommon0 libxrender1 libsm6 libice6)
bash "$(dirname "$0")/install-missing.sh" system-packages "${packages[@]}"
