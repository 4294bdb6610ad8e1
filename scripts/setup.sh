#!/usr/bin/env bash
# Installs every Debian package the project needs, and nothing else.
# Idempotent: only what is missing is installed. Run as root or as a user
# who may use sudo. Package lists: scripts/deps/*.txt (one package a line).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

packages=()
for list in "$here"/deps/*.txt; do
  while read -r line; do
    line="${line%%#*}"
    line="$(echo "$line" | xargs)"
    [ -n "$line" ] && packages+=("$line")
  done < "$list"
done

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "$(id -u)" -eq 0 ]; then
  SUDO=()
elif command -v sudo >/dev/null; then
  SUDO=(sudo)
else
  SUDO=()
fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} Debian packages are installed"
else
  if [ "$(id -u)" -ne 0 ] && [ ${#SUDO[@]} -eq 0 ]; then
    echo "setup: missing packages: ${missing[*]}" >&2
    echo "setup: run this script as root or install sudo" >&2
    exit 1
  fi
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  "${SUDO[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Module-specific preparation (for example the kernel for CAN tests in a
# virtual machine) lives in scripts/setup.d/*.sh, run in name order.
if [ -d "$here/setup.d" ]; then
  for step in "$here"/setup.d/*.sh; do
    [ -e "$step" ] || continue
    bash "$step"
  done
fi
