#!/usr/bin/env bash
# One program through the real controller: cncd on a copy of configs/sim
# (no realtime scheduling), power on, home, run PROGRAM in auto mode, and
# print its wall time from `cnc run` to the end of `cnc wait-program`, the
# controller's own program time (task: from run to the program's end), the
# end position (machine coordinates) and the servo thread's figures (cycles, overruns, longest overrun streak,
# execution time max). For the planner's servo-cycle cost under the daemon
# and for comparing the time with what bench_tp predicts (docs/tp.md;
# bench/tp/predict_cncd.sh does both and compares). The last line is
# machine-readable: RESULT program_s=... wall_s=... cycles_s=... overruns=... end=X,Y,Z
#
#   bench/tp/cncd_program.sh PROGRAM.ngc [BUILD_DIR]
#
# The sim's machine envelope is X -1..300, Y -1..200, Z -120..1: a program
# around the origin needs an offset (the script does not add one).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
prog="${1:?usage: cncd_program.sh PROGRAM.ngc [BUILD_DIR]}"
bin="${2:-$root/build}/bin"
config="$root/configs/sim"
prog=$(cd "$(dirname "$prog")" && pwd)/$(basename "$prog")
source "$root/tests/system/cncd_on_copy.sh" tpbench
fail() { echo "cncd_program: $*" >&2; tail -20 "$work/cncd.log" >&2; exit 1; }
cnc --timeout 30 wait-ready || fail "controller did not start"
cnc estop-reset || fail "estop-reset"
cnc on || fail "machine on"
cnc --timeout 120 home all || fail "home all"
cnc mode auto || fail "mode auto"
cnc open "$prog" || fail "open $prog"
before=$(cnc status --json)
t0=$(date +%s.%N)
cnc run || fail "run"
cnc --timeout 3000 wait-program >"$work/progress.txt" || fail "program: $(tail -3 "$work/progress.txt")"
t1=$(date +%s.%N)
after=$(cnc status --json)
/usr/bin/python3 - "$before" "$after" "$t0" "$t1" <<'PY'
import json, sys
b, a = json.loads(sys.argv[1]), json.loads(sys.argv[2])
t0, t1 = float(sys.argv[3]), float(sys.argv[4])
def servo(s):
    return [t for t in s["threads"] if t["name"] == "servo-thread"][0]
sb, sa = servo(b), servo(a)
cycles = sa["cycles"] - sb["cycles"]
over = sa["overruns"] - sb["overruns"]
print(f"program wall time {t1 - t0:.3f} s (from `cnc run` to the end of `cnc wait-program`)")
print(f"servo thread: {cycles} cycles, {over} overruns ({100.0 * over / max(cycles, 1):.2f} %), "
      f"longest streak {sa['longest_streak']}, exec max {sa['exec_max_ns'] / 1e3:.1f} us, "
      f"product exec max {sa['product_exec_max_ns'] / 1e3:.1f} us, "
      f"latency p99.9 {sa['latency_p999_ns'] / 1e3:.1f} us")
end = a["motion"]["position"][:3]
prog_s = a["task"]["program_elapsed_s"]
print(f"program time {prog_s:.3f} s (the controller's, from run to the program's end)")
print("end position", [round(x, 6) for x in end])
# Servo periods that ran while the program did (a few more: the command
# round trips): the motion time as the planner counts it. Without realtime
# scheduling the thread misses periods when it is late, and the wall time
# is longer by them.
cycles_s = cycles * sa["period_ns"] * 1e-9
print(f"servo cycles x period {cycles_s:.3f} s (the planner's time: periods missed by a late thread not counted)")
print(f"RESULT program_s={prog_s:.6f} wall_s={t1 - t0:.6f} cycles_s={cycles_s:.6f} overruns={over} "
      f"end={end[0]:.6f},{end[1]:.6f},{end[2]:.6f}")
PY
cnc shutdown >/dev/null 2>&1 || true
