#!/usr/bin/env bash
# The controller over EtherCAT on a real kernel link: cncd with the test
# mill (mill/: three CiA 402 drives on ethercat.0) in a network namespace
# of its own, ecat-sim with three drives on the other end of a veth pair.
#   mill.sh BIN_DIR program      power up, home, run mill/program.ngc, check the end position
#   mill.sh BIN_DIR cable-break  the cable breaks behind the second drive while
#                                the program runs: E-stop, the message names where
#   mill.sh BIN_DIR in-process   the program on the same mill with the drives
#                                simulated inside cncd (INTERFACE = sim:mill, no
#                                namespace, no root needed)
set -euo pipefail
bin=$1
case_name=$2
here="$(cd "$(dirname "$0")" && pwd)"
ns="cnc-ecat-mill-$$"
work="$(mktemp -d)"
simpid=""
daemon=""
cleanup() {
  if [ -n "$daemon" ]; then kill "$daemon" 2>/dev/null || true; wait "$daemon" 2>/dev/null || true; fi
  if [ -n "$simpid" ]; then kill "$simpid" 2>/dev/null || true; wait "$simpid" 2>/dev/null || true; fi
  ip netns del "$ns" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT INT TERM
fail() {
  echo "FAIL: $*"
  echo "--- controller log"; cat "$work/cncd.log" || true
  echo "--- simulator log"; cat "$work/sim.log" || true
  exit 1
}

cp -r "$here/mill" "$work/mill"
touch "$work/mill/mill.var"
export CNC_INSTANCE="ecatmill-$$"
if [ "$case_name" = in-process ]; then
  # The same machine choosing the in-process simulation: only the bus line
  # of the INI and one loadrt differ.
  sed -i 's|^INTERFACE = raw:ecm|INTERFACE = sim:mill|' "$work/mill/mill.ini"
  sed -i 's|^loadrt ethercat$|loadrt ethercat_sim name=mill drives=3\nloadrt ethercat|' "$work/mill/mill.hal"
  CNC_NO_REALTIME=1 "$bin/cncd" "$work/mill/mill.ini" 2>"$work/cncd.log" &
  daemon=$!
  case_name=program
else
  # Two first-time `ip netns add` at once can race on /run/netns: retry.
  for _try in 1 2 3 4 5; do ip netns add "$ns" && break; sleep 0.2; done
  ip netns exec "$ns" true
  ip -n "$ns" link set lo up
  ip -n "$ns" link add ecm type veth peer name ecs
  ip -n "$ns" link set ecm up
  ip -n "$ns" link set ecs up
  fault=()
  [ "$case_name" = cable-break ] && fault=(--fault break:2 --fault-after-ms 4000)
  ip netns exec "$ns" "$bin/ecat-sim" --iface ecs --drives 3 --seconds 300 "${fault[@]}" 2>"$work/sim.log" &
  simpid=$!
  sleep 0.3
  ip netns exec "$ns" env CNC_INSTANCE="$CNC_INSTANCE" "$bin/cncd" "$work/mill/mill.ini" 2>"$work/cncd.log" &
  daemon=$!
fi
"$bin/cnc" --timeout 30 wait-ready || fail "controller did not start"
"$bin/cnc" estop-reset || fail "estop-reset"
"$bin/cnc" on || fail "machine on"
"$bin/cnc" --timeout 30 home all || fail "home all"
"$bin/cnc" mode auto || fail "mode auto"

case "$case_name" in
  program)
    "$bin/cnc" open "$work/mill/program.ngc" || fail "open"
    "$bin/cnc" run || fail "run"
    "$bin/cnc" --timeout 120 wait-program >"$work/progress.txt" || fail "program: $(tail -3 "$work/progress.txt")"
    json="$("$bin/cnc" status --json)"
    /usr/bin/python3 - "$json" <<'PY' || fail "final state"
import json, sys
s = json.loads(sys.argv[1])
pos = s["motion"]["position"]
for i, (got, want) in enumerate(zip(pos[:3], [12.5, -7.5, 5.0])):
    if abs(got - want) > 1e-6:
        sys.exit(f"axis {i}: final position {got}, expected {want}")
if s["task"]["interp_state"] != "IDLE":
    sys.exit("interpreter not idle")
print("final position ok:", pos[:3])
PY
    if "$bin/cnc" messages | grep " error " >/dev/null; then fail "errors on the message channel: $("$bin/cnc" messages)"; fi
    ;;
  cable-break)
    # A long move; the cable breaks 4 s after the drives reached OP.
    "$bin/cnc" mode mdi || fail "mode mdi"
    "$bin/cnc" mdi "G1 X90 F300" || true
    for _ in $(seq 1 200); do
      if "$bin/cnc" messages 2>/dev/null | grep "link lost after slave 2 (y-axis)" >/dev/null; then break; fi
      sleep 0.1
    done
    msgs="$("$bin/cnc" messages)"
    echo "$msgs" | grep "safe stop" >/dev/null || fail "no safe stop reported: $msgs"
    echo "$msgs" | grep "only 2 of 3 slaves answer: link lost after slave 2 (y-axis)" >/dev/null || fail "break not located: $msgs"
    echo "$msgs" | grep -E "safe stop|E-stop|EMCY" || true
    json="$("$bin/cnc" status --json)"
    /usr/bin/python3 - "$json" <<'PY' || fail "machine still on after the bus fault"
import json, sys
s = json.loads(sys.argv[1])
if s["task"]["state"] not in ("ESTOP", "ESTOP_RESET", "OFF"):
    sys.exit("task state " + s["task"]["state"])
print("machine stopped:", s["task"]["state"])
PY
    ;;
  *) echo "unknown case $case_name"; exit 2 ;;
esac
"$bin/cnc" shutdown || fail "shutdown"
wait "$daemon" || true
daemon=""
echo "PASS: mill $case_name"
