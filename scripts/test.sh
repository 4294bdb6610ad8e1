#!/usr/bin/env bash
# Sets up, builds and runs every test (all labels: unit, vm, netns, gui, package,
# slow). Extra arguments go to ctest, e.g. `scripts/test.sh -L unit` or
# `scripts/test.sh -LE vm`.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
cd "$root/build"
ctest -j "$(nproc)" --output-on-failure --timeout 600 "$@"
