#!/usr/bin/env bash
# Sets up, builds and runs the main job: the controller daemon on the
# simulated mill (configs/sim), driven from the command-line client like an
# operator would: E-stop reset, machine on, home, AUTO, run a real part
# program to the end, then a clean shutdown. Every command is printed.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"

bin="$root/build/bin"
export CNC_INSTANCE="demo-$$"
# Run on a copy of the configuration: the controller writes its parameter
# file and tool table there.
run="$root/build/demo"
rm -rf "$run"
cp -r "$root/configs/sim" "$run"
log="$run/cncd.log"
step() { echo; echo "\$ ${*#$bin/}"; "$@"; }

echo
echo "== Starting the controller on the simulated mill (log: $log)"
"$bin/cncd" "$run/sim.ini" 2>"$log" &
daemon=$!
trap 'kill $daemon 2>/dev/null || true' EXIT
step "$bin/cnc" wait-ready
step "$bin/cnc" estop-reset
step "$bin/cnc" on
step "$bin/cnc" home all
step "$bin/cnc" mode auto
step "$bin/cnc" open "$run/nc_files/demo.ngc"
step "$bin/cnc" run
step "$bin/cnc" wait-program
step "$bin/cnc" status
step "$bin/cnc" messages
step "$bin/cnc" shutdown
wait $daemon
trap - EXIT
echo
echo "== Controller log"
cat "$log"
