#!/usr/bin/env bash
# A program moves only the axes it names, whatever moved the machine before:
# on a copy of configs/sim run by cncd and driven by cnc as an operator
# would, the one-axis program `G0 X..` runs after an MDI move, after a jog,
# after a program aborted in the middle of a move and after an E-stop and
# its recovery; each time Y and Z must end where they stood, to the
# micrometre (they used to travel to machine 0 at rapid). Last, the shipped
# Park macro with work offsets set.
#   unnamed_axes_stay.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
# shellcheck source=cncd_on_copy.sh
source "$(dirname "${BASH_SOURCE[0]}")/cncd_on_copy.sh" axes
fail() { echo "FAIL: $*"; echo "--- messages"; cnc messages 2>/dev/null | tail -20 || true; echo "--- log"; tail -30 "$work/cncd.log"; exit 1; }
position() { cnc status --json | python3 -c "import json,sys; p=json.load(sys.stdin)['motion']['position']; print('%.3f %.3f %.3f' % tuple(p[:3]))"; }
# Runs `G0 X$1` (G54, X offset 20) as a program and checks that it ends at
# machine X$1+20 with Y and Z as given.
run_x_only() {
  local x="$1" before="$2" case="$3"
  printf 'G21 G90 G54\nG0 X%s\nM2\n' "$x" > "$work/x_only.ngc"
  cnc mode auto || fail "$case: mode auto"
  cnc open "$work/x_only.ngc" || fail "$case: open"
  cnc run || fail "$case: run"
  cnc --timeout 60 wait-program > "$work/progress.txt" || fail "$case: program: $(tail -3 "$work/progress.txt")"
  local yz="${before#* }"
  local want
  want="$(python3 -c "import sys; print('%.3f' % (float(sys.argv[1]) + 20))" "$x") $yz"  # G54 X20
  local got
  got="$(position)"
  [ "$got" = "$want" ] || fail "$case: the program ended at $got, expected $want (it names only X)"
  echo "ok   $case: ended at $got"
}
cnc --timeout 30 wait-ready || fail "controller did not start"
cnc estop-reset && cnc on || fail "power up"
cnc --timeout 60 home all || fail "home all"
# G54 is not zero: the program's X is a work coordinate.
cnc mode mdi && cnc --timeout 30 mdi G10 L2 P1 X20 Y0 Z0 || fail "G54"

# 1. after an MDI move
cnc --timeout 30 mdi G53 G0 X200 Y150 Z-60 || fail "MDI move"
run_x_only 230 "$(position)" "after an MDI move"

# 2. after a jog (teleop, to an absolute position)
cnc mode manual || fail "manual"
cnc --timeout 30 jog-to z 50 -10 && cnc --timeout 30 jog-to y 50 120 || fail "jog"
for _ in $(seq 100); do [ "$(position | cut -d' ' -f2-)" = "120.000 -10.000" ] && break; sleep 0.1; done
run_x_only 180 "$(position)" "after a jog"

# 3. after a program aborted in the middle of a Y move
printf 'G21 G90\nG53 G1 Y20 F1200\nM2\n' > "$work/long_y.ngc"
cnc mode auto && cnc open "$work/long_y.ngc" && cnc run || fail "long program"
for _ in $(seq 200); do
  y="$(position | cut -d' ' -f2)"
  python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) < 90 else 1)" "$y" && break
  sleep 0.05
done
cnc abort || fail "abort"
sleep 0.5
stopped="$(position)"
python3 -c "import sys; y=float(sys.argv[1]); sys.exit(0 if 20.5 < y < 119.5 else 1)" "$(echo "$stopped" | cut -d' ' -f2)" \
  || fail "the abort did not stop Y in the middle of its move ($stopped)"
run_x_only 150 "$stopped" "after an abort mid-program"

# 4. after an E-stop and its recovery
cnc estop || fail "estop"
cnc estop-reset && cnc on || fail "recovery"
run_x_only 100 "$(position)" "after an E-stop and recovery"

# 5. the shipped Park macro goes to its machine position whatever the work
# offset (G54 is X20 here, G92 added): it moves in machine coordinates.
cnc mode mdi && cnc --timeout 30 mdi G92 X5 Y5 Z5 || fail "G92"
cnc --timeout 60 macro 0 || fail "macro 0 (Park)"
got="$(position)"
[ "$got" = "280.000 180.000 0.000" ] || fail "Park ended at $got, expected machine 280.000 180.000 0.000"
echo "ok   Park with G54 and G92 set: $got"
cnc --timeout 30 mdi G92.1 || fail "G92.1"

cnc shutdown || fail "shutdown"
wait "$daemon" || fail "cncd exited with an error"
daemon=""
echo PASS
