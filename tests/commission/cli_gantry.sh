#!/usr/bin/env bash
# A gantry pair through cnc-commission as a script uses it: X on node 1,
# Y on nodes 2 and 3 (the second drive mounted mirrored) of a simulated
# random machine (cnc-sim-random-machine, seed 7); bad assignments refused
# with nothing saved; the configuration written (trivkins with Y twice,
# kinstype=BOTH, both Y joints with one negative HOME_SEQUENCE) and
# `cnc-commission check` on it: cncd starts, homes every joint (the pair
# together) and runs the check program, which moves Y on both drives.
set -eu
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-gantry-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/m/check-cncd.log" ] && tail -20 "$work/m/check-cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }

"$bin/cnc-sim-random-machine" --seed 7 --dir "$work/m" --interface "virtual:gantry-$$" --nodes 1,2,3 >/dev/null
# Node 3 becomes node 2's twin on the gantry's other side: the same drive,
# screw and switches, the motor mounted the other way round.
python3 - "$work/m/sim-machine.ini" <<'EOF_PY'
import re, sys
text = open(sys.argv[1]).read()
sec = lambda n: re.search(r"\[CIA402_SIM_NODE_%d\]\n(.*?)(?=\n\[|\Z)" % n, text, re.S)
two = sec(2).group(1)
rev = "NO" if "MOTOR_REVERSED = YES" in two else "YES"
three = re.sub(r"MOTOR_REVERSED = \w+", "MOTOR_REVERSED = " + rev, two).replace("NAME = axis-2", "NAME = axis-3")
m = sec(3)
open(sys.argv[1], "w").write(text[:m.start(1)] + three + text[m.end(1):])
EOF_PY
# Node-IDs 1 and 2 from the truth, node 3 as node 2.
counts() { python3 -c "import json;print(int(json.load(open('$work/m/sim-truth.json'))['axes'][min($1, 1)]['encoder_counts']))"; }
node() {
  cat <<JSON
{"node_id": $1, "device_type": 131474, "vendor_id": 3265, "product_code": 1026, "name": "drive $1",
 "cia402": true, "fault": false, "supported_modes": 928, "encoder_increments": $(counts $(($1 - 1))),
 "encoder_motor_revs": 1, "problems": []}
JSON
}
cat > "$work/state.json" <<JSON
{"version": 1, "interface": "virtual:gantry-$$", "nodes": [$(node 1), $(node 2), $(node 3)], "axes": []}
JSON

cc axis X assign --node 1 --joint 0 >/dev/null || fail "assign X"
# Bad gantry assignments: refused naming the drive or joint, nothing saved.
before="$(cat "$work/state.json")"
if cc axis Y assign --node 2 --gantry-node 1 2>"$work/err"; then fail "X's drive taken as Y's second drive"; fi
grep -q "node 1 already drives axis X" "$work/err" || fail "no message for a drive in use: $(cat "$work/err")"
if cc axis Y assign --node 2 --gantry-node 3 --gantry-joint 0 2>"$work/err"; then fail "X's joint taken"; fi
grep -q "joint 0 already belongs to axis X" "$work/err" || fail "no message for a joint in use: $(cat "$work/err")"
if cc axis Y assign --node 2 --gantry-node 9 2>"$work/err"; then fail "an unknown second drive was assigned"; fi
grep -q "axis Y: the gantry's second drive, node 9 was not found by the bus scan" "$work/err" \
  || fail "no message for an unknown second drive: $(cat "$work/err")"
set +e; cc axis Y assign --slave 2 --gantry-node 3 2>"$work/err"; rc=$?; set -e
[ $rc -eq 2 ] || fail "a CANopen second drive with an EtherCAT first one: status $rc"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused assignment changed the state"

cc axis Y assign --node 2 --joint 1 --gantry-node 3 --gantry-reverse > "$work/out" || fail "assign Y: $(cat "$work/out")"
grep -q "axis Y: node 2 on joint 1, gantry pair with node 3 on joint 2 (reversed)" "$work/out" || fail "assign Y: $(cat "$work/out")"
cc show | grep -q "gantry pair: node 3 on joint 2, reversed" || fail "show: no gantry pair"
cc axis X scaling --lead 5 >/dev/null
cc axis Y scaling --lead 5 >/dev/null
cc axis X limits --min -5 --max 5 --velocity 10 --acceleration 100 >/dev/null
cc axis Y limits --min -5 --max 5 --velocity 10 --acceleration 100 >/dev/null
cc include --ini sim-machine.ini --hal-before-bus sim-machine.hal --hal-after-bus sim-machine-run.hal >/dev/null

cc write --dir "$work/m" --name gantry --yes > "$work/out" || fail "write --yes: $(cat "$work/out")"
ini="$work/m/gantry.ini"
grep -qx "KINEMATICS = trivkins coordinates=XYY kinstype=BOTH" "$ini" || fail "kinematics: $(grep KINEMATICS "$ini")"
grep -qx "JOINTS = 3" "$ini" || fail "joints"
[ "$(grep -c '^HOME_SEQUENCE = -1$' "$ini")" = 2 ] || fail "the pair does not home together: $(grep HOME_SEQUENCE "$ini")"
grep -q "^net y2-pos-cmd joint.2.motor-pos-cmd => cia402.0.drive.02.pos-cmd$" "$work/m/gantry.hal" || fail "no HAL for the second drive"

# cncd runs it: every joint homed (the pair together), the check program
# moves X and Y (both drives) and ends where it declares.
cc check > "$work/out" || fail "check: $(cat "$work/out")"
grep -q "^check passed: .*ending at X0 Y0 as declared" "$work/out" || fail "check: $(cat "$work/out")"
grep -q "G53 G1 Y" "$work/m/check.ngc" || fail "the check program does not move Y: $(cat "$work/m/check.ngc")"

# Both sides of the gantry carry the table the same way: Y moved 4 mm by
# MDI, the simulator's true table positions of the two drives (the second
# one's motor turning the other way) moved alike.
cc bring-up --dir "$work/m" --name gantry | grep -q "cncd runs on" || fail "bring-up"
table() { "$bin/halcmd" getp "cia402-sim.0.node.0$1.table-position"; }
"$bin/cnc" estop-reset && "$bin/cnc" on && "$bin/cnc" home all >/dev/null || fail "on and homed"
"$bin/cnc" mode mdi >/dev/null
l0="$(table 2)"; r0="$(table 3)"
"$bin/cnc" mdi "G53 G1 Y4 F300" >/dev/null || fail "MDI move"
sleep 0.3
l1="$(table 2)"; r1="$(table 3)"
"$bin/cnc" off >/dev/null
cc shutdown >/dev/null
python3 -c "
l, r = $l1 - $l0, $r1 - $r0
print(f'Y moved 4 mm: the drives\' tables moved {l:.4f} and {r:.4f} mm')
assert abs(l) > 1 and abs(l - r) < 0.01, (l, r)" || fail "the gantry's sides did not move alike"
echo PASS
