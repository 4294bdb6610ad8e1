#!/usr/bin/env bash
# cnc-commission against a running controller, as a machine builder meets
# it on the simulated mill: cncd on configs/sim offers its simulated CAN
# buses to other processes (INTERFACE = virtual:sim,share), and
# `cnc-commission scan` and `backup` reach the drives inside it as
# unix:/dev/shm/cnc-<instance>.can-sim, as they reach real drives on
# socketcan:can0. The controller keeps running undisturbed; when it stops,
# the socket is gone and the scan says so.
set -eu
bin="$(cd "$1" && pwd)"
cfg="$(cd "$2" && pwd)"
work="$(mktemp -d)"
export CNC_INSTANCE="commission-live-$$" CNC_NO_REALTIME=1
sock="/dev/shm/cnc-$CNC_INSTANCE.can-sim"
trap '"$bin/cnc" shutdown >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; tail -20 "$work/cncd.log"; exit 1; }
cc() { "$bin/cnc-commission" --state "$work/state.json" "$@"; }

( cd "$cfg" && exec "$bin/cncd" sim.ini ) >"$work/cncd.log" 2>&1 &
"$bin/cnc" --timeout 60 wait-ready >/dev/null || fail "cncd did not come up"
[ -S "$sock" ] || fail "no socket $sock"

cc scan --interface "unix:$sock" --eds-dir "$cfg/../canopen-mill/drives" > "$work/scan" || fail "scan: $(cat "$work/scan")"
cat "$work/scan"
grep -q "^node 1: cnc simulated servo drive (x-axis), vendor 0x00000CC1 product 0x00000402" "$work/scan" || fail "node 1 not found"
grep -q "^node 2: cnc simulated servo drive (y-axis)" "$work/scan" || fail "node 2 not found"
grep -q "^2 node(s) on unix:$sock" "$work/scan" || fail "not exactly the two drives of the first bus"
grep -q "131072 increments/rev, EDS servo.eds" "$work/scan" || fail "encoder increments or the EDS not read"

# The spindle bus is offered too: Z (3) and the spindle drive (4).
"$bin/cnc-commission" --state "$work/state2.json" scan --interface "unix:/dev/shm/cnc-$CNC_INSTANCE.can-sim-spindle" > "$work/scan2" || true
grep -q "^node 3: .*(z-axis)" "$work/scan2" || fail "node 3 not found on the second bus: $(cat "$work/scan2")"

cc axis X assign --node 1 --joint 0 >/dev/null
cc axis Y assign --node 2 --joint 1 >/dev/null
cc backup --dir "$work/backup" > "$work/out" || fail "backup: $(cat "$work/out")"
cat "$work/out"
grep -q "^node 1 (axis X): [1-9][0-9]* values" "$work/out" || fail "no values backed up from node 1"
ls "$work/backup"/* >/dev/null 2>&1 || fail "backup wrote nothing"

# The controller ran on undisturbed: both buses operational, no fault.
"$bin/cnc" status > "$work/status" || fail "cnc status"
if grep -Ei "lost|fault|bus-off|timeout|not operational" "$work/cncd.log"; then fail "the scan disturbed the controller"; fi
"$bin/cnc" estop-reset >/dev/null && "$bin/cnc" on >/dev/null || fail "machine on after the scan"

"$bin/cnc" shutdown >/dev/null
for _ in $(seq 50); do [ -e "$sock" ] || break; sleep 0.1; done
[ ! -e "$sock" ] || fail "the socket outlived cncd"
if cc scan --interface "unix:$sock" > "$work/out" 2>&1; then fail "scanned a bus nobody offers"; fi
grep -q "nothing offers a bus at $sock" "$work/out" || fail "no clear error: $(cat "$work/out")"
echo "PASS"
