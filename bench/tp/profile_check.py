#!/usr/bin/env python3
"""bench_tp --profile: the profile it writes is the run it reports.

Runs bench_tp on bench/tp/predict_sim.ngc with one profile (custom
limits, 1 ms) and checks the file: one section, a row per servo cycle
whose times step by the period and end where the printed traverse time
ends (within two cycles: the cycles that find the machine at rest), path
speeds within the programmed feed and the limits, and every program line
that moves the machine named in some row.

  profile_check.py BUILD_DIR PROGRAM
"""
import re
import subprocess
import sys
import tempfile
from pathlib import Path

build, program = Path(sys.argv[1]), Path(sys.argv[2])
with tempfile.TemporaryDirectory() as tmp:
    prof = Path(tmp) / "profile.txt"
    out = subprocess.run(
        [str(build / "bin" / "bench_tp"), "--only-ngc", "--ngc", str(program), "--limits", "100,1000,50000",
         "--period", "0.001", "--profile", str(prof)],
        check=True, capture_output=True, text=True).stdout
    row = next(l for l in out.splitlines() if l.startswith(program.name))
    time_s = float(row.split()[4])
    lines = prof.read_text().splitlines()

fail = []
headers = [l for l in lines if l.startswith("#")]
if len(headers) != 1 or f"{program} (custom, 1000 us)" not in headers[0]:
    fail.append(f"expected one section header naming {program} (custom, 1000 us), got {headers}")
rows = [l.split() for l in lines if not l.startswith("#")]
times = [float(r[0]) for r in rows]
speeds = [float(r[1]) for r in rows]
used = {int(r[2]) for r in rows if float(r[1]) > 0}
if any(abs(b - a - 0.001) > 1e-9 for a, b in zip(times, times[1:])):
    fail.append("times do not step by the 1 ms period")
if abs(times[-1] - time_s) > 0.002 + 1e-9:
    fail.append(f"profile ends at {times[-1]} s, bench_tp printed {time_s} s")
if max(speeds) > 100 * 3 ** 0.5 + 1e-6:
    fail.append(f"path speed {max(speeds)} above the axes' limits")
moving = set()
for n, text in enumerate(program.read_text().splitlines(), 1):
    code = re.sub(r"\(.*?\)|;.*", "", text).upper()
    if re.search(r"\bG0*[0123]\b", code) and re.search(r"[XYZ]\s*-?[\d.]", code):
        moving.add(n)
missing = sorted(moving - used)
if missing:
    fail.append(f"lines {missing} move the machine but no cycle names them")
for f in fail:
    print("profile_check:", f)
print(f"profile_check: {len(rows)} cycles, {time_s} s, {len(used)} lines: {'FAIL' if fail else 'ok'}")
sys.exit(1 if fail else 0)
