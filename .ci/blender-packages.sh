#!/usr/bin/env bash
# Debian packages of the Blender 3.4 lane (`make test-blender34`): Debian's blender (3.4.1 on
# bookworm, whose Python is the system's 3.11) and the system Python's pytest and numpy, which that
# blender imports. Does nothing when they are all present; otherwise installs the missing ones.
set -euo pipefail
packages=(blender python3-pytest python3-numpy)
missing=()
for package in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "blender-packages: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
