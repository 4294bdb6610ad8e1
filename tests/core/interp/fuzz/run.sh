#!/bin/bash
# Builds the interpreter's libFuzzer target with clang-14 in its own build
# folder and runs it. Usage: run.sh [SECONDS] [extra libFuzzer flags...]
# Findings (crash-*, leak-*, timeout-*) land in the current folder; the
# growing corpus in build-fuzz-interp/corpus (seeded from the golden programs).
set -eu
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../../../.." && pwd)"
SECONDS_TO_RUN="${1:-300}"
shift || true
BUILD="$ROOT/build-fuzz-interp"
CC=clang-14 CXX=clang++-14 cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCNC_BUILD_BENCH=OFF -DCNC_BUILD_HMI=OFF >/dev/null
ninja -C "$BUILD" interp_fuzz
mkdir -p "$BUILD/corpus"
for f in "$ROOT"/tests/core/interp/data/programs/*.ngc "$ROOT"/tests/core/interp/data/errors/*.ngc; do
    cp -n "$f" "$BUILD/corpus/" 2>/dev/null || true
done
exec "$BUILD/bin/interp_fuzz" -max_total_time="$SECONDS_TO_RUN" -max_len=4096 -timeout=10 \
    -dict="$HERE/gcode.dict" "$@" "$BUILD/corpus"
