#!/bin/sh
# Inside the VM (or a namespace with vcan0): the master (cnc-canopen) and
# two simulated devices (cnc-canopen-node), each its own process, over the
# kernel's SocketCAN. Usage: run_processes.sh NODE_PROGRAM TOOL_PROGRAM
set -u
node_prog="$1"
tool="$2"
here="$(cd "$(dirname "$0")" && pwd)"
eds="$here/../data/echo_device.eds"
failures=0
check() {  # check NAME COMMAND...
  name="$1"; shift
  if "$@"; then echo "ok: $name"; else echo "FAILED: $name"; failures=$((failures + 1)); fi
}

"$node_prog" --interface socketcan:vcan0 --node 5 --eds "$eds" --echo 0x607A:0=0x6064:0 > /tmp/node5.txt 2>&1 &
p5=$!
"$node_prog" --interface socketcan:vcan0 --node 6 --eds "$eds" --echo 0x607A:0=0x6064:0 > /tmp/node6.txt 2>&1 &
p6=$!
sleep 0.5

"$tool" load "$here/vcan.ini"
check "bus-load plan" [ $? -eq 0 ]

"$tool" boot "$here/vcan.ini" --run-s 3 --echo 0x607A:0=0x6064:0 > /tmp/master.txt 2>&1
rc=$?
cat /tmp/master.txt
check "boot two nodes in separate processes and run the cycle with the echo check" [ $rc -eq 0 ]

out="$("$tool" read socketcan:vcan0 5 0x1008:0)"
echo "read 0x1008: $out"
check "SDO read of the device name" sh -c "echo '$out' | grep -q 'Echo device'"
"$tool" write socketcan:vcan0 6 0x2001:0:hex 01 02 03 04 05 06 07 08 09 0a --block
check "SDO block download from the tool" [ $? -eq 0 ]
out="$("$tool" read socketcan:vcan0 6 0x2001:0 --block)"
echo "read 0x2001: $out"
check "SDO block upload gives it back" sh -c "echo '$out' | grep -q '^01 02 03 04 05 06 07 08 09 0A'"
out="$("$tool" read socketcan:vcan0 6 0x3000:0 2>&1)"
echo "$out"
check "abort decoded" sh -c "echo '$out' | grep -q '0x06020000 object does not exist'"

out="$("$tool" boot "$here/vcan-wrong-identity.ini" 2>&1)"
rc=$?
echo "$out"
check "wrong identity stops the start-up" sh -c "[ $rc -ne 0 ] && echo '$out' | grep -q 'start-up stopped: node 5 (x-axis): identity 0x1018:02 product code is 0x00000402, expected 0x00000999'"

out="$("$tool" boot "$here/vcan-missing-node.ini" 2>&1)"
rc=$?
echo "$out"
check "missing node stops the start-up" sh -c "[ $rc -ne 0 ] && echo '$out' | grep -q 'start-up stopped: node 9 (z-axis): not found: no boot-up message within 500 ms'"

# The interface taken down under the running master: reported as such.
"$tool" boot "$here/vcan.ini" --run-s 3 > /tmp/master-down.txt 2>&1 &
pm=$!
sleep 1.5
ip link set vcan0 down
sleep 0.3
ip link set vcan0 up
wait "$pm"
cat /tmp/master-down.txt
check "interface down reported by the master" grep -q "CAN interface socketcan:vcan0 is down: no SYNC, PDO or heartbeat can be sent" /tmp/master-down.txt
check "interface up again reported" grep -q "CAN interface socketcan:vcan0 is up again" /tmp/master-down.txt

kill "$p5" "$p6"
wait "$p5" "$p6"
cat /tmp/node5.txt /tmp/node6.txt
if [ $failures -ne 0 ]; then
  echo "$failures check(s) failed"
  exit 1
fi
echo "all checks passed"
