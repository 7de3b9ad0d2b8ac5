#!/usr/bin/env bash
# Debian packages the project needs beyond the base image: the shared libraries the PyPI `bpy`
# module links against. Does nothing when they are all present; otherwise installs the missing
# ones with apt-get (as root, or through sudo).
set -euo pipefail
packages=(libgl1 libglx0 libx11-6 libxext6 libxfixes3 libxi6 libxkbcommon0 libxrender1 libsm6 libice6)
missing=()
for package in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "system-packages: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
