#!/usr/bin/env bash
# The scope on the product path: cncd on a copy of configs/sim with
# `loadrt scope` sampling in the servo thread; `cnc-scope` captures a jog
# of X (trigger: joint.0.vel-cmd rising through 1 unit/s, 20 % before it)
# into a CSV file, whose rows must show the axis standing before the
# trigger and moving after it, one row per servo cycle; `halcmd watch`
# prints the pins as halmeter would.
#   scope_capture.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
staged="$(mktemp -d /var/tmp/cnc-scope-config.XXXXXX)"
trap 'rm -rf "$staged"' EXIT
cp -r "$config/." "$staged/"
printf '\nloadrt scope samples=2000\naddf scope.sample servo-thread\n' >> "$staged/sim.hal"
config="$staged"
# shellcheck source=cncd_on_copy.sh
source "$(dirname "${BASH_SOURCE[0]}")/cncd_on_copy.sh" scope
trap 'cleanup; rm -rf "$staged"' EXIT
fail() { echo "FAIL: $*"; echo "--- log"; tail -30 "$work/cncd.log"; exit 1; }
cnc --timeout 30 wait-ready || fail "controller did not start"
cnc estop-reset && cnc on || fail "power up"
cnc --timeout 60 home all || fail "home all"
cnc mode manual || fail "manual"
"$bin/cnc-scope" --pins joint.0.pos-fb,joint.0.f-error,joint.0.vel-cmd --trigger joint.0.vel-cmd \
  --edge rising --level 1 --pre 20 --samples 1000 --timeout 30 --csv "$work/jog.csv" &
scope=$!
sleep 1
cnc jog x 20 || fail "jog"
wait "$scope" || fail "cnc-scope"
cnc jog-stop x 2>/dev/null || cnc jog x 0 2>/dev/null || true
python3 - "$work/jog.csv" <<'PY' || fail "the CSV does not show the jog"
import csv, sys
rows = list(csv.reader(open(sys.argv[1])))
assert rows[0] == ["time_s", "joint.0.pos-fb", "joint.0.f-error", "joint.0.vel-cmd"], rows[0]
data = [[float(v) for v in r] for r in rows[1:]]
assert len(data) == 1000, len(data)
t = [r[0] for r in data]
assert abs(t[200]) < 1e-9 and abs(t[201] - 0.001) < 1e-9, (t[199:202])  # the trigger row, 1 ms per row
vel = [r[3] for r in data]
assert all(v < 1 for v in vel[:200]), "no trigger level before the trigger"
assert vel[200] >= 1, vel[200]
assert max(vel) <= 20 + 1e-6 and vel[-1] > 19, vel[-1]
pos = [r[1] for r in data]
assert abs(pos[199] - pos[0]) < 1e-3, "X stood before"
assert pos[-1] - pos[200] > 0.1, (pos[200], pos[-1])
print("ok   the jog captured: %d rows, X %.3f -> %.3f, max |f-error| %.4f" % (len(data), pos[0], pos[-1], max(abs(r[2]) for r in data)))
PY
out="$("$bin/halcmd" watch -n 0.1 -c 3 joint.0.pos-fb x-pos-fb)" || fail "halcmd watch"
[ "$(echo "$out" | wc -l)" = 3 ] || fail "halcmd watch printed: $out"
echo "$out" | grep "^joint.0.pos-fb=[-0-9.]*  x-pos-fb=[-0-9.]*$" >/dev/null || fail "halcmd watch printed: $out"
echo "ok   halcmd watch: $(echo "$out" | tail -1)"
echo "PASS"
