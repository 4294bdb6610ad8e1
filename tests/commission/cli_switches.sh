#!/usr/bin/env bash
# Steps 5 and 6 as a script runs them (cnc-commission axis X switches,
# soft-limits, homing with --bring-up) on a one-axis simulated machine
# (cnc-sim-random-machine, seed 1): the switches within 0.1 mm of the
# truth (read here only to check), soft limits from them, drive homing
# (method 22) 3 times with a spread below 0.05 mm, the keys written.
set -eu
bin="$1"
work="$(mktemp -d)"
trap 'CNC_INSTANCE=$CNC_INSTANCE "$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
export CNC_INSTANCE="commission-sw-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/m/cncd.log" ] && tail -20 "$work/m/cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }
"$bin/cnc-sim-random-machine" --seed 1 --dir "$work/m" --interface "virtual:sw-$$" --nodes 1 >/dev/null
t() { python3 -c "import json;print(json.load(open('$work/m/sim-truth.json'))['axes'][0]['$1'])"; }
[ "$(t motor_reversed)" = "False" ] || fail "seed 1 was drawn with a reversed motor: pick a seed without"
cat > "$work/state.json" <<JSON
{"version": 1, "interface": "virtual:sw-$$", "nodes": [{"node_id": 1, "device_type": 131474, "cia402": true,
 "fault": false, "supported_modes": 928, "encoder_increments": $(t encoder_counts | cut -d. -f1),
 "encoder_motor_revs": 1, "problems": []}], "axes": []}
JSON
cc axis X assign --node 1 --joint 0 >/dev/null
cc axis X scaling --lead "$(t lead_mm)" --gear "$(t gear):1" >/dev/null
cc axis X limits --min -300 --max 300 --velocity 20 --acceleration 200
cc include --ini sim-machine.ini --hal-before-bus sim-machine.hal --hal-after-bus sim-machine-run.hal

# Before the search: soft limits from switches are refused, nothing changes.
before="$(cat "$work/state.json")"
if cc axis X soft-limits 2>"$work/err"; then fail "soft-limits without a switch search"; fi
grep -q "axis X: no switch search yet" "$work/err" || fail "no message: $(cat "$work/err")"
[ "$before" = "$(cat "$work/state.json")" ] || fail "a refused step changed the state"

cc axis X switches --search 250 --velocity 10 --bring-up "$work/m" > "$work/out" || fail "switches: $(cat "$work/out")"
grep -q "^progress: 5/5" "$work/out" || fail "no progress lines"
python3 - "$work/state.json" "$work/m/sim-truth.json" <<'PY' || fail "switches not where the truth has them: $(cat "$work/out")"
import json, sys
s = json.load(open(sys.argv[1]))["axes"][0]["switches"]
t = json.load(open(sys.argv[2]))["axes"][0]
for got, want in ((s["neg_limit"]["position"], t["neg_limit_mm"]), (s["pos_limit"]["position"], t["pos_limit_mm"]),
                  (s["home"]["position"], t["home_min_mm"]), (s["home"]["position_high"], t["home_max_mm"])):
    assert abs(got - want) < 0.1, (got, want)
assert s["home"]["active_high"] == (not t["switches_active_low"])
PY
cc axis X soft-limits --margin 2 | grep -q "axis X: soft limits" || fail "soft-limits"
cc homing-methods | grep -q "^drive:22 " || fail "homing-methods"
cc axis X homing --method drive:22 --repeat 3 --bring-up "$work/m" > "$work/out" || fail "homing: $(cat "$work/out")"
python3 - "$work/state.json" <<'PY' || fail "homing: $(cat "$work/out")"
import json, sys
h = json.load(open(sys.argv[1]))["axes"][0]["homing"]
assert h["method"] == "drive:22" and len(h["references"]) == 3, h
assert h["spread"] < 0.05, h
PY
grep -q "^HOME_METHOD = 22" "$work/m/commission.ini" || fail "no HOME_METHOD written"
grep -q "^net x-home-start joint.0.drive-home-start" "$work/m/commission.hal" || fail "no drive homing handshake"
echo "ok"
