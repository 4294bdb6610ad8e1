#!/usr/bin/env bash
# Sets up, builds and runs the main job: the controller daemon on the
# simulated mill (configs/sim), driven from the command-line client, then a
# clean shutdown. Everything it runs is printed as it runs.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"

bin="$root/build/bin"
export CNC_INSTANCE="demo-$$"
log="$root/build/demo-cncd.log"
step() { echo; echo "\$ $*"; "$@"; }

echo
echo "== Starting the controller on the simulated mill (log: $log)"
"$bin/cncd" "$root/configs/sim/sim.ini" 2>"$log" &
daemon=$!
trap 'kill $daemon 2>/dev/null || true' EXIT
step "$bin/cnc" wait-ready
step "$bin/cnc" status
step "$bin/halcmd" show thread
step "$bin/cnc" shutdown
wait $daemon
trap - EXIT
echo
echo "== Controller log"
cat "$log"
