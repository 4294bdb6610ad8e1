#!/bin/bash
# Regenerates the golden canonical-call files of the interpreter tests.
#
#   programs/*.ngc, errors/*.ngc
#                   -> golden/<dir>/<name>.canon (stdout) and .err
#                      (error text and line, empty when the run succeeds),
#                      produced by LinuxCNC 2.9's stand-alone interpreter
#                      `rs274 -g -t tool.tbl` (apt-get install linuxcnc-uspace;
#                      a development reference only, never a dependency).
#   own/*.ngc       -> own/<name>.canon and own/<name>.err, produced by this
#                      project's cnc-rs274: programs whose output deliberately
#                      differs from LinuxCNC (docs/interpreter.md says why).
#
# Usage: regenerate.sh [BUILD_DIR]   (default: ../../../../build-interp)
# Every run rewrites golden/PRODUCER with the tools and versions used.
# Review every diff (git diff) before committing.
set -eu
HERE="$(cd "$(dirname "$0")" && pwd)"
BUILD="${1:-$HERE/../../../../build-interp}"
CNC="$BUILD/bin/cnc-rs274"
mkdir -p "$HERE/golden"
if command -v rs274 >/dev/null; then
    ver=$(dpkg-query -W -f '${Version}' linuxcnc-uspace 2>/dev/null || echo unknown)
    echo "golden/<dir>/*.canon and *.err: LinuxCNC rs274 -g -t ../tool.tbl (linuxcnc-uspace $ver), run in programs/" > "$HERE/golden/PRODUCER"
    for dir in programs errors; do
        mkdir -p "$HERE/golden/$dir"
        for p in "$HERE"/$dir/*.ngc; do
            n=$(basename "$p" .ngc)
            [ "$n" = filesub ] && continue   # a subroutine file, called by subs.ngc
            out="$HERE/golden/$dir/$n"
            ( cd "$HERE/$dir" && rs274 -g -t ../tool.tbl "$n.ngc" > "$out.canon" 2> "$out.stderr" ) || true
            grep -v '^executing$' "$out.stderr" > "$out.err" || true
            rm -f "$out.stderr"
        done
    done
    # parameter file: start.var -> golden/params/expected.var
    cp "$HERE/params/start.var" "$HERE/golden/params/expected.var"
    ( cd "$HERE/params" && rs274 -g -v ../golden/params/expected.var params.ngc > /dev/null 2>&1 ) || true
else
    echo "rs274 not found (apt-get install linuxcnc-uspace): golden/ left as it is" >&2
fi
if [ -x "$CNC" ]; then
    echo "own/*.canon and *.err: cnc-rs274 -t ../tool.tbl (this project), run in own/" > "$HERE/own/PRODUCER"
    for p in "$HERE"/own/*.ngc; do
        n=$(basename "$p" .ngc)
        args="-t ../tool.tbl"
        [ -f "$HERE/own/$n.args" ] && args=$(cat "$HERE/own/$n.args")   # per-program options
        # shellcheck disable=SC2086
        ( cd "$HERE/own" && "$CNC" $args "$n.ngc" > "$n.canon" 2> "$n.stderr" ) || true
        grep -v '^executing$' "$HERE/own/$n.stderr" > "$HERE/own/$n.err" || true
        rm -f "$HERE/own/$n.stderr"
    done
else
    echo "$CNC not built: own/ left as it is" >&2
fi
