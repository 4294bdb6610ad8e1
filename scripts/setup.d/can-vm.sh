#!/usr/bin/env bash
# Prepares Debian's own kernel for the virtual-CAN tests (scripts/vm/): the
# image package that linux-image-amd64 depends on is fetched with
# `apt-get download` and unpacked with `dpkg -x` into .cache/can-vm/ (ignored
# by git). Nothing is installed. Idempotent: a kernel already unpacked for the
# current package version is kept. Run by scripts/setup.sh; may be run alone.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cache="${CNC_VM_CACHE:-$root/.cache/can-vm}"

# The versioned package behind the meta-package, e.g. linux-image-6.1.0-56-amd64.
versioned() { apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}'; }
pkg="$(versioned)"
if [ -z "$pkg" ]; then
  # No package lists yet (fresh system): fetch them once.
  if [ "$(id -u)" -eq 0 ]; then apt-get update -qq || true
  elif command -v sudo >/dev/null; then sudo apt-get update -qq || true
  fi
  pkg="$(versioned)"
fi
if [ -z "$pkg" ]; then
  echo "can-vm: apt-cache does not know linux-image-amd64 (no package lists?); the vm tests need it" >&2
  exit 1
fi
version="$(apt-cache policy "$pkg" 2>/dev/null | awk '/Candidate:/ {print $2; exit}')"
stamp="$cache/kernel/.unpacked"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$pkg $version" ] && ls "$cache"/kernel/boot/vmlinuz-* >/dev/null 2>&1; then
  echo "can-vm: kernel $pkg $version already unpacked in $cache/kernel"
  exit 0
fi

mkdir -p "$cache/deb"
( cd "$cache/deb" && rm -f ./*.deb && apt-get download -q "$pkg" 2>&1 | grep -v "^W: Download is performed unsandboxed" || true )
deb="$(ls "$cache"/deb/"$pkg"_*.deb 2>/dev/null | head -n1)"
if [ -z "$deb" ]; then
  echo "can-vm: apt-get download $pkg failed" >&2
  exit 1
fi
rm -rf "$cache/kernel.new"
dpkg -x "$deb" "$cache/kernel.new"
rm -rf "$cache/kernel"
mv "$cache/kernel.new" "$cache/kernel"
rm -f "$deb"
echo "$pkg $version" > "$stamp"
echo "can-vm: unpacked $pkg $version into $cache/kernel"
