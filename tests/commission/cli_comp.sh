#!/usr/bin/env bash
# Step 8 through cnc-commission as a script (and the wizard) uses it, on a
# simulated one-axis machine (cnc-sim-random-machine, seed 7): the cycle
# program, bad measurement input refused naming file and line with the
# state unchanged, the cycle run on a controller the program brings up
# (the laser: the simulator's table-position pin), Ctrl-C during the cycle
# (machine off, "aborted", state unchanged), the fit installed and written
# with the configuration.
set -eu
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-comp-cli-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/m/cncd.log" ] && tail -20 "$work/m/cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }

"$bin/cnc-sim-random-machine" --seed 7 --dir "$work/m" --interface "virtual:comp-cli-$$" --nodes 1
counts=$(python3 -c "import json;print(int(json.load(open('$work/m/sim-truth.json'))['axes'][0]['encoder_counts']))")
cat > "$work/state.json" <<JSON
{"version": 1, "interface": "virtual:comp-cli-$$", "axes": [],
 "nodes": [{"node_id": 1, "device_type": 131474, "vendor_id": 3265, "product_code": 1026, "name": "drive 1",
            "cia402": true, "fault": false, "supported_modes": 928, "encoder_increments": $counts,
            "encoder_motor_revs": 1, "problems": []}]}
JSON
cc axis X assign --node 1 --joint 0 >/dev/null
cc axis X scaling --lead 5 >/dev/null
# Inside the random machine's limit switches (X: about -30 and +215 mm from
# where it powers up, sim/cia402/random_machine).
cc axis X limits --min -20 --max 80 --velocity 20 --acceleration 200
cc include --ini sim-machine.ini --hal-before-bus sim-machine.hal --hal-after-bus sim-machine-run.hal
# Step 4 first (the dial plays from the simulator's truth): the cycle needs the right scaling.
dial=$(python3 -c "
import json
t = json.load(open('$work/m/sim-truth.json'))['axes'][0]
s = json.load(open('$work/state.json'))['axes'][0]['scaling']
print(2 * s['counts_per_mm'] / t['counts_per_mm'] * (-1 if t['motor_reversed'] else 1))")
# 2 mm: the first test of an unchecked scaling jogs at most that.
cc axis X direction-test --distance 2 --velocity 5 --dial "$dial" --bring-up "$work/m" >/dev/null || fail "direction test"

# The cycle: outside the soft limits refused (usage or problem, nothing saved), then written.
before="$(cat "$work/state.json")"
if cc axis X comp-program --out "$work/x.ngc" --min -25 --max 60 2>"$work/err"; then fail "a cycle beyond the limits"; fi
grep -q "soft limits" "$work/err" || fail "no soft-limit message: $(cat "$work/err")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused cycle changed the state"
cc axis X comp-program --out "$work/x.ngc" --min -15 --max 65 --runs 2 --dwell 0.3 --feed 1200 > "$work/out"
grep -q "^stop 1: X -15.000 moving +, run 1$" "$work/out" || fail "no stop list: $(cat "$work/out")"
grep -q "G53 G1 X" "$work/x.ngc" || fail "no cycle program"
stops=$(grep -c "^stop " "$work/out")

# Measurements by hand: a bad file and a wrong count are refused naming file/line or count.
printf 'target,run,direction,deviation_um\n-15,1,+,1\n-15,1,sideways,1\n' > "$work/bad.csv"
before="$(cat "$work/state.json")"
if cc axis X comp-measurements --csv "$work/bad.csv" 2>"$work/err"; then fail "a bad measurement file"; fi
grep -q "bad.csv:3:" "$work/err" || fail "no file:line: $(cat "$work/err")"
if cc axis X comp-measurements --values 1,2,3 2>"$work/err"; then fail "three values for $stops stops"; fi
grep -q "3 value(s) for the cycle's $stops stops" "$work/err" || fail "no count message: $(cat "$work/err")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "refused measurements changed the state"

# Ctrl-C during the cycle: aborted, machine off, state unchanged.
cc bring-up --dir "$work/m" | grep -q "cncd runs on" || fail "bring-up"
before="$(cat "$work/state.json")"
"$bin/cnc-commission" --state "$work/state.json" axis X comp-run --laser-pin cia402-sim.0.node.01.table-position \
  >"$work/out" 2>&1 &
pid=$!
sleep 4
kill -INT $pid
set +e; wait $pid; rc=$?; set -e
[ $rc -eq 1 ] || fail "aborted cycle: status $rc: $(cat "$work/out")"
grep -q "aborted" "$work/out" || fail "no abort message: $(cat "$work/out")"
grep -q "the drives disabled" "$work/out" || fail "abort did not switch off: $(cat "$work/out")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "the aborted cycle changed the state"
"$bin/cnc" status --json | python3 -c "
import json, sys
s = json.load(sys.stdin)
assert s['task']['state'] != 'ON', s['task']['state']
assert s['task']['interp_state'] == 'IDLE', s['task']['interp_state']
" || fail "the machine is not off and idle after the abort"
cc shutdown

# The whole cycle on a controller of its own, read by the laser pin.
cc axis X comp-run --laser-pin cia402-sim.0.node.01.table-position --bring-up "$work/m" > "$work/out" \
  || fail "comp-run: $(cat "$work/out")"
grep -q "^progress: $stops/$stops " "$work/out" || fail "no progress lines: $(cat "$work/out")"
grep -q "^axis X: A " "$work/out" || fail "no figures: $(cat "$work/out")"
cc axis X comp-fit --install --out-dir "$work/fit" > "$work/out" || fail "comp-fit: $(cat "$work/out")"
grep -q "predicted with the table" "$work/out" || fail "comp-fit: $(cat "$work/out")"
[ -f "$work/fit/X.comp" ] || fail "no table file"
cc write --dir "$work/m" --name mill | grep -q "^+COMP_FILE = mill-x.comp" || fail "no COMP_FILE in the difference"
cc write --dir "$work/m" --name mill --yes > "$work/out" || fail "write --yes: $(cat "$work/out")"
grep -q "wrote .*mill-x.comp" "$work/out" || fail "the table was not written: $(cat "$work/out")"
grep -q "^loadrt screwcomp" "$work/m/mill.hal" || fail "no screwcomp in the HAL file"
echo PASS
