#!/usr/bin/env bash
# Installs the Debian packages named after the label that are not installed yet, with apt-get (as
# root, or through sudo); does nothing when they all are. Usage: install-missing.sh LABEL PACKAGE...
set -euo pipefail
label=$1
shift
missing=()
for package in "$@"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "$label: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
