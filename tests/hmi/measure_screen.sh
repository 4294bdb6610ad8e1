#!/usr/bin/env bash
# Measures the operator screen on the simulated mill: start-up time (process
# start to the first frame, and the whole process run with
# --quit-after-startup) and CPU use while idle and while a program runs.
# Not a test (timings are never asserted); run it under a display:
#   xvfb-run -a -s "-screen 0 1280x1024x24" tests/hmi/measure_screen.sh [BUILD_DIR]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="$(cd "${1:-$root/build}" && pwd)"
bin="$build/bin"
run="$(mktemp -d /tmp/cnc-hmi-measure-XXXXXX)"
export CNC_INSTANCE="hmi-measure-$$"
export CNC_NO_REALTIME=1
cp -r "$root/configs/sim" "$run/sim"
"$bin/cncd" "$run/sim/sim.ini" 2>"$run/cncd.log" &
daemon=$!
hmi=""
cleanup() {
  [ -n "$hmi" ] && kill "$hmi" 2>/dev/null || true
  "$bin/cnc" shutdown >/dev/null 2>&1 || kill "$daemon" 2>/dev/null || true
  wait "$daemon" 2>/dev/null || true
  rm -rf "$run"
}
trap cleanup EXIT
"$bin/cnc" wait-ready

echo "== start-up (5 runs): first frame after main(), and the whole process"
for i in 1 2 3 4 5; do
  t0=$(date +%s%N)
  first=$("$bin/cnc-hmi" --quit-after-startup "$run/sim/sim.ini" 2>/dev/null | sed -n 's/.*first frame \([0-9]*\) ms.*/\1/p')
  t1=$(date +%s%N)
  echo "  run $i: first frame ${first} ms after main(); process start to exit $(( (t1 - t0) / 1000000 )) ms"
done

ticks=$(getconf CLK_TCK)
cpu_of() { awk '{print $14 + $15}' "/proc/$1/stat"; }
measure() {  # pid seconds -> percent of one core
  local a b
  a=$(cpu_of "$1"); sleep "$2"; b=$(cpu_of "$1")
  awk -v a="$a" -v b="$b" -v s="$2" -v t="$ticks" 'BEGIN { printf "%.1f", (b - a) * 100 / (t * s) }'
}

"$bin/cnc" estop-reset && "$bin/cnc" on && "$bin/cnc" home all && "$bin/cnc" mode auto
"$bin/cnc" open "$run/sim/nc_files/demo.ngc"
"$bin/cnc-hmi" "$run/sim/sim.ini" >/dev/null 2>&1 &
hmi=$!
sleep 3  # started, preview computed
echo "== CPU of cnc-hmi (percent of one core; CYCLE_TIME from the INI)"
echo "  idle, program loaded:   $(measure "$hmi" 10) %"
"$bin/cnc" run
sleep 1
echo "  program running:        $(measure "$hmi" 20) %   (cncd meanwhile: $(measure "$daemon" 5) %)"
"$bin/cnc" abort >/dev/null || true
