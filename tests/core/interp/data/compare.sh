#!/bin/bash
# Runs LinuxCNC's rs274 and cnc-rs274 on programs (default: programs/*.ngc)
# and prints the differences (development aid; needs linuxcnc-uspace).
HERE="$(cd "$(dirname "$0")" && pwd)"
CNC="${CNC:-$HERE/../../../../build-interp/bin/cnc-rs274}"
TBL="${TBL:-$HERE/tool.tbl}"
[ $# -gt 0 ] || set -- "$HERE"/programs/*.ngc
same=0; differ=0
for p in "$@"; do
    d=$(dirname "$p"); n=$(basename "$p")
    a=$(cd "$d" && rs274 -g -t "$TBL" "$n" 2>&1 | grep -v '^executing$')
    b=$(cd "$d" && "$CNC" -t "$TBL" "$n" 2>&1 | grep -v '^executing$')
    if [ "$a" == "$b" ]; then same=$((same+1)); else differ=$((differ+1)); echo "=== $n"; diff <(echo "$a") <(echo "$b") | head -${LINES_SHOWN:-20}; fi
done
echo "$same same, $differ differ"
