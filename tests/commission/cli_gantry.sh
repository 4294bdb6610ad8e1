#!/usr/bin/env bash
# A gantry pair through cnc-commission as a script uses it: X on node 1,
# Y on nodes 2 and 3 of a simulated random machine (cnc-sim-random-machine,
# seed 7). Node 3 is node 2's twin on the gantry's other side, but not an
# exact one: its motor turns the same way although it is assigned with
# --gantry-reverse (a wrong belief the direction test must find on that
# side), its screw is 0.4 % longer, it powers on 0.6 mm ahead of node 2 and
# its home switch sits 0.3 mm further (the racking the squaring must find).
# Bad assignments are refused with nothing saved; the configuration is
# written (trivkins with Y twice, kinstype=BOTH, both Y joints with one
# negative HOME_SEQUENCE) and `cnc-commission check` runs on it. Then steps
# 4-7 on both sides: direction and scaling per drive (two rounds, the dial
# readings from the simulator's table positions), the switches of each
# side, homing with the squaring read from the two table positions, the
# tuning of the pair (homed together, both sides recorded); written
# again, homed by cncd: the two sides stand square, and Y moved 4 mm by MDI
# moves both tables 4 mm.
set -eu
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-gantry-$$" CNC_NO_REALTIME=1
fail() {
  echo "FAIL: $*"
  for log in "$work/m/check-cncd.log" "$work/m/cncd.log"; do [ -f "$log" ] && grep -v "late spell\|no cycle for\|on time again" "$log" | tail -15; done
  exit 1
}
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }

"$bin/cnc-sim-random-machine" --seed 7 --dir "$work/m" --interface "virtual:gantry-$$" --nodes 1,2,3 >/dev/null
# Node 3 becomes node 2's twin on the gantry's other side (see above).
python3 - "$work/m/sim-machine.ini" <<'EOF_PY'
import re, sys
text = open(sys.argv[1]).read()
sec = lambda n: re.search(r"\[CIA402_SIM_NODE_%d\]\n(.*?)(?=\n\[|\Z)" % n, text, re.S)
two = sec(2).group(1)
three = two.replace("NAME = axis-2", "NAME = axis-3")
lead = float(re.search(r"SCREW_LEAD = (\S+)", three).group(1))
three = re.sub(r"SCREW_LEAD = \S+", "SCREW_LEAD = %.6f" % (lead * 1.004), three)
lo, hi = map(float, re.search(r"HOME_SWITCH = (\S+) (\S+)", three).groups())
three = re.sub(r"HOME_SWITCH = .*", "HOME_SWITCH = %.6f %.6f" % (lo + 0.3, hi + 0.3), three)
three += "\nSTART_POSITION = 0.6"
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

# Steps 4-6 on both sides of the pair. The dial: the simulator's true
# table position of each drive, read around each test.
table() { "$bin/halcmd" getp "cia402-sim.0.node.0$1.table-position"; }
direction_round() {  # DISTANCE
  cc bring-up --dir "$work/m" --name gantry | grep -q "cncd runs on" || fail "bring-up for the direction test"
  [ "$(grep -c '^HOME_SEQUENCE = 0$' "$work/m/gantry.ini")" = 3 ] || fail "the pair is homed together before its homing is commissioned"
  local l0 r0 l1 r1
  l0="$(table 2)"; r0="$(table 3)"
  cc axis Y direction-test --distance "$1" --velocity 5 > "$work/out" || fail "direction-test $1: $(cat "$work/out")"
  sleep 0.2
  l1="$(table 2)"; r1="$(table 3)"
  cc shutdown >/dev/null
  cc axis Y dial "$(python3 -c "print($l1 - $l0)")" "$(python3 -c "print($r1 - $r0)")" | tee -a "$work/verdicts"
}
direction_round 2
grep -q "axis Y (the gantry's second drive, joint 2): the table moved against the command: REVERSE flipped to NO" "$work/verdicts" \
  || fail "the second drive's direction was not found: $(cat "$work/verdicts")"
direction_round 10
python3 - "$work/state.json" "$work/m/sim-truth.json" <<'PY' || fail "each side's scale and direction"
import json, sys
y = [a for a in json.load(open(sys.argv[1]))["axes"] if a["letter"] == "Y"][0]
truth = json.load(open(sys.argv[2]))["axes"][1]["counts_per_mm"]
first = y["scaling"]["counts_per_mm"]
second = first / y["scaling"]["correction"] * y["gantry"]["correction"]
print(f"Y counts/mm: first {first:.4f}, second {second:.4f}; truth {truth:.4f} and {truth / 1.004:.4f}")
assert abs(first / truth - 1) < 0.002, (first, truth)
assert abs(second / (truth / 1.004) - 1) < 0.002, (second, truth / 1.004)
PY

cc axis Y switches --search 150 --velocity 20 --bring-up "$work/m" > "$work/out" || fail "switches: $(cat "$work/out")"
grep -q "axis Y (gantry joint 2): searched" "$work/out" || fail "the second side's switches were not searched: $(cat "$work/out")"
cc axis Y soft-limits --margin 2 >/dev/null || fail "soft-limits"
racking_pins="cia402-sim.0.node.02.table-position,cia402-sim.0.node.03.table-position"
cc axis Y homing --method controller --repeat 2 --square-pins "$racking_pins" --bring-up "$work/m" > "$work/out" \
  || fail "homing: $(cat "$work/out")"
grep -q "axis Y (gantry joint 2): controller, 2 runs" "$work/out" || fail "the second side was not homed: $(cat "$work/out")"
grep "second side stood" "$work/out" || fail "no squaring: $(cat "$work/out")"
# Each side's HOME_OFFSET is where its home switch is in the squared frame:
# the second 0.3 mm further. The squaring itself is the 0.6 mm the second
# side stood ahead at power-on (the switch searches ran in each side's
# power-on frame).
python3 - "$work/state.json" <<'PY' || fail "the HOME_OFFSETs are not 0.3 mm apart: $(cat "$work/out")"
import json, sys
y = [a for a in json.load(open(sys.argv[1]))["axes"] if a["letter"] == "Y"][0]
sq, h1, h2 = y["gantry"]["squaring"], y["homing"]["home_offset"], y["gantry"]["homing"]["home_offset"]
print(f"squaring {sq:.4f} mm; HOME_OFFSET {h1:.4f} and {h2:.4f} ({h2 - h1:+.4f})")
assert abs(h2 - h1 - 0.3) < 0.05 and abs(sq - 0.6) < 0.05, (sq, h1, h2)
PY

# Step 7 on the pair: homed together, then jogged as Y with both sides
# recorded in every test (never one side at a time).
cc axis Y tune --max-velocity 60 --max-acceleration 1200 --steps 3 --bring-up "$work/m" > "$work/out" \
  || fail "tune: $(cat "$work/out")"
grep -q "homing the machine (the gantry pair's joints 1 and 2 together)" "$work/out" || fail "the pair was not homed before tuning: $(cat "$work/out")"
grep -q "mm/s2: peak following error [0-9.]* / [0-9.]* (each side) mm" "$work/out" || fail "a test did not record both sides: $(cat "$work/out")"
grep "recommended" "$work/out" || fail "no recommendation: $(cat "$work/out")"
ls "$work"/tuning-y/*-second-drive.csv >/dev/null || fail "no record of the second side"
python3 - "$work/state.json" <<'PY' || fail "the pair's tuning was not kept"
import json, sys
y = [a for a in json.load(open(sys.argv[1]))["axes"] if a["letter"] == "Y"][0]
t = y["tuning"]
print(f"Y tuned as a pair: MAX_VELOCITY {t['max_velocity']:.1f}, MAX_ACCELERATION {t['max_acceleration']:.0f}, {len(t['tests'])} tests")
assert 0 < t["max_velocity"] <= 60 and 0 < t["max_acceleration"] <= 1200, t
PY

cc write --dir "$work/m" --name gantry --yes > "$work/out" || fail "write after steps 4-7: $(cat "$work/out")"
[ "$(grep -c '^HOME_SEQUENCE = -1$' "$ini")" = 2 ] || fail "the pair does not home together: $(grep HOME_SEQUENCE "$ini")"
grep -A12 "^\[CIA402_DRIVE_2\]" "$ini" | grep -qx "REVERSE = NO" || fail "the second drive's REVERSE: $(grep -A12 '^\[CIA402_DRIVE_2\]' "$ini")"
cc bring-up --dir "$work/m" --name gantry | grep -q "cncd runs on" || fail "bring-up"
"$bin/cnc" estop-reset && "$bin/cnc" on && "$bin/cnc" home all >/dev/null || fail "on and homed"
sleep 0.3
l0="$(table 2)"; r0="$(table 3)"
"$bin/cnc" mode mdi >/dev/null
"$bin/cnc" mdi "G91 G1 Y4 F300" >/dev/null && "$bin/cnc" mdi "G90" >/dev/null || fail "MDI move"
sleep 0.3
l1="$(table 2)"; r1="$(table 3)"
"$bin/cnc" off >/dev/null
cc shutdown >/dev/null
python3 -c "
l0, r0, l1, r1 = $l0, $r0, $l1, $r1
print(f'homed: the sides stand {r0 - l0:+.4f} mm apart; Y moved 4 mm: the tables moved {l1 - l0:.4f} and {r1 - r0:.4f} mm')
assert abs(r0 - l0) < 0.02, 'not square after homing'
assert abs(l1 - l0 - 4) < 0.02 and abs(r1 - r0 - 4) < 0.02, 'a side did not move 4 mm'" || fail "the gantry is not square or its sides did not move alike"
echo PASS
