#!/usr/bin/env bash
# Step 8 with the camera as the measurement source, through cnc-commission
# on a simulated one-axis machine (cnc-sim-random-machine, seed 7): the
# cycle run on a controller the program brings up, each stop read by the
# simulated camera over a glass scale at the simulator's true table
# position (comp-run --camera exec:sim_camera.sh ..., a picture taken by
# cnc-vision-sim at each reading), then the same cycle read by the
# laser pin (that position itself): the camera's deviations agree with the
# laser's at every stop. Bad input: a missing camera named, nothing saved;
# two sources refused.
set -eu
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-camera-cli-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/m/cncd.log" ] && tail -20 "$work/m/cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }
pin=cia402-sim.0.node.01.table-position

"$bin/cnc-sim-random-machine" --seed 7 --dir "$work/m" --interface "virtual:camera-cli-$$" --nodes 1 >/dev/null
counts=$(python3 -c "import json;print(int(json.load(open('$work/m/sim-truth.json'))['axes'][0]['encoder_counts']))")
cat > "$work/state.json" <<JSON
{"version": 1, "interface": "virtual:camera-cli-$$", "axes": [],
 "nodes": [{"node_id": 1, "device_type": 131474, "vendor_id": 3265, "product_code": 1026, "name": "drive 1",
            "cia402": true, "fault": false, "supported_modes": 928, "encoder_increments": $counts,
            "encoder_motor_revs": 1, "problems": []}]}
JSON
cc axis X assign --node 1 --joint 0 >/dev/null
cc axis X scaling --lead 5 >/dev/null
cc axis X limits --min -20 --max 80 --velocity 20 --acceleration 200 >/dev/null
cc include --ini sim-machine.ini --hal-before-bus sim-machine.hal --hal-after-bus sim-machine-run.hal >/dev/null
# Step 4 first (the dial plays from the simulator's truth): the cycle needs the right scaling.
dial=$(python3 -c "
import json
t = json.load(open('$work/m/sim-truth.json'))['axes'][0]
s = json.load(open('$work/state.json'))['axes'][0]['scaling']
print(2 * s['counts_per_mm'] / t['counts_per_mm'] * (-1 if t['motor_reversed'] else 1))")
cc axis X direction-test --distance 2 --velocity 5 --dial "$dial" --bring-up "$work/m" >/dev/null || fail "direction test"
cc axis X comp-program --out "$work/x.ngc" --min -15 --max 65 --targets 5 --runs 2 --dwell 3 --feed 1200 > "$work/out"
stops=$(grep -c "^stop " "$work/out")

# Bad input: two sources refused (usage), a camera that is not there named
# before anything moves; nothing saved.
before="$(cat "$work/state.json")"
camera="exec:$(dirname "$0")/sim_camera.sh $bin $pin"
set +e; cc axis X comp-run --camera "$camera" --laser-pin "$pin" 2>"$work/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "one of --laser-pin, --laser and --camera" "$work/err" || fail "two sources: status $rc: $(cat "$work/err")"
set +e; cc axis X comp-run --camera "$work/no-camera/" --bring-up "$work/m" >"$work/out" 2>"$work/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "no-camera" "$work/err" || fail "a missing camera: status $rc: $(cat "$work/out" "$work/err")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused run changed the state"

# The cycle read by the simulated camera, then by the laser pin.
cc axis X comp-run --camera "$camera" --pitch 0.1 --um-per-px 2.5 --bring-up "$work/m" > "$work/out" \
  || fail "comp-run --camera: $(cat "$work/out")"
grep -q "^progress: $stops/$stops X .* reading " "$work/out" || fail "no progress lines: $(cat "$work/out")"
grep -q "^axis X: A " "$work/out" || fail "no figures: $(cat "$work/out")"
python3 -c "
import json
c = json.load(open('$work/state.json'))['axes'][0]['compensation']
assert c['source'].startswith('camera exec:') and 'on a glass scale' in c['source'], c['source']
json.dump(c['points'], open('$work/camera.json', 'w'))" || fail "the camera's measurement is not in the state"
cc axis X comp-run --laser-pin "$pin" --bring-up "$work/m" > "$work/out" || fail "comp-run --laser-pin: $(cat "$work/out")"
python3 - "$work/state.json" "$work/camera.json" <<'PY' || fail "the camera's deviations differ from the laser's"
import json, sys
laser = json.load(open(sys.argv[1]))["axes"][0]["compensation"]["points"]
camera = json.load(open(sys.argv[2]))
assert len(laser) == len(camera), (len(laser), len(camera))
worst = max(abs(l[3] - c[3]) for l, c in zip(laser, camera))  # [target, run, direction, deviation_um]
span = max(abs(l[3]) for l in laser)
print(f"{len(laser)} stops: camera against laser, worst {worst:.3f} um (deviations up to {span:.1f} um)")
assert worst < 2.0, worst
PY
echo PASS
