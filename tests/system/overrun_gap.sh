#!/usr/bin/env bash
# A stalled controller is noticed: cncd on a copy of configs/sim is stopped
# with SIGSTOP for 2 s and continued. The servo thread must report the gap
# (about 2000 periods missed at once) in the status and on the message
# channel; with the default OVERRUN_ACTION (WARN) the machine stays on, with
# OVERRUN_ACTION = STOP it is turned off with the reason.
#   overrun_gap.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
work="$(mktemp -d /var/tmp/cnc-overrun-gap.XXXXXX)"
daemon=""
trap 'if [ -n "$daemon" ]; then kill -CONT "$daemon" 2>/dev/null || true; kill "$daemon" 2>/dev/null || true; fi; rm -rf "$work"' EXIT
export CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; echo "--- messages"; "$bin/cnc" messages || true; echo "--- controller log"; cat "$work/cncd.log" || true; exit 1; }

# Prints the task state and the servo thread's figures from `cnc status --json`.
figures() {
  "$bin/cnc" status --json | /usr/bin/python3 -c '
import json, sys
s = json.load(sys.stdin)
t = [t for t in s["threads"] if t["name"] == "servo-thread"][0]
print(s["task"]["state"], t["missed_cycles"], t["longest_gap"], t["overruns"], t["late_wakes"])'
}

run_case() {
  local action="$1"
  rm -rf "$work/sim" && cp -r "$config" "$work/sim"
  if [ "$action" != default ]; then
    # Inserted first in [EMCMOT], so they win over the copy's own keys (the
    # first occurrence of a key counts). A long streak limit (0.5 s): the
    # scheduling noise of a loaded test host without SCHED_FIFO does not
    # stop the machine before the stall does.
    sed -i "s/^\[EMCMOT\]$/[EMCMOT]\nOVERRUN_ACTION = $action\nOVERRUN_STREAK = 500/" "$work/sim/sim.ini"
    grep -q "^OVERRUN_ACTION = $action" "$work/sim/sim.ini" || fail "could not set OVERRUN_ACTION"
  fi
  export CNC_INSTANCE="overrun-$$-$action"
  "$bin/cncd" "$work/sim/sim.ini" 2>"$work/cncd.log" &
  daemon=$!
  "$bin/cnc" --timeout 30 wait-ready || fail "$action: controller did not start"
  "$bin/cnc" estop-reset || fail "$action: estop-reset"
  "$bin/cnc" on || fail "$action: machine on"
  read -r state missed gap overruns late < <(figures)
  [ "$state" = ON ] || fail "$action: machine not on before the stall ($state)"
  [ "$gap" -lt 1000 ] || fail "$action: a gap of $gap periods before the stall"
  kill -STOP "$daemon"
  sleep 2
  kill -CONT "$daemon"
  # The task cycle publishes within milliseconds; allow a loaded host 5 s.
  for _ in $(seq 50); do
    read -r state missed gap overruns late < <(figures)
    [ "$gap" -ge 1500 ] && break
    sleep 0.1
  done
  echo "$action: state $state, $missed periods missed, longest gap $gap, $overruns overruns, $late on late wake-ups"
  [ "$gap" -ge 1500 ] && [ "$gap" -le 3000 ] || fail "$action: longest gap $gap periods, expected about 2000"
  [ "$missed" -ge "$gap" ] || fail "$action: $missed periods missed in all, fewer than the gap $gap"
  local msgs=""
  for _ in $(seq 50); do
    msgs="$("$bin/cnc" messages)"
    grep -q "\[servo-thread\] no cycle for [12]\.[0-9]* s: [0-9]* periods of 1.000 ms missed at once" <<<"$msgs" && break
    sleep 0.1
  done
  grep -q "\[servo-thread\] no cycle for [12]\.[0-9]* s: [0-9]* periods of 1.000 ms missed at once" <<<"$msgs" ||
    fail "$action: no gap message"
  # The stall is blamed on the late wake-up, or, when the stop caught the
  # thread inside a function, on that function, which then ran the 2 s.
  grep -q "missed at once; \(the thread woke [12]\.[0-9]* s late\|blamed on [^ ]*, which ran [12]\.[0-9]* s\)" <<<"$msgs" ||
    fail "$action: the gap is blamed on neither the wake-up nor the function the stop interrupted"
  case "$action" in
    default)
      [ "$state" = ON ] || fail "WARN: the machine left the on state ($state)"
      ;;
    STOP)
      for _ in $(seq 50); do
        read -r state missed gap overruns late < <(figures)
        [ "$state" != ON ] && break
        sleep 0.1
      done
      [ "$state" != ON ] || fail "STOP: the machine is still on"
      "$bin/cnc" messages | grep "the servo thread is late: .* (OVERRUN_ACTION = STOP): motion disabled" >/dev/null ||
        fail "STOP: no reason on the message channel"
      ;;
  esac
  "$bin/cnc" shutdown || fail "$action: shutdown"
  wait "$daemon" || fail "$action: cncd exited with an error"
  daemon=""
}

run_case default
run_case STOP
echo "PASS"
