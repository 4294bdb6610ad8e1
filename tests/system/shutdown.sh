#!/usr/bin/env bash
# cncd stops cleanly, with exit status 0, however it is asked to: the
# `shutdown` command, SIGTERM and SIGINT, on the task test mill (joints in
# HAL) and on configs/sim (CiA 402 drives behind CANopen, whose threads and
# drives must be stopped in order), with the machine on and homed and an
# MDI move running. A crash while stopping (an earlier session saw SIGSEGV
# in Controller::shutdown) shows as a signal exit status here.
#   shutdown.sh BIN_DIR SOURCE_DIR
set -euo pipefail
bin="$1"
src="$2"
work="$(mktemp -d)"
daemon=""
trap 'if [ -n "$daemon" ]; then kill "$daemon" 2>/dev/null || true; fi; rm -rf "$work"' EXIT
export CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; echo "--- controller log"; cat "$work/cncd.log" || true; exit 1; }

run_case() {
  local config="$1" ini="$2" how="$3"
  rm -rf "$work/m" && cp -r "$src/$config" "$work/m"
  export CNC_INSTANCE="shutdown-$$-$how"
  "$bin/cncd" "$work/m/$ini" 2>"$work/cncd.log" &
  daemon=$!
  "$bin/cnc" --timeout 30 wait-ready || fail "$config: controller did not start"
  # Every thread blocks SIGINT (bit 2) and SIGTERM (bit 15): only the main
  # thread's wait takes them. A thread that did not (blocked in the main
  # thread only, after the others had started) let a signal arriving while
  # the main thread worked kill the process (exit status 143, seen in CI).
  local t blk
  for t in /proc/"$daemon"/task/*; do
    # the main thread: its sigtimedwait unblocks them while it waits
    [ "$(basename "$t")" = "$daemon" ] && continue
    blk=$(awk '/^SigBlk:/ { print $2 }' "$t/status")
    (( (16#$blk & 0x4002) == 0x4002 )) || fail "$config: thread $(basename "$t") ($(cat "$t/comm")) does not block SIGINT and SIGTERM (SigBlk $blk)"
  done
  "$bin/cnc" estop-reset || fail "$config: estop-reset"
  "$bin/cnc" on || fail "$config: machine on"
  "$bin/cnc" --timeout 120 home all || fail "$config: home all"
  "$bin/cnc" mode mdi || fail "$config: mode mdi"
  "$bin/cnc" --timeout 0.5 mdi "G91 G1 X20 F300" >/dev/null 2>&1 || true  # 4 s: still moving when we stop
  case "$how" in
    command) "$bin/cnc" shutdown || fail "$config: shutdown command" ;;
    sigterm) kill -TERM "$daemon" ;;
    sigint) kill -INT "$daemon" ;;
  esac
  local rc=0
  wait "$daemon" || rc=$?
  daemon=""
  [ "$rc" -eq 0 ] || fail "$config ($how): cncd exited with status $rc$([ "$rc" -gt 128 ] && echo " (signal $((rc - 128)))")"
  grep -q "\[cncd\] stopped" "$work/cncd.log" || fail "$config ($how): no 'stopped' line"
  echo "ok: $config, $how: exit status 0"
}

for how in command sigterm sigint; do
  run_case tests/core/task/mill sim.ini "$how"
  run_case configs/sim sim.ini "$how"
done
