# Sourced by system tests (needs $bin, the build's bin folder, and $config,
# a configuration folder): starts cncd on a copy of $config in a fresh
# folder $work (as $work/sim), instance NAME-test-<pid>, without realtime,
# log in $work/cncd.log; stops it and removes the folder on exit. Defines
# cnc (the build's cnc).
#   source cncd_on_copy.sh NAME
work="$(mktemp -d "/var/tmp/cnc-$1-test.XXXXXX")"
daemon=""
cleanup() {
  if [ -n "$daemon" ]; then kill "$daemon" 2>/dev/null || true; wait "$daemon" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
cp -r "$config" "$work/sim"
export CNC_INSTANCE="$1test-$$"
export CNC_NO_REALTIME=1
"$bin/cncd" "$work/sim/sim.ini" 2>"$work/cncd.log" &
daemon=$!
cnc() { "$bin/cnc" "$@"; }
