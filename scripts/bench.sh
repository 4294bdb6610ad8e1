#!/usr/bin/env bash
# Builds the project and runs the benchmarks; each prints its figures
# (medians, percentiles, ratios) and never fails on a timing.
#
#   scripts/bench.sh              every benchmark, short runs
#   scripts/bench.sh rt tp        only the named ones
#   scripts/bench.sh --list       the names
#
# Benchmarks that measure a cycle are pinned to CPU 1 with taskset when the
# machine has two or more CPUs; on a shared machine quote medians and
# ratios, not worst cases. docs/benchmarks.md says what each one measures and
# what it measured here.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$root/build/bin"

pin=()
if [ "$(nproc)" -ge 2 ] && command -v taskset >/dev/null; then pin=(taskset -c 1); fi

names=(rt motion tp interp kinematics canopen comp cia402 ethercat modbus vision)
run_one() {
  case "$1" in
    rt)         "${pin[@]}" "$bin/bench_rt_jitter" 10 1000000 ;;
    motion)     "${pin[@]}" "$bin/bench_motion" 200000
                "${pin[@]}" "$bin/bench_motion" 200000 lookahead ;;
    tp)         "${pin[@]}" "$bin/bench_tp" ;;
    interp)     "$bin/interp_bench" --runs 3 ;;
    kinematics) "${pin[@]}" "$bin/kinematics_bench" 100000 ;;
    canopen)    "$bin/canopen_bus_load" ;;
    comp)       "$bin/comp_bench" ;;
    cia402)     "$bin/cia402_bench" ;;
    ethercat)   "$bin/ethercat_bench" ;;
    modbus)     "$bin/modbus_bench" 4 ;;
    vision)     "$bin/vision_bench" ;;
    *) echo "unknown benchmark '$1' (known: ${names[*]})" >&2; return 2 ;;
  esac
}
binary_of() {
  case "$1" in
    rt) echo bench_rt_jitter ;; motion) echo bench_motion ;; tp) echo bench_tp ;;
    interp) echo interp_bench ;; kinematics) echo kinematics_bench ;;
    canopen) echo canopen_bus_load ;; comp) echo comp_bench ;;
    cia402) echo cia402_bench ;; ethercat) echo ethercat_bench ;;
    modbus) echo modbus_bench ;; vision) echo vision_bench ;;
  esac
}

if [ "${1:-}" = "--list" ]; then printf '%s\n' "${names[@]}"; exit 0; fi
selected=("$@")
[ ${#selected[@]} -eq 0 ] && selected=("${names[@]}")

"$root/scripts/build.sh" >/dev/null
status=0
for n in "${selected[@]}"; do
  b="$(binary_of "$n")"
  if [ -z "$b" ]; then echo "unknown benchmark '$n' (known: ${names[*]})" >&2; exit 2; fi
  if [ ! -x "$bin/$b" ]; then
    if [ $# -gt 0 ]; then echo "== $n: $bin/$b was not built" >&2; status=1; fi
    continue
  fi
  echo
  echo "== $n ($b)"
  run_one "$n" || { echo "== $n: exited with status $?" >&2; status=1; }
done
exit $status
