#!/bin/sh
# Inside the VM (or a namespace with vcan0): LSS (CiA 305) over the kernel's
# SocketCAN. One process holds two devices without node-ID and one with
# node-ID 5 (cnc-canopen-node); cnc-commission scans (the devices without
# node-ID are reported), gives them node-IDs by LSS fastscan, scans again
# and reads their serial numbers back over SDO (cnc-canopen). A fastscan
# step waits 40 ms: the emulated VM answers later than a real device.
# Usage: run_lss.sh NODE_PROGRAM TOOL_PROGRAM COMMISSION_PROGRAM
set -u
node_prog="$1"
tool="$2"
commission="$3"
failures=0
check() {  # check NAME COMMAND...
  name="$1"; shift
  if "$@"; then echo "ok: $name"; else echo "FAILED: $name"; failures=$((failures + 1)); fi
}
work="$(mktemp -d)"
cd "$work" || exit 1

"$node_prog" --interface socketcan:vcan0 --node 5 --lss --lss-unconfigured 0x2222 --lss-unconfigured 0x1111 \
  > "$work/nodes.txt" 2>&1 &
pn=$!
sleep 0.5

out="$("$commission" --state "$work/c.json" scan --interface socketcan:vcan0 --last 10 2>&1)"
echo "$out"
check "the scan finds node 5 and reports devices without node-ID" \
  sh -c "echo '$out' | grep -q '^node 5:' && echo '$out' | grep -q 'without node-ID answer LSS'"

out="$("$commission" --state "$work/c.json" lss --interface socketcan:vcan0 --first 5 --window-ms 40 2>&1)"
rc=$?
echo "$out"
check "lss gives the two devices node-IDs 6 and 7 in the order of their serials" \
  sh -c "[ $rc -eq 0 ] && echo '$out' | grep -q 'serial 0x00001111 -> node-ID 6' && echo '$out' | grep -q 'serial 0x00002222 -> node-ID 7'"

sleep 0.2
out="$("$commission" --state "$work/c.json" scan --interface socketcan:vcan0 --last 10 2>&1)"
rc=$?
echo "$out"
check "the next scan finds three nodes and no problem" sh -c "[ $rc -eq 0 ] && echo '$out' | grep -q '^3 node(s)'"
out="$("$tool" read socketcan:vcan0 7 0x1018:4 2>&1)"
echo "node 7 0x1018:4: $out"
check "node 7 is the device with serial 0x2222" sh -c "echo '$out' | grep -qi '0x00002222\|8738'"

kill "$pn"
wait "$pn"
cat "$work/nodes.txt"
check "the devices ended under their new node-IDs" sh -c "grep -q '^node 6:' '$work/nodes.txt' && grep -q '^node 7:' '$work/nodes.txt'"
rm -rf "$work"
if [ $failures -ne 0 ]; then
  echo "$failures check(s) failed"
  exit 1
fi
echo "all checks passed"
