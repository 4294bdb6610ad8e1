#!/bin/bash
# Runs LinuxCNC's own rs274 regression tests (tests/interp, tests/ccomp,
# tests/oword, tests/m70-m73, tests/remap of LinuxCNC, exported unchanged in
# <checkout>/../shared/suites/linuxcnc-interp-tests/) against an interpreter
# the way LinuxCNC's scripts/runtests does: in each test folder `bash -x
# test.sh > result 2> stderr` (or `./test`), then `checkresult result` when
# the folder has one, else `result` must be byte-identical to `expected`; a
# folder holding `xfail` is expected to fail. The test scripts call `rs274`
# by name: the tool given with -r is put first on PATH under that name.
#
# The suite is GPL reference data: it is copied to a temporary folder for the
# run (the tests write their `result` next to them), never into the project.
#
# Usage: run.sh -r RS274_TOOL [-d SUITE_TESTS_DIR] [-k KNOWN_FILE] [-v] [TEST...]
#   -r  the interpreter to test (the project's cnc-rs274, or LinuxCNC's
#       /usr/bin/rs274 to check the suite itself)
#   -d  the suite's tests folder (default: the f1270d6ed7 export under
#       <checkout>/../shared); absent: prints why and exits 77 (skipped)
#   -k  file of tests that are expected not to pass, one "path<TAB>reason"
#       a line (docs/interpreter.md explains each); such a test that passes
#       is an error too, so the list stays true
#   -v  print result/stderr and the difference of every failing test
#   TEST  test folders relative to the tests folder (default: all)
# Exit: 0 all as expected, 1 an unexpected result, 77 suite absent.
set -u
HERE="$(cd "$(dirname "$0")" && pwd)"
CHECKOUT="$(cd "$HERE/../../../.." && pwd)"
SUITE="$CHECKOUT/../shared/suites/linuxcnc-interp-tests/f1270d6ed7/tests"
TOOL=""; KNOWN=""; VERBOSE=0
while getopts "r:d:k:vh" opt; do
    case $opt in
        r) TOOL=$OPTARG ;; d) SUITE=$OPTARG ;; k) KNOWN=$OPTARG ;; v) VERBOSE=1 ;;
        *) sed -n '2,/^set -u/p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
    esac
done
shift $((OPTIND - 1))
[ -n "$TOOL" ] || { echo "run.sh: -r RS274_TOOL is required" >&2; exit 2; }
[ -x "$TOOL" ] || { echo "run.sh: $TOOL is not an executable" >&2; exit 2; }
TOOL="$(cd "$(dirname "$TOOL")" && pwd)/$(basename "$TOOL")"
if [ ! -d "$SUITE" ]; then
    echo "SKIPPED: LinuxCNC's interpreter test suite is not at $SUITE"
    echo "(it is reference data beside the checkout, ../shared/suites/linuxcnc-interp-tests)"
    exit 77
fi
SUITE="$(cd "$SUITE" && pwd)"

# Tests that are not tests of the stand-alone interpreter: they start the
# whole LinuxCNC (`linuxcnc -r`), compile against its headers and library,
# or run its Python module. runtests would run them; here they are listed
# as not applicable, with the reason, and never run.
not_applicable() {
    local d="$1" f
    f=$(ls "$SUITE/$d"/test.sh "$SUITE/$d"/test 2>/dev/null | head -1)
    if grep -qE '^[^#]*\blinuxcnc -r\b' "$f"; then echo "starts the whole LinuxCNC (linuxcnc -r)"; return 0; fi
    if grep -qE '^[^#]*\bg\+\+ ' "$f"; then echo "compiles a program against LinuxCNC's librs274 and headers"; return 0; fi
    if grep -qE '^[^#]*python3 -mcanon' "$f"; then echo "runs LinuxCNC's Python canon module"; return 0; fi
    return 1
}

declare -A KNOWN_REASON=()
if [ -n "$KNOWN" ]; then
    while IFS=$'\t' read -r path reason; do
        case "$path" in ''|'#'*) continue ;; esac
        KNOWN_REASON["$path"]="$reason"
    done < "$KNOWN"
fi

WORK=$(mktemp -d /tmp/lcnc-interp-suite.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
cp -a "$SUITE/." "$WORK/tests"
mkdir -p "$WORK/bin"
ln -s "$TOOL" "$WORK/bin/rs274"
export PATH="$WORK/bin:$PATH"
export LC_ALL=C LANGUAGES=
# LinuxCNC's rs274 reads its installation's sample tool table when a test
# gives no -t (tools 1, 2, 3 and 99999); cnc-rs274 reads this stand-in.
export CNC_RS274_TOOL_TABLE="$HERE/default_tool.tbl"
unset DISPLAY
# What runtests exports for an installed LinuxCNC (only the plugin tests use it).
export LIBDIR=/usr/lib HEADERS=/usr/include/linuxcnc

cd "$WORK/tests" || exit 2
if [ $# -gt 0 ]; then
    tests=("$@")
else
    mapfile -t tests < <(find . \( -name test.sh -o -name test \) -printf '%h\n' | sed 's|^\./||' | sort)
fi

pass=0; fail=0; xfail=0; known_fail=0; na=0; unexpected_pass=0
failed_names=""
for d in "${tests[@]}"; do
    d="${d%/}"
    if [ ! -d "$d" ]; then echo "run.sh: no test $d" >&2; exit 2; fi
    if why=$(not_applicable "$d"); then
        na=$((na + 1)); echo "n/a   $d: $why"; continue
    fi
    (
        cd "$d" || exit 2
        export TEST_DIR="$PWD"
        if [ -e test.sh ]; then timeout 120 bash -x test.sh > result 2> stderr
        else timeout 120 ./test > result 2> stderr; fi
    )
    rc=$?
    if [ $rc -ne 0 ]; then
        reason="test run exited with $rc"; ok=1
    elif [ -e "$d/checkresult" ]; then
        "$d/checkresult" "$d/result" > "$d/checkresult.out" 2>&1; ok=$?
        reason="checkresult exited with $ok"
    elif [ -f "$d/expected" ]; then
        cmp -s "$d/expected" "$d/result"; ok=$?
        reason="result differed from expected"
    else
        ok=1; reason="neither expected nor checkresult existed"
    fi
    xf=0; [ -f "$d/xfail" ] && xf=1
    known="${KNOWN_REASON[$d]:-}"
    if [ $ok -ne 0 ] && [ $xf -eq 1 ]; then
        xfail=$((xfail + 1)); echo "xfail $d"
    elif [ $ok -ne 0 ] && [ -n "$known" ]; then
        known_fail=$((known_fail + 1)); echo "known $d: $reason ($known)"
    elif [ $ok -ne 0 ]; then
        fail=$((fail + 1)); failed_names="$failed_names $d"; echo "FAIL  $d: $reason"
        if [ $VERBOSE -eq 1 ]; then
            if [ -f "$d/expected" ]; then diff -u "$d/expected" "$d/result" | head -60
            else echo "--- result:"; head -40 "$d/result"; fi
            [ -f "$d/checkresult.out" ] && head -40 "$d/checkresult.out"
            echo "--- stderr:"; grep -v '^+ ' "$d/stderr" | tail -15
        fi
    elif [ -n "$known" ]; then
        unexpected_pass=$((unexpected_pass + 1)); failed_names="$failed_names $d"
        echo "XPASS $d: passes but is listed as known to fail ($known)"
    else
        pass=$((pass + 1)); echo "pass  $d"
    fi
done
run=$((pass + fail + xfail + known_fail + unexpected_pass))
echo "SUMMARY: $run run, $pass passed, $fail failed, $known_fail known failures (listed), $xfail expected failures (xfail), $unexpected_pass listed but passing, $na not applicable"
[ $fail -eq 0 ] && [ $unexpected_pass -eq 0 ] || { echo "unexpected:$failed_names"; exit 1; }
exit 0
