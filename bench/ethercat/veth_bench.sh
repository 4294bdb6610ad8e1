#!/bin/sh
# EtherCAT over a veth pair: achieved cycle, frame round trip, missed
# cycles and DC lock offset for 3 and 9 simulated drives at 1 ms and 250 us.
# Creates (and always removes) its own network namespace; needs root.
#
#   bench/ethercat/veth_bench.sh ECAT_SIM CNC_ETHERCAT [SECONDS]
#
# Figures only: nothing here fails on timing. The master spins for the
# reply in this mode (--rtt) to time the round trip; the controller does not.
set -eu
sim=$1
tool=$2
seconds=${3:-10}
ns="cnc-ecat-bench-$$"
simpid=""
out=$(mktemp)
cleanup() {
  if [ -n "$simpid" ]; then kill "$simpid" 2>/dev/null || true; wait "$simpid" 2>/dev/null || true; fi
  ip netns del "$ns" 2>/dev/null || true
  rm -f "$out"
}
trap cleanup EXIT INT TERM
# Two first-time `ip netns add` at once can race on /run/netns: retry.
for _try in 1 2 3 4 5; do ip netns add "$ns" && break; sleep 0.2; done
ip netns exec "$ns" true
ip -n "$ns" link set lo up
ip -n "$ns" link add ecm type veth peer name ecs
ip -n "$ns" link set ecm up
ip -n "$ns" link set ecs up

echo "host: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg), kernel $(uname -r)"
for cycle in 1000 250; do
  for drives in 3 9; do
    ip netns exec "$ns" "$sim" --iface ecs --drives "$drives" --seconds $((seconds + 30)) 2>/dev/null &
    simpid=$!
    sleep 0.3
    echo "=== cycle ${cycle} us, ${drives} drives, ${seconds} s ==="
    ip netns exec "$ns" "$tool" run raw:ecm --cycle-us "$cycle" --seconds "$seconds" --move --rtt --miss-limit 0 \
      >"$out" 2>/dev/null || true
    grep -E "^(achieved|wake-up|frame round|missed|DC lock|largest|OK|FAILED)" "$out" || cat "$out"
    kill "$simpid" 2>/dev/null || true
    wait "$simpid" 2>/dev/null || true
    simpid=""
  done
done
