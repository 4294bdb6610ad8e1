#!/usr/bin/env bash
# cncd on configs/sim-modbus: the spindle is a Delta VFD simulated by
# cnc-modbus-sim on Modbus TCP loopback, started by the HAL file.
#  - a program with M3 S12000, cuts, M4 S6000 and M5 runs to its end; while
#    it cuts the VFD reports the commanded speed and at-speed; the first
#    feed move after M3 waits for spindle.0.at-speed (cnc status says so);
#  - the drive panel of `cnc status` lists the VFD;
#  - the VFD simulator killed while the spindle runs: the spindle faults
#    for lost communication, motion is disabled and the message channel
#    says why, naming the VFD.
#   modbus_spindle.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
work="$(mktemp -d /var/tmp/cnc-modbus-test.XXXXXX)"
daemon=""
cleanup() {
  if [ -n "$daemon" ]; then kill "$daemon" 2>/dev/null || true; wait "$daemon" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
cp -r "$config" "$work/cfg"
# A free port of this host's loopback for the simulator.
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
sed -i "s/^PORT = 15020$/PORT = $port/" "$work/cfg/sim-modbus.ini"
export CNC_INSTANCE="modbustest-$$"
export CNC_NO_REALTIME=1
"$bin/cncd" "$work/cfg/sim-modbus.ini" 2>"$work/cncd.log" &
daemon=$!
cnc() { "$bin/cnc" "$@"; }
halcmd() { "$bin/halcmd" "$@"; }
fail() { echo "FAIL: $*"; echo "--- messages"; cnc messages --all 2>/dev/null | tail -20 || true; echo "--- log"; tail -30 "$work/cncd.log"; exit 1; }

cnc --timeout 30 wait-ready || fail "controller did not start"
for _ in $(seq 100); do [ "$(halcmd getp modbus.0.vfd.01.comm-ok)" = "TRUE" ] && break; sleep 0.1; done
[ "$(halcmd getp modbus.0.vfd.01.comm-ok)" = "TRUE" ] || fail "the VFD simulator never answered"
echo "ok   the link talks to the simulated VFD on 127.0.0.1:$port"
cnc estop-reset && cnc on || fail "power up"
cnc --timeout 60 home all || fail "home all"
cnc mode auto || fail "mode auto"
cnc open "$work/cfg/nc_files/spindle.ngc" || fail "open"
cnc run || fail "run"
# G1 Z-1 right after M3 S12000 waits for the VFD's at-speed (netted to
# spindle.0.at-speed): the status says so while the drive ramps up.
seen_wait=""
for _ in $(seq 200); do
  if cnc status | grep "waiting for spindle 0 at speed" >/dev/null; then seen_wait=1; break; fi
  sleep 0.02
done
[ -n "$seen_wait" ] || fail "the feed move after M3 S12000 did not wait for spindle 0 at speed"
echo "ok   G1 after M3 S12000 waits for spindle 0 at speed"
seen_speed=""
for _ in $(seq 300); do
  rpm="$(halcmd getp modbus.0.vfd.01.speed-fb)"
  at="$(halcmd getp modbus.0.vfd.01.at-speed)"
  if python3 -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) - 12000) < 240 else 1)" "$rpm" && [ "$at" = "TRUE" ]; then
    seen_speed="$rpm"
    break
  fi
  sleep 0.05
done
[ -n "$seen_speed" ] || fail "the VFD never reported 12000 rpm at speed during the program"
echo "ok   M3 S12000: the VFD runs at $seen_speed rpm, at-speed"
cnc --timeout 120 wait-program || fail "the program did not end well"
echo "ok   spindle.ngc ran to its end"
[ "$(halcmd getp modbus.0.vfd.01.timeouts)" = "0" ] || fail "timeouts on loopback: $(halcmd getp modbus.0.vfd.01.timeouts)"
cnc status | grep "spindle" >/dev/null || fail "cnc status shows no spindle drive"

# Lost communication while the spindle runs stops motion, with the reason.
cnc mode manual || fail "mode manual"
cnc spindle 6000 || fail "spindle 6000"
for _ in $(seq 100); do [ "$(halcmd getp modbus.0.vfd.01.at-speed)" = "TRUE" ] && break; sleep 0.05; done
sim_pid="$(pgrep -P "$daemon" -x cnc-modbus-sim || true)"
[ -n "$sim_pid" ] || fail "no simulator (a child of cncd) to stop"
kill "$sim_pid"
for _ in $(seq 100); do [ "$(halcmd getp motion.motion-enabled 2>/dev/null || echo x)" = "FALSE" ] && break; sleep 0.05; done
cnc messages --all > "$work/messages.txt" 2>&1 || true
grep -q "spindle 0 amplifier fault" "$work/messages.txt" || fail "no spindle fault message: $(tail -5 "$work/messages.txt")"
grep -Eq "no communication|no complete exchange" "$work/messages.txt" || fail "the fault message does not say the VFD stopped answering: $(tail -5 "$work/messages.txt")"
echo "ok   VFD lost while running: $(grep -m1 'amplifier fault' "$work/messages.txt")"
cnc shutdown || true
wait "$daemon" || true
daemon=""
echo "PASS"
