#!/usr/bin/env bash
# Steps 5 and 6 as a script runs them (cnc-commission axis X switches,
# soft-limits, homing with --bring-up) on a one-axis simulated machine
# (cnc-sim-random-machine, seed 1): the switches, latched in the servo
# thread, within a servo cycle of travel at the search speed of the truth
# (read here only to check), soft limits from them, drive homing (method
# 22) 3 times with a spread below 0.01 mm, the keys written.
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

t0=$(date +%s.%N)
cc axis X switches --search 250 --velocity 10 --bring-up "$work/m" > "$work/out" || fail "switches: $(cat "$work/out")"
echo "switch search took $(python3 -c "print(round($(date +%s.%N) - $t0, 1))") s"
grep -q "^progress: 5/5" "$work/out" || fail "no progress lines"
# Each edge where the servo thread latched it: none crossed again slowly.
if grep -q "again at" "$work/out"; then fail "an edge was crossed again slowly: $(cat "$work/out")"; fi
# Within a servo cycle of travel at the search speed (plus an encoder
# count) of where the motor was when the table reached the switch: the
# simulator's switches are at table positions, the table the nut's
# position (nominal + pitch error) -/+ half the backlash moving +/-.
python3 - "$work/state.json" "$work/m/sim-truth.json" "$work/m/sim-machine.ini" "$work/m/commission.ini" <<'PY' || fail "switches not where the truth has them: $(cat "$work/out")"
import json, re, sys
s = json.load(open(sys.argv[1]))["axes"][0]["switches"]
t = json.load(open(sys.argv[2]))["axes"][0]
sim = dict(re.findall(r"^(\w+) = (.*)$", open(sys.argv[3]).read(), re.M))
backlash = float(sim["BACKLASH"])
pitch = [tuple(map(float, w.split(":"))) for w in sim["PITCH_ERROR"].split()]
def pe(x):
    if x <= pitch[0][0]: return pitch[0][1]
    for (x0, e0), (x1, e1) in zip(pitch, pitch[1:]):
        if x <= x1: return e0 + (x - x0) / (x1 - x0) * (e1 - e0)
    return pitch[-1][1]
period = float(re.search(r"^SERVO_PERIOD = (\d+)", open(sys.argv[4]).read(), re.M).group(1)) * 1e-9
tol = s["velocity"] * period + 1 / t["counts_per_mm"]
worst = 0
for name, got, edge in (("neg limit", s["neg_limit"]["position"], t["neg_limit_mm"]),
                        ("pos limit", s["pos_limit"]["position"], t["pos_limit_mm"]),
                        ("home low", s["home"]["position"], t["home_min_mm"]),
                        ("home high", s["home"]["position_high"], t["home_max_mm"])):
    d = -1 if edge < s["start"] else 1  # the direction the search crossed it
    motor = edge + d * backlash / 2 - pe(edge)
    print(f"{name}: found {got:.4f}, table {edge:.4f} ({(got - edge) * 1000:+.1f} um), "
          f"motor side {motor:.4f} ({(got - motor) * 1000:+.1f} um)")
    worst = max(worst, abs(got - motor))
    assert abs(got - motor) <= tol, (name, got, motor, tol)
    assert abs(got - edge) <= tol + backlash / 2 + 0.005, (name, got, edge)
print(f"worst {worst * 1000:.1f} um, allowed {tol * 1000:.1f} um")
assert s["home"]["active_high"] == (not t["switches_active_low"])
PY
cc axis X soft-limits --margin 2 | grep -q "axis X: soft limits" || fail "soft-limits"
cc homing-methods | grep -q "^drive:22 " || fail "homing-methods"
cc axis X homing --method drive:22 --repeat 3 --bring-up "$work/m" > "$work/out" || fail "homing: $(cat "$work/out")"
python3 - "$work/state.json" <<'PY' || fail "homing: $(cat "$work/out")"
import json, sys
h = json.load(open(sys.argv[1]))["axes"][0]["homing"]
assert h["method"] == "drive:22" and len(h["references"]) == 3, h
assert h["spread"] < 0.01, h
print(f"drive homing: references {h['references']}, spread {h['spread'] * 1000:.1f} um")
PY
grep -q "^HOME_METHOD = 22" "$work/m/commission.ini" || fail "no HOME_METHOD written"
grep -q "^net x-home-start joint.0.drive-home-start" "$work/m/commission.hal" || fail "no drive homing handshake"
echo "ok"
