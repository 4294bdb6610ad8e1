#!/usr/bin/env bash
# Sets up, builds and runs every test (all labels: unit, vm, netns, gui, package,
# slow). Extra arguments go to ctest, e.g. `scripts/test.sh -L unit` or
# `scripts/test.sh -LE vm`. A failed test is run a second time; the digest at
# the end names every test that failed once (scripts/test_digest.py).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
cd "$root/build"
# A test that fails is run once more; one that then passes does not fail the
# run, but the digest printed last names it with why it failed the first time.
rc=0
ctest -j "$(nproc)" --output-on-failure --timeout 600 --repeat until-pass:2 "$@" || rc=$?
python3 "$root/scripts/test_digest.py" Testing/Temporary/LastTest.log
exit "$rc"
