#!/usr/bin/env bash
# End to end: start cncd on a copy of configs/sim, power up, home, run the
# demo program through the CLI, then check what the program must leave
# behind: the final position, the tool in the spindle, no errors, and the
# work offset it set persisted in the parameter file.
set -euo pipefail
bin="$1"
config="$2"
work="$(mktemp -d)"
trap 'kill $daemon 2>/dev/null || true; rm -rf "$work"' EXIT
cp -r "$config" "$work/sim"
export CNC_INSTANCE="systest-$$"
export CNC_NO_REALTIME=1
"$bin/cncd" "$work/sim/sim.ini" 2>"$work/cncd.log" &
daemon=$!
fail() { echo "FAIL: $*"; echo "--- controller log"; cat "$work/cncd.log"; exit 1; }
"$bin/cnc" --timeout 20 wait-ready || fail "controller did not start"
"$bin/cnc" estop-reset || fail "estop-reset"
"$bin/cnc" on || fail "machine on"
"$bin/cnc" --timeout 60 home all || fail "home all"
"$bin/cnc" mode auto || fail "mode auto"
"$bin/cnc" open "$work/sim/nc_files/demo.ngc" || fail "open"
"$bin/cnc" run || fail "run"
"$bin/cnc" --timeout 500 wait-program > "$work/progress.txt" || fail "program: $(tail -3 "$work/progress.txt")"
json="$("$bin/cnc" status --json)"
check() {
  /usr/bin/python3 - "$json" <<'PY' || exit 1
import json, sys
s = json.loads(sys.argv[1])
pos = s["motion"]["position"]
# G53 G0 Z0 after the drilling at G54 X80 Y60 (offset X100 Y50): X180 Y110 Z0.
expect = [180.0, 110.0, 0.0]
for i, (got, want) in enumerate(zip(pos[:3], expect)):
    if abs(got - want) > 1e-6:
        sys.exit(f"axis {i}: final position {got}, expected {want}")
if s["io"]["tool_in_spindle"] != 3:
    sys.exit(f"tool in spindle {s['io']['tool_in_spindle']}, expected 3")
if s["task"]["interp_state"] != "IDLE":
    sys.exit("interpreter not idle")
if s["spindles"][0]["enabled"]:
    sys.exit("spindle still on")
print("final state ok:", pos[:3], "tool", s["io"]["tool_in_spindle"])
PY
}
check
# G10 L2 P1 X100 Y50 Z-80 is persisted: #5221..#5223 in the parameter file.
grep -Eq '^5221[[:space:]]+100(\.0+)?$' "$work/sim/sim.var" || fail "G54 X offset not persisted: $(grep ^522 "$work/sim/sim.var" || true)"
grep -Eq '^5223[[:space:]]+-80(\.0+)?$' "$work/sim/sim.var" || fail "G54 Z offset not persisted"
if "$bin/cnc" messages | grep " error " >/dev/null; then fail "errors on the message channel: $("$bin/cnc" messages)"; fi
"$bin/cnc" shutdown || fail "shutdown"
wait $daemon || fail "cncd exited with an error"
# A shutdown is said as one: the task goes to E-stop first, no "fault".
grep -q "E-stop: the controller is shutting down" "$work/cncd.log" || fail "shutdown not announced"
if grep -q "disabled by a fault" "$work/cncd.log"; then fail "shutdown reported as a fault"; fi
tail -3 "$work/progress.txt"
echo "PASS"
