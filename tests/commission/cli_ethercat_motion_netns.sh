#!/usr/bin/env bash
# The commissioning steps that move, on EtherCAT: cnc-commission brings up
# cncd on the configuration of its state (the drives on raw:ecm) inside a
# network namespace of its own, with ecat-sim's two CiA 402 CoE drives on
# the other end of a veth pair (5 mm screws, limit switches at -30 and
# +70 mm, a home switch over 38-42 mm, Y's motor mounted the other way
# round), and runs the direction test with a dial reading that finds a
# wrong lead (4 mm entered for X) and the reversed Y (the script plays the
# dial with what the simulated table moved), the test again (confirmed),
# the switch search over the drives' digital inputs (0x60FD in the
# written TXPDO), the soft limits, the controller's homing repeated, the
# tuning (torque read from 0x6077), the velocity loop's response (0x60FF
# mapped in the RXPDO, the gains over CoE: a higher gain gives a higher
# bandwidth), the write and the check program to its end. Every step's controller runs on the real kernel link; the machine
# is off after each. Needs root (ip netns) and AF_PACKET.
#
#   cli_ethercat_motion_netns.sh BIN_DIR ECAT_SIM SOURCE_DIR
set -eu  # no pipefail: `grep -q` may end a pipe before the writer
bin="$1"
sim="$2"
src="$3"
ns="cnc-comm-ecatm-$$"
work="$(mktemp -d)"
simpid=""
# The controllers run with realtime scheduling (as root; as the netns
# mill test's): the drives' sync-manager watchdog (100 ms) trips on a
# servo thread that a loaded host stalls for longer.
export CNC_INSTANCE="commission-ecatm-$$"
unset CNC_NO_REALTIME
cleanup() {
  "$bin/cnc" shutdown >/dev/null 2>&1 || true
  if [ -n "$simpid" ]; then kill "$simpid" 2>/dev/null || true; wait "$simpid" 2>/dev/null || true; fi
  ip netns del "$ns" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT INT TERM
fail() {
  echo "FAIL: $*"
  [ -f "$work/m/cncd.log" ] && { echo "--- cncd log"; tail -20 "$work/m/cncd.log"; }
  [ -f "$work/m/check-cncd.log" ] && { echo "--- the check's cncd log"; tail -40 "$work/m/check-cncd.log"; }
  [ -f "$work/sim.log" ] && { echo "--- ecat-sim log"; tail -5 "$work/sim.log"; }
  exit 1
}

for _try in 1 2 3 4 5; do ip netns add "$ns" && break; sleep 0.2; done
ip -n "$ns" link set lo up
ip -n "$ns" link add ecm type veth peer name ecs
ip -n "$ns" link set ecm up
ip -n "$ns" link set ecs up
ip netns exec "$ns" "$sim" --iface ecs --drives 2 --seconds 900 --switches -30,38,42,70 --reversed 2 2>"$work/sim.log" &
simpid=$!
sleep 0.3

# cnc-commission inside the namespace (so that the controllers it brings
# up are too); its output in $work/out, shown.
cc() {
  local rc=0
  ip netns exec "$ns" "$bin/cnc-commission" --state "$work/state.json" "$@" >"$work/out" 2>&1 || rc=$?
  echo "\$ cnc-commission $*"
  cat "$work/out"
  return $rc
}
expect() { grep -qF -- "$1" "$work/out" || fail "output lacks: $1"; }
# One number of the state: python expression over `s` (the state's JSON).
state() { python3 -c "import json; s = json.load(open('$work/state.json')); print($1)"; }

mkdir -p "$work/m"
cc scan-ethercat --interface raw:ecm --esi-dir "$src/configs/ethercat-mill/drives" || fail "scan-ethercat"
expect "2 slave(s) on raw:ecm, no problems"
cc axis X assign --slave 1 --joint 0 || fail "assign X"
cc axis Y assign --slave 2 --joint 1 || fail "assign Y"
cc axis X scaling --lead 4 || fail "scaling X"
cc axis Y scaling --lead 5 || fail "scaling Y"
cc axis X limits --min -20 --max 60 --velocity 20 --acceleration 200 || fail "limits X"
cc axis Y limits --min -20 --max 60 --velocity 20 --acceleration 200 || fail "limits Y"
x_counts="$(state "s['axes'][0]['scaling']['counts_per_mm'] if s['axes'][0]['letter'] == 'X' else s['axes'][1]['scaling']['counts_per_mm']")"

# Step 4 on a controller of its own over the kernel link: the first test
# jogs 2 mm; the dial shows 2.5 mm on X (a 5 mm screw, not the 4 mm
# entered) and -2 mm on Y (its motor turns the other way).
cc axis X direction-test --distance 10 --velocity 5 --bring-up "$work/m" || fail "direction-test X"
expect "the machine is off again"
expect "jogged 2 mm, not 10"
grep -q "^INTERFACE = raw:ecm" "$work/m/"*.ini || fail "the brought-up configuration is not on raw:ecm"
cc axis X dial 2.5 || fail "dial X"
cc axis Y direction-test --distance 10 --velocity 5 --bring-up "$work/m" || fail "direction-test Y"
expect "the machine is off again"
cc axis Y dial -2 || fail "dial Y"
python3 - "$work/state.json" "$x_counts" <<'PY' || fail "the dial's corrections are not in the state"
import json, sys
s = json.load(open(sys.argv[1]))
ax = {a["letter"]: a for a in s["axes"]}
nominal = float(sys.argv[2])
x, y = ax["X"]["scaling"], ax["Y"]["scaling"]
# 2 mm commanded moved the table 2.5 mm: 2/2.5 of the counts per mm, the
# 131072 increments per 5 mm turn.
assert abs(x["counts_per_mm"] / (nominal * 2 / 2.5) - 1) < 1e-3, (x, nominal)
assert abs(x["counts_per_mm"] / (131072 / 5) - 1) < 1e-3, x
assert not x["reverse"], x
assert y["reverse"], y
print("X", x["counts_per_mm"], "counts/mm (nominal", nominal, "); Y reversed")
PY
# The second round confirms both (20 mm now that a dial checked them; the
# script's dial: what the corrected machine moves, the distance itself).
cc axis X direction-test --distance 10 --velocity 5 --bring-up "$work/m" || fail "second direction-test X"
expect "the machine is off again"
cc axis X dial 10 || fail "second dial X"
expect "direction right; scale right"
cc axis Y direction-test --distance 10 --velocity 5 --bring-up "$work/m" || fail "second direction-test Y"
cc axis Y dial 10 || fail "second dial Y"
expect "direction right; scale right"
# Step 5: the switches through the drives' inputs, on both sides.
cc axis X switches --search 80 --velocity 2 --bring-up "$work/m" || fail "switches X"
cc axis Y switches --search 80 --velocity 2 --bring-up "$work/m" || fail "switches Y"
python3 - "$work/state.json" <<'PY' || fail "the switches are not where the simulator has them"
import json, sys
ax = {a["letter"]: a for a in json.load(open(sys.argv[1]))["axes"]}
for letter in "XY":
    sw = ax[letter]["switches"]
    def at(name):
        return sw[name]["position"]
    for name, want in (("neg_limit", -30), ("pos_limit", 70), ("home", 38)):
        assert sw[name]["seen"], (letter, name, sw)
        assert abs(at(name) - want) < 0.1, (letter, name, at(name), want)
    print(letter, "switches at", at("neg_limit"), at("home"), at("pos_limit"))
PY
cc axis X soft-limits || fail "soft limits X"
cc axis Y soft-limits || fail "soft limits Y"
# Step 6: the controller's homing on the home switch, 3 times.
cc axis X homing --method controller --repeat 3 --away 2 --bring-up "$work/m" || fail "homing X"
state "abs(s['axes'][0]['homing']['spread']) < 0.01" | grep -qx True || fail "homing X: spread too large"
# Step 7: a short tuning run on the link.
cc axis X tune --max-velocity 40 --max-acceleration 800 --steps 2 --bring-up "$work/m" || fail "tune X"
expect "recommended (margin 20 %): MAX_VELOCITY = "
"$bin/cnc" status >/dev/null 2>&1 && fail "a controller is still running after the tune"
# Step 7's loop response over CoE: the gains read (and --velocity-gain
# written) by this program's own master in PREOP before each response
# controller starts, 0x60FF mapped in X's RXPDO. A step at the drive's
# own gain, a swept sine at a tenth and at a quarter of it (velocity loops
# of about 20 and 50 Hz: the quarter's bandwidth must be the higher), each
# response putting back the gain and the mode it found once its controller
# stopped: the last step reads the drive's own gain again, and the check
# below runs on the drives as the responses left them.
cc axis X response --step --amplitude 4 --bring-up "$work/m" || fail "response X step"
expect "the machine is off again"
expect "step: rise "
grep -q "^RXPDO = 0x6040:0:u16 0x607A:0:s32 0x60B8:0:u16 0x60FF:0:s32" "$work/m/commission-response.ini" ||
  fail "the response configuration does not map 0x60FF in the RXPDO"
kv="$(sed -n 's/^axis X: velocity gain 0x60F9:01 = \([0-9]*\) .*/\1/p' "$work/out")"
[ -n "$kv" ] && [ "$kv" -gt 40 ] || fail "no velocity gain read over CoE"
bandwidth() {  # the printed -3 dB bandwidth, Hz; "above" when none fell below it
  grep -q "^bandwidth (-3 dB): above" "$work/out" && { echo above; return; }
  sed -n 's/^bandwidth (-3 dB): \([0-9.]*\) Hz.*/\1/p' "$work/out"
}
cc axis X response --chirp --amplitude 4 --velocity-gain $((kv / 10)) --bring-up "$work/m" || fail "response X chirp, gain $((kv / 10))"
expect "wrote $((kv / 10)) to 0x60F9:01"
expect "velocity gain 0x60F9:01 = $((kv / 10)) "
expect "put back the velocity gain $kv (0x60F9:01)"
low="$(bandwidth)"
cc axis X response --chirp --amplitude 4 --velocity-gain $((kv / 4)) --bring-up "$work/m" || fail "response X chirp, gain $((kv / 4))"
expect "velocity gain 0x60F9:01 = $((kv / 4)) "
high="$(bandwidth)"
echo "bandwidth at gain $((kv / 10)): $low Hz; at gain $((kv / 4)): $high Hz"
[ -n "$low" ] && [ "$low" != above ] || fail "the low gain's bandwidth is not inside the sweep ($low)"
[ "$high" = above ] || python3 -c "import sys; sys.exit(0 if $high > 1.3 * $low else 1)" ||
  fail "a higher velocity gain did not give a higher bandwidth ($low Hz, then $high Hz)"
expect "put back the velocity gain $kv (0x60F9:01)"
cc axis X response --step --amplitude 4 --bring-up "$work/m" || fail "response X after the gains put back"
expect "velocity gain 0x60F9:01 = $kv "
state "[a for a in s['axes'] if a['letter'] == 'X'][0]['response']['gains']['velocity_gain'] == $kv" | grep -qx True ||
  fail "the response is not kept in the state"
"$bin/cnc" status >/dev/null 2>&1 && fail "a controller is still running after the response"
# Step 9: written and checked on the link.
cc write --dir "$work/m" --name mill --yes || fail "write"
expect "wrote "
grep -q "^\[ETHERCAT\]" "$work/m/mill.ini" || fail "no [ETHERCAT] section in mill.ini"
# The check program's length follows the tuning: X's feed is a quarter of
# its recommended MAX_VELOCITY, which a loaded host's stalls (torque spikes
# that repeat) can leave at 8 mm/s: 2 mm/s, about 121 s of moves. A time
# limit shorter than the moves is refused before cncd starts.
cc check --timeout 10 && fail "check: a time limit shorter than the program was taken"
expect "the check program's moves take "
cc check --timeout 300 || fail "check"
expect "check passed"
state "s['check']['passed']" | grep -qx True || fail "the check is not kept in the state"
echo "PASSED"
