#!/usr/bin/env bash
# E-stop does not depend on the task cycle, the command channels or motion
# itself staying in the servo thread. On a copy of configs/sim whose E-stop
# chain goes through a signal halcmd can set (halcmd is served by its own
# thread), with the task cycle stalled on purpose (`cnc inject "task stall
# S"`) while an axis jogs:
#   (a) `cnc estop` returns within a bound and the X drive is disabled
#       (cia402.0.drive.00.enabled FALSE) within it; `cnc status` warns that
#       the status is stale and that E-stop still works;
#   (b) opening the E-stop chain does the same;
#   (c) with all 32 command channels taken by other processes, `cnc estop`
#       still works;
#   (d) a spindle drive fault during a program stops the axes and aborts
#       the program with the drive and its fault in the message;
#   (e) `halcmd delf motion-controller servo-thread` during a jog: the
#       motion watchdog (on whenever motion is enabled) makes the drive
#       layer disable the drives, and the task goes to E-stop naming the
#       function; the status no longer says "moving".
#   estop_stalled_task.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
work="$(mktemp -d /var/tmp/cnc-estop-test.XXXXXX)"
daemon=""
pings=()
cleanup() {
  for p in "${pings[@]}"; do kill "$p" 2>/dev/null || true; done
  if [ -n "$daemon" ]; then kill "$daemon" 2>/dev/null || true; wait "$daemon" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
cp -r "$config" "$work/sim"
# The chain: a signal set from halcmd instead of the simulated loop.
sed -i 's/^net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in$/net estop-chain iocontrol.0.emc-enable-in\nsets estop-chain TRUE/' \
  "$work/sim/sim.hal"
grep -q "^sets estop-chain TRUE" "$work/sim/sim.hal" || { echo "FAIL: could not rewire the E-stop chain"; exit 1; }
export CNC_INSTANCE="estoptest-$$"
export CNC_NO_REALTIME=1
"$bin/cncd" "$work/sim/sim.ini" 2>"$work/cncd.log" &
daemon=$!
cnc() { "$bin/cnc" "$@"; }
halcmd() { "$bin/halcmd" "$@"; }
fail() { echo "FAIL: $*"; echo "--- messages"; cnc messages 2>/dev/null | tail -30 || true; echo "--- controller log"; tail -40 "$work/cncd.log"; exit 1; }
now() { date +%s.%N; }
elapsed() { python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.3f}')" "$1" "$2"; }
within() { python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) <= float(sys.argv[2]) else 1)" "$1" "$2"; }
json_field() { cnc status --json | python3 -c "import json, sys; s = json.load(sys.stdin); print($1)"; }
bound=1.0  # seconds: cnc estop returns (a process start, one servo cycle, the acknowledgement)

# Reads X's drive after an action returned at time $1: `enabled` must read
# FALSE within 3 reads 10 ms apart (the drive layer writes it in the servo
# cycle that acted; a halcmd process takes longer than that to start).
# Prints how long after the action the FALSE answer came (mostly halcmd's
# own start-up on a loaded host).
wait_drive_disabled() {
  local t0="$1"
  for _ in 1 2 3; do
    if [ "$(halcmd getp cia402.0.drive.00.enabled)" = "FALSE" ]; then elapsed "$t0" "$(now)"; return 0; fi
    sleep 0.01
  done
  return 1
}
power_up_and_jog() {
  cnc --timeout 10 estop-reset || fail "estop-reset"
  cnc --timeout 10 on || fail "machine on"
  cnc mode manual || fail "mode manual"
  cnc jog x -20 || fail "jog"
  sleep 0.3
  [ "$(halcmd getp cia402.0.drive.00.enabled)" = "TRUE" ] || fail "X drive not enabled while jogging"
}
wait_task_state() {
  for _ in $(seq 100); do
    [ "$(json_field 's["task"]["state"]')" = "$1" ] && return 0
    sleep 0.05
  done
  fail "task state is $(json_field 's["task"]["state"]'), expected $1"
}

cnc --timeout 20 wait-ready || fail "controller did not start"
cnc --timeout 10 estop-reset || fail "estop-reset"
cnc --timeout 10 on || fail "machine on"
cnc --timeout 120 home all || fail "home all"
cnc mode manual || fail "mode manual"
cnc jog x -20 || fail "jog"
sleep 0.2
[ "$(halcmd getp motion.watchdog-enabled)" = "TRUE" ] || fail "motion.watchdog-enabled is FALSE while jogging"

# --- (a) cnc estop while the task cycle is stalled
cnc inject "task stall 3" || fail "inject task stall"
sleep 0.7
status="$(cnc status)"
echo "$status" | grep "WARNING: the task cycle has not run for" >/dev/null || fail "cnc status shows no stale warning: $status"
echo "$status" | grep "E-stop still works" >/dev/null || fail "the warning does not say that E-stop works"
[ "$(json_field 's["liveness"]["task_stalled"]')" = "True" ] || fail "status --json: liveness.task_stalled is not true"
t0="$(now)"
cnc estop || fail "cnc estop failed while the task was stalled"
t1="$(now)"
t_cmd="$(elapsed "$t0" "$t1")"
t_drive="$(wait_drive_disabled "$t1")" || fail "X drive still enabled right after cnc estop returned"
within "$t_cmd" "$bound" || fail "cnc estop took $t_cmd s"
echo "ok (a): cnc estop returned in $t_cmd s; halcmd read X's drive disabled $t_drive s later; task stalled"
sleep 3
wait_task_state ESTOP
cnc messages | grep -Eq "E-stop (by the operator|requested by) \(?process" || fail "the task did not record who asked"

# --- (b) the E-stop chain opens while the task cycle is stalled
power_up_and_jog
cnc inject "task stall 3" || fail "inject task stall"
sleep 0.3
t0="$(now)"
halcmd sets estop-chain FALSE || fail "halcmd sets estop-chain FALSE"
t1="$(now)"
t_drive="$(wait_drive_disabled "$t1")" || fail "X drive still enabled right after the chain opened"
echo "ok (b): chain opened (halcmd sets took $(elapsed "$t0" "$t1") s); halcmd read X's drive disabled $t_drive s later; task stalled"
sleep 3
wait_task_state ESTOP
cnc messages | grep "E-stop chain opened" >/dev/null || fail "no 'E-stop chain opened' message"
halcmd sets estop-chain TRUE

# --- (c) every command channel taken by another process
power_up_and_jog
cnc inject "task stall 4" || fail "inject task stall"
for _ in $(seq 32); do
  "$bin/cnc" --timeout 30 ping >/dev/null 2>&1 &
  pings+=($!)
done
sleep 1
if out="$(cnc --timeout 1 ping 2>&1)"; then fail "a 33rd client got a channel: not all channels were taken"; fi
echo "$out" | grep "too many clients" >/dev/null || fail "33rd client: unexpected answer: $out"
t0="$(now)"
cnc estop 2>"$work/estop.err" || fail "cnc estop failed with every channel taken: $(cat "$work/estop.err")"
t1="$(now)"
t_cmd="$(elapsed "$t0" "$t1")"
t_drive="$(wait_drive_disabled "$t1")" || fail "X drive still enabled right after cnc estop returned"
within "$t_cmd" "$bound" || fail "cnc estop took $t_cmd s"
echo "ok (c): 32 channels taken; cnc estop returned in $t_cmd s ($(tr -d '\n' <"$work/estop.err")); halcmd read X's drive disabled $t_drive s later"
for p in "${pings[@]}"; do wait "$p" || true; done
pings=()
wait_task_state ESTOP

# --- (d) a spindle drive fault during a program
cnc --timeout 10 estop-reset || fail "estop-reset"
cnc --timeout 10 on || fail "machine on"
cnc mode auto || fail "mode auto"
cat >"$work/spindle.ngc" <<'EOF'
G21 G90 G54
G53 G0 X150 Y100 Z-10
S3000 M3
G53 G1 X20 F600
G53 G1 Y20
M5
M2
EOF
cnc open "$work/spindle.ngc" || fail "open"
cnc run || fail "run"
for _ in $(seq 200); do
  [ "$(json_field 's["task"]["current_line"]')" = "4" ] && break
  sleep 0.05
done
[ "$(json_field 's["task"]["current_line"]')" = "4" ] || fail "the program did not reach the feed move"
sleep 0.5
cnc inject "drive 4 overcurrent" || fail "inject spindle overcurrent"
if cnc --timeout 10 wait-program >"$work/program.txt"; then fail "the program ended without an error after the spindle fault"; fi
grep -q "1 errors" "$work/program.txt" || fail "wait-program: $(cat "$work/program.txt")"
sleep 0.5
msgs="$(cnc messages)"
echo "$msgs" | grep "program aborted at line 4: spindle 0 amplifier fault (spindle.0.amp-fault-in); drive spindle: fault 0x2310" >/dev/null ||
  fail "no program abort naming the spindle drive and its fault: $(echo "$msgs" | tail -8)"
[ "$(json_field 'abs(s["motion"]["current_vel"]) < 1e-9')" = "True" ] || fail "the axes still move after the spindle fault"
echo "ok (d): spindle overcurrent aborted the program: $(echo "$msgs" | grep -o 'program aborted.*' | head -1)"
cnc inject "drive 4 clear" || true

# --- (e) motion-controller removed from the servo thread during a jog
power_up_and_jog
[ "$(halcmd getp motion.watchdog-enabled)" = "TRUE" ] || fail "motion.watchdog-enabled is FALSE while jogging"
t0="$(now)"
halcmd delf motion-controller servo-thread || fail "delf"
t1="$(now)"
t_drive="$(wait_drive_disabled "$t1")" || fail "X drive still enabled right after motion-controller was removed"
wait_task_state ESTOP
t_task="$(elapsed "$t0" "$(now)")"
# The message follows the state change within a task cycle or two.
for _ in $(seq 40); do
  cnc messages | grep "E-stop: motion-controller is in no HAL thread any more" >/dev/null && break
  sleep 0.05
done
cnc messages | grep "E-stop: motion-controller is in no HAL thread any more" >/dev/null || fail "no E-stop naming motion-controller"
status="$(cnc status)"
if echo "$status" | grep "moving" >/dev/null; then fail "the status still says moving: $status"; fi
echo "$status" | grep "Motion: NOT RUNNING" >/dev/null || fail "the status does not say that motion does not run"
echo "ok (e): delf motion-controller: halcmd read X's drive disabled $t_drive s after the delf returned (watchdog); task in E-stop $t_task s after the delf"

cnc shutdown || fail "shutdown"
rc=0
wait "$daemon" || rc=$?
daemon=""
[ "$rc" -eq 0 ] || fail "cncd exited with status $rc"
echo "PASS"
