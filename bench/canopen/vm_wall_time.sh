#!/usr/bin/env bash
# Wall time of the virtual-CAN tests (label vm): each boots Debian's kernel
# under qemu (software emulation) or runs in a namespace with vcan.
# usage: bench/canopen/vm_wall_time.sh [BUILD_DIR]   (default: build)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${1:-$root/build}"
cd "$build"
start=$(date +%s.%N)
ctest -L vm --output-on-failure 2>&1 | grep -E "Test +#|tests passed|tests failed|Total Test time" || true
end=$(date +%s.%N)
awk -v s="$start" -v e="$end" -v l="$(cut -d" " -f1-3 /proc/loadavg)" 'BEGIN { printf "vm tests wall time: %.1f s (load average now: %s)\n", e - s, l }'
