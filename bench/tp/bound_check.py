#!/usr/bin/env python3
"""bench_tp's bound_s is a lower bound: no run of our planner, which holds
every limit and the tolerance (bench_tp checks it sample by sample and
prints "ok"), may take less. Runs `bench_tp --quick` under the LC
profile, under a near jerk-free one (J = 10^9, where the corner bound's
caps matter most) and under a slow one, and fails on any row whose bound
is above its time, or that did not run.

  bound_check.py BUILD_DIR
"""
import subprocess
import sys
from pathlib import Path

bench = Path(sys.argv[1]) / "bin" / "bench_tp"
runs = [["--quick"], ["--quick", "--limits", "100,1000,1000000000", "--period", "0.001"],
        ["--quick", "--limits", "50,300,5000", "--period", "0.001"]]
fail, rows = [], 0
for args in runs:
    out = subprocess.run([str(bench), *args], check=True, capture_output=True, text=True).stdout
    table = out.split("== short-segment")[0]
    for line in table.splitlines():
        f = line.split()
        if "ok" not in f and "no" not in f:
            continue
        k = f.index("ok") if "ok" in f else f.index("no")
        if f[k + 1] == "time_s":
            continue  # the header
        rows += 1
        if f[k] != "ok":
            fail.append(f"{' '.join(args)}: did not run to its end: {line}")
            continue
        time_s, bound_s = float(f[k + 1]), float(f[k + 2])
        if bound_s > time_s:
            fail.append(f"{' '.join(args)}: bound {bound_s} s above the run's {time_s} s: {line.strip()}")
for f in fail:
    print("bound_check:", f)
print(f"bound_check: {rows} rows: {'FAIL' if fail or rows < 30 else 'ok'}")
sys.exit(1 if fail or rows < 30 else 0)
