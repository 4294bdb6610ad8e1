#!/bin/sh
# EtherCAT over a real kernel link: creates its own network namespace with a
# veth pair (ecm = master end, ecs = slave end), runs ecat-sim with three
# CiA 402 drives on ecs and cnc-ethercat on ecm, and checks one case.
# Needs root (ip netns) and AF_PACKET; touches no other interface; the
# namespace is always removed.
#
#   run.sh CASE ECAT_SIM CNC_ETHERCAT
#   CASE: scan | bringup | cable-break | lost-frames | wrong-wkc | refused-state | sdo-abort
#         | exit | interrupt
set -eu
case_name=$1
sim=$2
tool=$3
ns="cnc-ecat-$$"
simpid=""
out=$(mktemp)
simout=$(mktemp)
cleanup() {
  if [ -n "$simpid" ]; then kill "$simpid" 2>/dev/null || true; wait "$simpid" 2>/dev/null || true; fi
  ip netns del "$ns" 2>/dev/null || true
  rm -f "$out" "$simout"
}
trap cleanup EXIT INT TERM

# Two first-time `ip netns add` at once can race on /run/netns: retry.
for _try in 1 2 3 4 5; do ip netns add "$ns" && break; sleep 0.2; done
ip netns exec "$ns" true
ip -n "$ns" link set lo up
ip -n "$ns" link add ecm type veth peer name ecs
ip -n "$ns" link set ecm up
ip -n "$ns" link set ecs up

start_sim() {
  ip netns exec "$ns" "$sim" --iface ecs --drives 3 --seconds 120 "$@" 2>"$simout" &
  simpid=$!
  sleep 0.3
}
master() {
  # Timing is not asserted: a shared CI machine stalls for milliseconds, so
  # the miss limit is generous except where a fault is the point.
  ip netns exec "$ns" "$tool" "$@" >"$out" 2>&1 || { cat "$out"; echo "FAILED: cnc-ethercat $*"; exit 1; }
  cat "$out"
}
expect() {
  grep -qF -- "$1" "$out" || { echo "FAILED: output lacks: $1"; exit 1; }
}
# How the master left the drives, as the simulated slaves saw it: every
# slave's last AL state INIT, every drive out of "operation enabled" (the
# master quick-stops them; a drive at rest passes quick stop active within
# one of the simulator's polls) and not enabled again.
expect_left_safely() {
  sleep 0.5  # the simulator prints changes every 0.5 ms; let it see the last
  cat "$simout"
  for k in 1 2 3; do
    last=$(grep "^ecat-sim: slave $k " "$simout" | tail -n 1)
    case "$last" in *"-> INIT") ;; *) echo "FAILED: slave $k left in: $last"; exit 1 ;; esac
    grep -q "^ecat-sim: drive $k operation enabled -> " "$simout" \
      || { echo "FAILED: drive $k was never enabled and stopped"; exit 1; }
    last=$(grep "^ecat-sim: drive $k " "$simout" | tail -n 1)
    case "$last" in *"-> switch on disabled" | *"-> ready to switch on" | *"-> switched on") ;;
      *) echo "FAILED: drive $k left in: $last"; exit 1 ;; esac
  done
}

case "$case_name" in
  scan)
    start_sim
    master scan raw:ecm
    expect "SLAVE = 1 2 3"
    expect "[ETHERCAT_SLAVE_3]"
    expect "VENDOR_ID = 0x00000CC1"
    expect "RXPDO = 0x6040:0:u16 0x607A:0:s32 0x6060:0:s8"
    master dict raw:ecm 2
    expect "slave 2 (drive-2)"
    expect "0x6040  Controlword"
    expect "  :01  ro  32 bits  type 0x0007  Vendor ID"
    ;;
  bringup)
    start_sim
    master run raw:ecm --cycle-us 1000 --seconds 3 --move --miss-limit 200
    expect "slaves 3, drives 3"
    expect "OK"
    ;;
  cable-break)
    start_sim --fault break:2 --fault-after-ms 1500
    master run raw:ecm --cycle-us 1000 --seconds 30 --move --miss-limit 200 \
      --expect-fault "only 2 of 3 slaves answer: link lost after slave 2 (drive-2)"
    expect "expected fault reported"
    ;;
  lost-frames)
    start_sim --fault drop --fault-after-ms 1500
    master run raw:ecm --cycle-us 1000 --seconds 30 --move --miss-limit 200 --expect-fault "no frame comes back at all"
    expect "200 consecutive cycles without valid process data"
    ;;
  wrong-wkc)
    start_sim --fault wkc --fault-after-ms 1500
    master run raw:ecm --cycle-us 1000 --seconds 30 --move --miss-limit 200 \
      --expect-fault "working counter 8, expected 9"
    expect "200 consecutive cycles without valid process data"
    ;;
  refused-state)
    start_sim --fault refuse:3:SAFEOP
    master run raw:ecm --expect-fault \
      "slave 3 (drive-3): PREOP -> SAFEOP refused: AL status code 0x001A synchronisation error"
    ;;
  sdo-abort)
    start_sim --fault sdo-abort:2:0x1C12
    master run raw:ecm --expect-fault \
      "slave 2 (drive-2): writing 0x1C12:00 = 0x00 (RxPDO assignment cleared) refused: aborted by the slave: 0x06090030"
    ;;
  exit)
    # The end of the time: drives quick-stopped, slaves back to INIT.
    start_sim
    master run raw:ecm --cycle-us 1000 --seconds 2 --move --miss-limit 200
    expect "OK"
    expect_left_safely
    ;;
  interrupt)
    # Ctrl-C in the middle of a run takes the same exit path.
    start_sim
    ip netns exec "$ns" "$tool" run raw:ecm --cycle-us 1000 --seconds 60 --move --miss-limit 200 >"$out" 2>&1 &
    toolpid=$!
    for _i in $(seq 1 150); do
      [ "$(grep -c -- '-> operation enabled' "$simout")" -ge 3 ] && break
      sleep 0.1
    done
    sleep 0.5
    kill -INT "$toolpid"
    rc=0
    wait "$toolpid" || rc=$?
    cat "$out"
    [ "$rc" -eq 0 ] || { echo "FAILED: cnc-ethercat run ended with $rc after Ctrl-C"; exit 1; }
    expect "interrupted: quick stop of the drives, slaves to INIT"
    expect_left_safely
    ;;
  *)
    echo "unknown case $case_name"
    exit 2
    ;;
esac
echo "PASSED: $case_name"
