#!/bin/bash
# Differential test: every program LinuxCNC ships (its nc_files, installed by
# Debian's linuxcnc-uspace under /usr/share/linuxcnc/ncfiles) is run by
# LinuxCNC 2.9's stand-alone interpreter `rs274 -g` and by the project's
# cnc-rs274 (under the name rs274, so errors print in LinuxCNC's format),
# once with the project's test tool table and no parameter file, once with a
# second tool table and parameter file (tool2.tbl, params2.var: other tools
# and offsets, G54-G59.3 offsets, G92, G28/G30 homes). The canonical output
# (stdout and stderr) must be identical for every program LinuxCNC runs
# without error; known_differences.tsv lists the exceptions with their
# reasons (docs/interpreter.md, "Differential test over LinuxCNC's nc_files").
#
# Usage: run.sh -r CNC_RS274 [-d NCFILES_DIR] [-k KNOWN_FILE] [-v] [PROGRAM...]
# Exit: 0 as expected, 1 an unexpected difference, 77 LinuxCNC absent (skipped).
set -u
HERE="$(cd "$(dirname "$0")" && pwd)"
NCFILES=/usr/share/linuxcnc/ncfiles
TOOL=""; KNOWN="$HERE/known_differences.tsv"; VERBOSE=0
while getopts "r:d:k:vh" opt; do
    case $opt in
        r) TOOL=$OPTARG ;; d) NCFILES=$OPTARG ;; k) KNOWN=$OPTARG ;; v) VERBOSE=1 ;;
        *) sed -n '2,/^set -u/p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
    esac
done
shift $((OPTIND - 1))
[ -n "$TOOL" ] && [ -x "$TOOL" ] || { echo "run.sh: -r CNC_RS274 (an executable) is required" >&2; exit 2; }
TOOL="$(cd "$(dirname "$TOOL")" && pwd)/$(basename "$TOOL")"
LCNC=$(command -v rs274 || true)
if [ -z "$LCNC" ] || [ ! -d "$NCFILES" ]; then
    echo "SKIPPED: LinuxCNC's rs274 or its nc_files ($NCFILES) are not installed"
    echo "(apt-get install linuxcnc-uspace: a development reference, never a dependency)"
    exit 77
fi
declare -A KNOWN_REASON=()
if [ -f "$KNOWN" ]; then
    while IFS=$'\t' read -r key reason; do
        case "$key" in ''|'#'*) continue ;; esac
        KNOWN_REASON["$key"]="$reason"
    done < "$KNOWN"
fi
WORK=$(mktemp -d /tmp/lcnc-ncfiles.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/bin" "$WORK/a" "$WORK/b"
ln -s "$TOOL" "$WORK/bin/rs274"
export LC_ALL=C
cd "$NCFILES" || exit 2
if [ $# -gt 0 ]; then progs=("$@"); else mapfile -t progs < <(find . -name '*.ngc' | sed 's|^\./||' | sort); fi

# One run: $1 interpreter, $2 program (relative to NCFILES), $3 config, $4 output file.
run_one() {
    local interp=$1 prog=$2 config=$3 out=$4 dir var
    dir=$(mktemp -d "$WORK/run.XXXXXX")
    cp -a "$NCFILES/$(dirname "$prog")/." "$dir/" 2>/dev/null
    local args=(-g)
    if [ "$config" = own ]; then
        args+=(-t "$HERE/../data/tool.tbl")
    else
        cp "$HERE/params2.var" "$dir/params2.var"
        args+=(-t "$HERE/tool2.tbl" -v params2.var)
    fi
    # HOME: LinuxCNC's rs274 keeps its tool data in ~/.tool.mmap, one file
    # for every rs274 of the user; runs at the same time (ctest -j) would
    # read each other's tools
    (cd "$dir" && HOME="$dir" timeout 20 "$interp" "${args[@]}" "$(basename "$prog")" < /dev/null > "$out.stdout" 2> "$out.stderr")
    echo $? > "$out.rc"
    { cat "$out.stdout"; grep -v '^executing$' "$out.stderr"; } > "$out"
    [ "$config" = own ] || cp "$dir/params2.var" "$out.var" 2>/dev/null
    rm -rf "$dir"
}

same=0; differ=0; known=0; not_run=0; unexpected=""
for p in "${progs[@]}"; do
    for config in own second; do
        key="$p $config"
        run_one "$LCNC" "$p" $config "$WORK/a/out"
        if [ "$(cat "$WORK/a/out.rc")" != 0 ]; then
            not_run=$((not_run + 1))
            [ $VERBOSE -eq 1 ] && echo "n/a   $key: LinuxCNC's rs274 exits $(cat "$WORK/a/out.rc"): $(grep -v '^executing$' "$WORK/a/out.stderr" | head -1)"
            continue
        fi
        run_one "$WORK/bin/rs274" "$p" $config "$WORK/b/out"
        ok=0
        cmp -s "$WORK/a/out" "$WORK/b/out" || ok=1
        [ "$(cat "$WORK/b/out.rc")" = 0 ] || ok=1
        if [ $config = second ] && ! cmp -s "$WORK/a/out.var" "$WORK/b/out.var"; then ok=1; fi
        reason="${KNOWN_REASON[$key]:-${KNOWN_REASON[$p]:-}}"
        if [ $ok -eq 0 ]; then
            same=$((same + 1))
            if [ -n "$reason" ]; then echo "XPASS $key: identical but listed ($reason)"; unexpected="$unexpected $p"; fi
        elif [ -n "$reason" ]; then
            known=$((known + 1)); echo "known $key: $reason"
        else
            differ=$((differ + 1)); unexpected="$unexpected $p"; echo "DIFF  $key"
            if [ $VERBOSE -eq 1 ]; then
                diff "$WORK/a/out" "$WORK/b/out" | head -20
                [ $config = second ] && diff "$WORK/a/out.var" "$WORK/b/out.var" | head -5
            fi
        fi
    done
done
echo "SUMMARY: $same identical, $differ differ, $known known differences (listed), $not_run runs LinuxCNC's rs274 refuses (not compared)"
[ -z "$unexpected" ] || { echo "unexpected:$unexpected"; exit 1; }
exit 0
