#!/usr/bin/env bash
# Builds the Debian packages in one command (docs/install.md): configures
# the build folder for /usr, builds the programs the packages hold and
# their manual pages, runs CPack (DEB, one package per component) and
# lintian. The packages land in build/packages/ (or OUT).
#   scripts/package.sh [--build-dir DIR] [--out DIR] [--no-lintian]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$root/build"
out=""
lintian=1
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build="$(realpath -m "$2")"; shift 2 ;;
    --out) out="$(realpath -m "$2")"; shift 2 ;;
    --no-lintian) lintian=0; shift ;;
    -h|--help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "package.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
out="${out:-$build/packages}"

export CCACHE_DIR="${CCACHE_DIR:-/work/.ccache}" CCACHE_BASEDIR="${CCACHE_BASEDIR:-$root}"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}"
fi
# The packages install under /usr whatever the build folder was set up with
# (the default of a new build folder; configured again only when not).
if ! grep -qx 'CMAKE_INSTALL_PREFIX:PATH=/usr' "$build/CMakeCache.txt"; then
  cmake "$build" -DCMAKE_INSTALL_PREFIX=/usr -UCMAKE_INSTALL_LIBDIR >/dev/null
fi
# Only what the packages hold: the programs, their manual pages.
targets=(cncd cnc halcmd cnc-rs274 cnc-canopen cnc-ethercat cnc-comp cnc-commission cnc-cia402-sim ecat-sim cnc-modbus-sim
         cnc-canopen-node cnc_man_pages cnc_deb_changelog)
if grep -q '^cnc-hmi:' <(cmake --build "$build" --target help 2>/dev/null | sed 's/^\([^:]*\):.*/\1:/'); then
  targets+=(cnc-hmi cnc-commission-wizard)
fi
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}"
mkdir -p "$out"
rm -f "$out"/*.deb
(cd "$build" && cpack -G DEB -B "$out" >"$out/cpack.log" 2>&1) || { cat "$out/cpack.log" >&2; exit 1; }
rm -rf "$out/_CPack_Packages"
ls -l "$out"/*.deb
if [ $lintian -eq 1 ] && command -v lintian >/dev/null; then
  # Remaining tags are explained in docs/install.md, "lintian".
  lintian --tag-display-limit 0 "$out"/*.deb | tee "$out/lintian.txt" || true
fi
