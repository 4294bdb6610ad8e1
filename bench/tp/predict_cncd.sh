#!/usr/bin/env bash
# Does the benchmark predict what the daemon does on the same
# configuration? Runs PROGRAM through cncd on configs/sim
# (bench/tp/cncd_program.sh: power on, home, auto, run) and through
# bench_tp --ini configs/sim/sim.ini (the same interpreter, task canon,
# limits and planner, offline, from where homing leaves the machine), and
# prints both times, their difference in % and both end positions (machine
# coordinates).
#
#   bench/tp/predict_cncd.sh [--tolerance PCT] [--slack S] PROGRAM.ngc [BUILD_DIR]
#
# Two times of cncd: the servo periods that ran while the program did
# (cycles x period: the planner's motion time, what bench_tp predicts) and
# the controller's program time (wall clock, from run to the program's
# end). Without realtime scheduling (as here) the servo thread misses
# periods when it is late (overruns), and the wall time is longer by them;
# both are printed with the overruns.
#
# Exit status 1 when the end positions differ by more than 1 um, or cncd's
# servo-cycle time differs from the prediction by more than PCT % (default
# 2) plus S seconds (default 0.1: the command round trips around the
# program, a few task and servo cycles at its start and end). The system
# test bench.cncd_takes_the_time_bench_tp_predicts runs it on a short
# program.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
tol=2
slack=0.1
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --tolerance) tol="$2"; shift 2 ;;
    --slack) slack="$2"; shift 2 ;;
    -h | --help) sed -n '2,18p' "$0"; exit 0 ;;
    *) args+=("$1"); shift ;;
  esac
done
prog="${args[0]:?usage: predict_cncd.sh [--tolerance PCT] [--slack S] PROGRAM.ngc [BUILD_DIR]}"
build="${args[1]:-$root/build}"
ini="$root/configs/sim/sim.ini"

bench_out=$("$build/bin/bench_tp" --ini "$ini" --only-ngc --ngc "$prog")
echo "$bench_out"
# "NAME  ini  1000 ok  TIME ..." then "  end position X.. Y.. Z.. (machine), ..."
pred=$(awk '$2 == "ini" && $4 == "ok" { print $5; exit }' <<<"$bench_out")
pend=$(sed -n 's/^  end position X\([^ ]*\) Y\([^ ]*\) Z\([^ ]*\) (machine).*/\1,\2,\3/p' <<<"$bench_out")
if [[ -z "$pred" || -z "$pend" ]]; then
  echo "predict_cncd: bench_tp did not run $prog to its end" >&2
  exit 1
fi

cncd_out=$("$root/bench/tp/cncd_program.sh" "$prog" "$build")
echo "$cncd_out"
result=$(grep '^RESULT ' <<<"$cncd_out")
real=$(sed 's/.* cycles_s=\([^ ]*\).*/\1/' <<<"$result")
wall=$(sed 's/.* program_s=\([^ ]*\).*/\1/' <<<"$result")
over=$(sed 's/.* overruns=\([^ ]*\).*/\1/' <<<"$result")
rend=$(sed 's/.* end=\([^ ]*\).*/\1/' <<<"$result")

python3 - "$pred" "$real" "$pend" "$rend" "$tol" "$slack" "$wall" "$over" <<'PY'
import sys
pred, real = float(sys.argv[1]), float(sys.argv[2])
pend = [float(x) for x in sys.argv[3].split(",")]
rend = [float(x) for x in sys.argv[4].split(",")]
tol, slack = float(sys.argv[5]), float(sys.argv[6])
wall, over = float(sys.argv[7]), int(sys.argv[8])
diff = 100.0 * (real - pred) / pred if pred > 0 else float("inf")
wdiff = 100.0 * (wall - pred) / pred if pred > 0 else float("inf")
print(f"\nprediction (bench_tp --ini):   {pred:.3f} s, end X{pend[0]:.6f} Y{pend[1]:.6f} Z{pend[2]:.6f}")
print(f"cncd, servo cycles x period:  {real:.3f} s, end X{rend[0]:.6f} Y{rend[1]:.6f} Z{rend[2]:.6f}")
print(f"difference: {real - pred:+.3f} s ({diff:+.2f} %)")
print(f"cncd, program time (wall):    {wall:.3f} s ({wdiff:+.2f} % against the prediction; "
      f"{over} servo overruns without realtime scheduling)")
bad = []
if max(abs(a - b) for a, b in zip(pend, rend)) > 1e-3:
    bad.append("the end positions differ")
if abs(real - pred) > tol / 100.0 * pred + slack:
    bad.append(f"the time differs by more than {tol:g} % + {slack:g} s")
if bad:
    print("predict_cncd: " + "; ".join(bad), file=sys.stderr)
    sys.exit(1)
PY
