#!/usr/bin/env bash
# cnc-commission as a script uses it: a state with the nodes a scan found
# (written here: the simulated drives live inside cncd, out of this
# process's reach), axes, scaling, the configuration's difference and
# writing, bad input refused with nothing written, and the direction test
# with --bring-up and on a controller brought up by the program, on a
# simulated machine (cnc-sim-random-machine, seed 7) whose truth the
# script reads only to play the dial indicator.
set -eu  # no pipefail: `grep -q` may end a pipe before the writer
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-cli-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/m/cncd.log" ] && tail -20 "$work/m/cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }

"$bin/cnc-sim-random-machine" --seed 7 --dir "$work/m" --interface "virtual:cli-$$" --nodes 1
node() {
  cat <<JSON
{"node_id": $1, "device_type": 131474, "vendor_id": 3265, "product_code": 1026, "name": "drive $1",
 "cia402": true, "fault": $2, "supported_modes": 928, "encoder_increments": $(python3 -c "import json;print(int(json.load(open('$work/m/sim-truth.json'))['axes'][0]['encoder_counts']))"),
 "encoder_motor_revs": 1, "problems": []}
JSON
}
cat > "$work/state.json" <<JSON
{"version": 1, "interface": "virtual:cli-$$", "nodes": [$(node 1 false), $(node 2 true)], "axes": []}
JSON

# Bad input: nothing changes in the state.
before="$(cat "$work/state.json")"
# Any command's --help prints the commands and exits 0, reading nothing.
cc check --help | grep -q '^  check \[--program FILE\]' || fail "check --help does not print the help"
cc axis X direction-test --help >/dev/null || fail "axis X direction-test --help exited $?"
if cc axis X assign --node 2 2>"$work/err"; then fail "a drive in fault was assigned"; fi
grep -q "is in fault" "$work/err" || fail "no fault message: $(cat "$work/err")"
if cc axis X assign --node 9 2>"$work/err"; then fail "an unknown node was assigned"; fi
grep -q "was not found by the bus scan" "$work/err" || fail "no unknown-node message"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused step changed the state"
set +e; cc scan >/dev/null 2>&1; rc=$?; set -e
[ $rc -eq 1 ] || [ $rc -eq 2 ] || fail "scan without a reachable bus: status $rc"

cc axis X assign --node 1 --joint 0 | grep "axis X: node 1 on joint 0" >/dev/null || fail "assign"
cc axis X scaling --lead 5 | grep "counts/mm" >/dev/null || fail "scaling"
# Inside the random machine's limit switches (X: about -30 and +215 mm
# from where it powers up): tune and check move up to these limits.
cc axis X limits --min -20 --max 50 --velocity 10 --acceleration 100
cc include --ini sim-machine.ini --hal-before-bus sim-machine.hal --hal-after-bus sim-machine-run.hal
cc show | grep "axis X: joint 0, node 1" >/dev/null || fail "show"

# write: a dry run shows the files and writes nothing; --yes writes and checks.
cc write --dir "$work/m" --name mill | grep "^+\[CIA402_DRIVE_0\]" >/dev/null || fail "no difference shown"
[ ! -f "$work/m/mill.ini" ] || fail "the dry run wrote"
cc write --dir "$work/m" --name mill --yes > "$work/out" || fail "write --yes: $(cat "$work/out")"; grep -q "wrote .*mill.ini" "$work/out" || fail "write --yes: $(cat "$work/out")"
cc write --dir "$work/m" --name mill --yes >/dev/null
[ ! -f "$work/m/mill.ini.bak" ] || fail "an unchanged file was backed up"

# The direction test on a controller of its own, then with a dial reading.
cc axis X direction-test --distance 10 --velocity 5 --bring-up "$work/m" > "$work/out" || fail "direction-test --bring-up"
grep -q "the machine is off again" "$work/out" || fail "direction-test --bring-up: $(cat "$work/out")"
grep -q "jogged 2 mm, not 10: no dial reading has checked the scaling yet" "$work/out" \
  || fail "the first test was not limited to 2 mm: $(cat "$work/out")"
cc bring-up --dir "$work/m" | grep "cncd runs on" >/dev/null || fail "bring-up"
pin=cia402-sim.0.node.01.table-position
# Ctrl-C during a test move: stopped, the machine off (motion and drive
# disabled), the step says so and changes nothing. (No dial reading has
# checked the scaling yet: the test jogs at most 2 mm, slowly here.)
before="$(cat "$work/state.json")"
"$bin/cnc-commission" --state "$work/state.json" axis X direction-test --distance 20 --velocity 0.25 >"$work/out" 2>&1 &
pid=$!
sleep 3
kill -INT $pid
set +e; wait $pid; rc=$?; set -e
[ $rc -eq 1 ] || fail "aborted test: status $rc: $(cat "$work/out")"
grep -q "aborted" "$work/out" || fail "no abort message: $(cat "$work/out")"
grep -q "the drives disabled" "$work/out" || fail "abort did not switch off: $(cat "$work/out")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "the aborted test changed the state"
"$bin/cnc" status --json | python3 -c "
import json, sys
s = json.load(sys.stdin)
assert not s['motion']['enabled'], 'motion still enabled'
assert s['task']['state'] != 'ON', s['task']['state']
" || fail "the machine is not off after the abort"
[ "$("$bin/halcmd" getp cia402.0.drive.00.enabled)" = "FALSE" ] || fail "the drive is still enabled"
# Hold-to-run (--hold) on a terminal: the key held for 1.5 s of an 8 s jog,
# then let go: the jog stops as Ctrl-C stops it, nothing is saved.
hold="$(dirname "$0")/hold_key.py"
set +e
python3 "$hold" 1.5 "$bin/cnc-commission" --state "$work/state.json" axis X direction-test --distance 20 --velocity 0.25 --hold >"$work/out" 2>&1
rc=$?; set -e
[ $rc -eq 1 ] || fail "hold-to-run let go: status $rc: $(cat "$work/out")"
grep -q "the test move was aborted" "$work/out" || fail "hold-to-run let go: no abort message: $(cat "$work/out")"
grep -q "the drives disabled" "$work/out" || fail "hold-to-run let go: not switched off: $(cat "$work/out")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "the let-go test changed the state"
[ "$("$bin/halcmd" getp cia402.0.drive.00.enabled)" = "FALSE" ] || fail "the drive is still enabled after hold-to-run"
# Held to the end: the jog runs its 2 mm and the test is saved.
python3 "$hold" all "$bin/cnc-commission" --state "$work/state.json" axis X direction-test --distance 2 --velocity 5 --hold >"$work/out" 2>&1 \
  || fail "hold-to-run held: $(cat "$work/out")"
grep -q "commanded 2 mm" "$work/out" || fail "hold-to-run held: $(cat "$work/out")"
# Not on a terminal: refused before anything moves.
set +e
cc axis X direction-test --distance 2 --velocity 5 --hold </dev/null >"$work/out" 2>&1
rc=$?; set -e
[ $rc -ne 0 ] && grep -q "needs a terminal" "$work/out" || fail "--hold without a terminal: status $rc: $(cat "$work/out")"
t0="$("$bin/halcmd" getp $pin)"
cc axis X direction-test --distance 10 --velocity 5 >/dev/null || fail "direction-test"
sleep 0.2
t1="$("$bin/halcmd" getp $pin)"
dial="$(python3 -c "print($t1 - $t0)")"
cc axis X dial "$dial" | tee "$work/verdict"
cc shutdown
python3 - "$work/state.json" "$work/m/sim-truth.json" <<'PY' || fail "scaling or direction not found"
import json, sys
s = json.load(open(sys.argv[1]))
t = json.load(open(sys.argv[2]))["axes"][0]
sc = s["axes"][0]["scaling"]
assert sc["reverse"] == t["motor_reversed"], (sc, t)
assert abs(sc["counts_per_mm"] / t["counts_per_mm"] - 1) < 0.005, (sc, t)
print("found", sc["counts_per_mm"], "counts/mm, reverse", sc["reverse"], "; truth", t)
PY
# Step 7, tuning: bad input is refused with the reason and changes nothing;
# Ctrl-C during the tests switches off and changes nothing; a short run
# with --bring-up records CSVs and stores the recommendation.
before="$(cat "$work/state.json")"
set +e; cc axis X tune --margin 5 2>"$work/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "margin" "$work/err" || fail "tune --margin 5: status $rc: $(cat "$work/err")"
set +e; cc axis Q tune 2>"$work/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "axis Q has no drive" "$work/err" || fail "tune of a missing axis: status $rc: $(cat "$work/err")"
set +e; cc axis X tune --max-velocity -3 2>"$work/err"; rc=$?; set -e
[ $rc -eq 2 ] || fail "tune --max-velocity -3: status $rc"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused tune changed the state"
cc bring-up --dir "$work/m" >/dev/null || fail "bring-up for the tune abort"
before="$(cat "$work/state.json")"
"$bin/cnc-commission" --state "$work/state.json" axis X tune --max-velocity 10 --max-acceleration 100 \
  --record "$work/tune-abort" >"$work/out" 2>&1 &
pid=$!
sleep 4
kill -INT $pid
set +e; wait $pid; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "aborted" "$work/out" || fail "aborted tune: status $rc: $(cat "$work/out")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "the aborted tune changed the state"
[ "$("$bin/halcmd" getp cia402.0.drive.00.enabled)" = "FALSE" ] || fail "the drive is still enabled after the aborted tune"
cc shutdown
cc axis X tune --max-velocity 60 --max-acceleration 1200 --steps 3 --record "$work/tune" --bring-up "$work/m" \
  > "$work/out" || fail "tune: $(cat "$work/out")"
grep -q "^progress: 1/" "$work/out" || fail "tune: no progress lines: $(cat "$work/out")"
grep -q "^recommended (margin 20 %): MAX_VELOCITY = " "$work/out" || fail "tune: no recommendation: $(cat "$work/out")"
head -1 "$(ls "$work"/tune/x-01-*.csv)" | grep -qx "time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct" \
  || fail "tune: no CSV record"
cc show | grep -q "tuning: MAX_VELOCITY" || fail "show: no tuning"
cat "$work/out"

# The configuration written again: the old one kept.
cc write --dir "$work/m" --name mill --yes >/dev/null || fail "final write"
[ -f "$work/m/mill.ini.bak" ] || fail "no backup of the changed file"
grep -q "^G53 G1 X-16.5 F" "$work/m/check.ngc" || fail "check program: $(cat "$work/m/check.ngc")"

# Step 9's check on the written configuration: Ctrl-C while its program
# runs (machine off, aborted, state unchanged), then a whole run, kept in
# the state.
before="$(cat "$work/state.json")"
"$bin/cnc-commission" --state "$work/state.json" check >"$work/out" 2>&1 &
pid=$!
for i in $(seq 1 600); do grep -q "^progress: 4/7" "$work/out" && break; sleep 0.1; done
sleep 1
kill -INT $pid
set +e; wait $pid; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "aborted" "$work/out" || fail "aborted check: status $rc: $(cat "$work/out")"
grep -q "the drives disabled" "$work/out" || fail "the aborted check did not switch off: $(cat "$work/out")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "the aborted check changed the state"
cc check > "$work/out" || fail "check: $(cat "$work/out")"
grep -q "^progress: 7/7 cncd stopped" "$work/out" && grep -q "^check passed: .*ending at X0 as declared" "$work/out" \
  || fail "check: $(cat "$work/out")"
python3 - "$work/state.json" "$work/m/check.ngc" <<'PY' || fail "no check in the state"
import json, sys
c = json.load(open(sys.argv[1]))["check"]
assert c["passed"] and c["program"] == sys.argv[2] and c["duration_s"] > 0, c
PY
echo PASS
