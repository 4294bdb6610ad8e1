#!/bin/bash
# run.sh -- compares the interface of the project's HAL components with
# LinuxCNC's: loads one instance of each component listed below in
# LinuxCNC's halrun (Debian's linuxcnc-uspace) and in the project's HAL
# (hal_pin_list), and diffs the sorted pins, parameters and functions:
# name, type, direction and initial value.
#
# USAGE  run.sh -p PATH/hal_pin_list [-a allowed.tsv] [-o OUTDIR] [-v]
# EXIT   0 same (or every difference allowed), 1 differences, 2 usage or
#        tool error, 77 skipped: LinuxCNC's halrun is not installed.
#
# allowed.tsv: one allowed difference a line, `SIDE KIND NAME TYPE DIR VALUE`
# where SIDE is lcnc (only LinuxCNC has it) or ours; each field may be a
# shell glob; a TAB then the reason. Lines starting with # are comments.
#
# rtapi_app refuses to run as root: as root, halrun runs as $LCNC_USER
# (default cnc; the test is skipped when that user does not exist).
set -u
HERE="$(cd "$(dirname "$0")" && pwd)"
LIST=""; ALLOWED="$HERE/allowed.tsv"; OUTDIR=""; VERBOSE=0
while getopts "p:a:o:vh" opt; do
    case $opt in
        p) LIST=$OPTARG ;; a) ALLOWED=$OPTARG ;; o) OUTDIR=$OPTARG ;; v) VERBOSE=1 ;;
        *) sed -n '2,/^set -u/p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
    esac
done
[ -x "$LIST" ] || { echo "run.sh: -p: hal_pin_list not executable: '$LIST'" >&2; exit 2; }
if ! command -v halrun >/dev/null 2>&1; then
    echo "SKIP: LinuxCNC's halrun is not installed (apt-get install linuxcnc-uspace)"
    exit 77
fi
RUNAS=()
if [ "$(id -u)" = 0 ]; then
    u="${LCNC_USER:-cnc}"
    if ! id "$u" >/dev/null 2>&1; then
        echo "SKIP: running as root and user '$u' does not exist (rtapi_app refuses root; useradd -m $u)"
        exit 77
    fi
    RUNAS=(runuser -u "$u" --)
fi
[ -n "$OUTDIR" ] || OUTDIR=$(mktemp -d /tmp/lcnc-pin-names.XXXXXX)
mkdir -p "$OUTDIR" && chmod 755 "$OUTDIR" || exit 2

# component | LinuxCNC's loadrt arguments | the project's loadrt arguments
COMPONENTS='
and2|count=1|count=1
or2|count=1|count=1
xor2|count=1|count=1
not|count=1|count=1
mux2|count=1|count=1
mux4|count=1|count=1
select8|count=1|count=1
debounce|cfg=2|cfg=2
toggle|count=1|count=1
edge|count=1|count=1
timedelay|count=1|count=1
limit3|count=1|count=1
scale|count=1|count=1
sum2|count=1|count=1
lowpass|count=1|count=1
ddt|count=1|count=1
estop_latch|count=1|count=1
siggen|num_chan=1|num_chan=1
pid|num_chan=1|num_chan=1
encoder|num_chan=1|num_chan=1
conv_float_s32|count=1|count=1
conv_s32_float|count=1|count=1
conv_bit_s32|count=1|count=1
conv_bit_u32|count=1|count=1
conv_s32_bit|count=1|count=1
conv_u32_bit|count=1|count=1
conv_float_u32|count=1|count=1
conv_u32_float|count=1|count=1
conv_s32_u32|count=1|count=1
conv_u32_s32|count=1|count=1
'
: > "$OUTDIR/lcnc.hal"; : > "$OUTDIR/ours.hal"
while IFS='|' read -r comp largs oargs; do
    [ -n "$comp" ] || continue
    echo "loadrt $comp $largs" >> "$OUTDIR/lcnc.hal"
    echo "loadrt $comp $oargs" >> "$OUTDIR/ours.hal"
done <<< "$COMPONENTS"
printf 'show pin\nshow param\nshow funct\n' >> "$OUTDIR/lcnc.hal"
chmod 644 "$OUTDIR"/*.hal

# LinuxCNC: halcmd's tables -> `pin|param NAME TYPE DIR VALUE`, `funct NAME`
# (u32 values in decimal as the project prints them).
(cd "$OUTDIR" && "${RUNAS[@]}" halrun -f "$OUTDIR/lcnc.hal") > "$OUTDIR/lcnc.raw" 2> "$OUTDIR/lcnc.err"
rc=$?
"${RUNAS[@]}" halrun -U >/dev/null 2>&1
if [ $rc != 0 ]; then echo "run.sh: LinuxCNC's halrun failed (rc=$rc):"; cat "$OUTDIR/lcnc.err"; exit 2; fi
awk '/^Component Pins:/{k="pin";next} /^Parameters:/{k="param";next} /^Exported Functions:/{k="funct";next}
     /^[A-Z][A-Za-z ]*:$/{k="";next}
     k=="pin" || k=="param" { if ($1 ~ /^[0-9]+$/) print k, $5, $2, $3, $4 }
     k=="funct" { if ($1 ~ /^[0-9]+$/) print k, $NF }' "$OUTDIR/lcnc.raw" |
while read -r kind name type dir value; do
    if [ "$type" = u32 ]; then value=$((value)); fi
    echo "$kind $name${type:+ $type $dir $value}"
done | LC_ALL=C sort > "$OUTDIR/lcnc.txt"

"$LIST" "$OUTDIR/ours.hal" > "$OUTDIR/ours.unsorted" 2> "$OUTDIR/ours.err" || {
    echo "run.sh: hal_pin_list failed:"; cat "$OUTDIR/ours.err"; exit 2; }
LC_ALL=C sort "$OUTDIR/ours.unsorted" > "$OUTDIR/ours.txt"

# Differences, each checked against the allow-list.
mapfile -t ALLOW < <(grep -v '^#' "$ALLOWED" 2>/dev/null | grep -v '^[[:space:]]*$' | cut -f1)
{ comm -23 "$OUTDIR/lcnc.txt" "$OUTDIR/ours.txt" | sed 's/^/lcnc /'
  comm -13 "$OUTDIR/lcnc.txt" "$OUTDIR/ours.txt" | sed 's/^/ours /'; } > "$OUTDIR/diff.txt"
bad=0; allowed=0
while read -r line; do
    ok=0
    for pat in "${ALLOW[@]}"; do
        # shellcheck disable=SC2053  # the pattern is a glob on purpose
        if [[ $line == $pat ]]; then ok=1; break; fi
    done
    if [ $ok = 1 ]; then
        allowed=$((allowed + 1)); [ $VERBOSE = 1 ] && echo "allowed: $line"
    else
        bad=$((bad + 1)); echo "DIFF: $line"
    fi
done < "$OUTDIR/diff.txt"
echo "components: $(grep -c . <<< "$COMPONENTS"); LinuxCNC lines: $(wc -l < "$OUTDIR/lcnc.txt"), ours: $(wc -l < "$OUTDIR/ours.txt"); differences: $bad, allowed: $allowed (files in $OUTDIR)"
[ $bad = 0 ]
