#!/usr/bin/env bash
# EtherCAT commissioning from the command line, as a person types it, on
# simulated EtherCAT drives over a real kernel link: its own network
# namespace with a veth pair (ecm = master end, ecs = slave end), ecat-sim
# with two CiA 402 CoE drives on ecs, and cnc-commission on ecm: the
# segment scan (SII identity, ESI match), axes on the slaves, the backup
# over CoE (the factor group 0x608F/0x6091/0x6092 among it), a parameter
# changed in a drive, the restore (dry run first), and the drives read back
# equal to the backup; another drive, a line that does not parse and a
# slave that is not there are refused with nothing written. Needs root (ip
# netns) and AF_PACKET; the namespace is always removed.
#
#   cli_ethercat_netns.sh BIN_DIR ECAT_SIM SOURCE_DIR
set -eu  # no pipefail: `grep -q` may end a pipe before the writer
bin="$1"
sim="$2"
src="$3"
ns="cnc-comm-ecat-$$"
work="$(mktemp -d)"
simpid=""
cleanup() {
  if [ -n "$simpid" ]; then kill "$simpid" 2>/dev/null || true; wait "$simpid" 2>/dev/null || true; fi
  ip netns del "$ns" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT INT TERM
# No controller runs on this instance: restore checks that.
export CNC_INSTANCE="commission-ecat-$$" CNC_NO_REALTIME=1
fail() { echo "FAIL: $*"; [ -f "$work/sim.log" ] && tail -5 "$work/sim.log"; exit 1; }

for _try in 1 2 3 4 5; do ip netns add "$ns" && break; sleep 0.2; done
ip -n "$ns" link set lo up
ip -n "$ns" link add ecm type veth peer name ecs
ip -n "$ns" link set ecm up
ip -n "$ns" link set ecs up
ip netns exec "$ns" "$sim" --iface ecs --drives 2 --seconds 300 2>"$work/sim.log" &
simpid=$!
sleep 0.3

# cnc-commission inside the namespace; its output in $work/out (and shown).
cc() {
  local rc=0
  ip netns exec "$ns" "$bin/cnc-commission" --state "$work/commission.json" "$@" >"$work/out" 2>&1 || rc=$?
  echo "\$ cnc-commission $*"
  cat "$work/out"
  return $rc
}
expect() { grep -qF -- "$1" "$work/out" || fail "output lacks: $1"; }
# ParameterValue of section [$2] in backup file $1.
value() { awk -v s="[$2]" '$0 == s { f = 1; next } /^\[/ { f = 0 } f && /^ParameterValue=/ { sub(/^ParameterValue=/, ""); print; exit }' "$1"; }

# Step 1: the segment.
cc scan-ethercat --interface raw:ecm --esi-dir "$src/configs/ethercat-mill/drives" || fail "scan-ethercat failed"
expect "slave 1: drive-1, vendor 0x00000CC1 product 0x00000402 revision 0x00010000"
expect "slave 2: drive-2,"
expect "CoE"
expect "ESI servo.xml"
expect "2 slave(s) on raw:ecm, no problems"
expect "131072 increments/rev, ESI servo.xml"  # 0x608F read over CoE in PREOP
# Step 2: the axes.
cc axis X assign --slave 1 --joint 0 || fail "assign X"
cc axis Y assign --slave 2 --joint 1 || fail "assign Y"
# Step 3: the scaling takes the encoder resolution and gear from the
# drive (over CoE) as for a CANopen node; only the lead is entered.
cc axis X scaling --lead 5 || fail "scaling X from the drive"
expect "counts/rev from the drive (0x608F over CoE)"

# Step 9's backup over CoE.
cc backup --dir "$work/backup" || fail "backup failed"
expect "EtherCAT slave 1 (axis X):"
expect "EtherCAT slave 2 (axis Y):"
expect "wrote $work/backup/slave-01-x.dcf"
expect "wrote $work/backup/slave-02-y.dcf"
x="$work/backup/slave-01-x.dcf"
grep -qx "EtherCATSlave=1" "$x" || fail "no EtherCATSlave=1 in $x"
# The scaling read over CoE: encoder increments, gear, feed constant.
counts="$(value "$x" 608Fsub1)"
[ -n "$counts" ] && [ $((counts)) -gt 0 ] || fail "no encoder increments (0x608F:1) in the backup: '$counts'"
[ $(($(value "$x" 6091sub1))) -ge 1 ] || fail "no gear ratio (0x6091:1) in the backup"
[ $(($(value "$x" 6092sub1))) -ge 1 ] || fail "no feed constant (0x6092:1) in the backup"
[ "$(value "$x" 1018sub1)" = "0x00000CC1" ] || fail "identity not in the backup"
window="$(value "$x" 6065)"
offset="$(value "$work/backup/slave-02-y.dcf" 607C)"
echo "backup: 0x608F:1 = $counts increments, 0x6065 = $window, 0x607C (Y) = $offset"

# A parameter changed in the drives: someone's files with other values
# restored into them (X's following-error window, Y's home offset).
mkdir -p "$work/other"
sed '/^\[6065\]$/,/^ParameterValue=/ s/^ParameterValue=.*/ParameterValue=0x00001234/' "$x" >"$work/other/slave-01-x.dcf"
sed '/^\[607C\]$/,/^ParameterValue=/ s/^ParameterValue=.*/ParameterValue=-777/' "$work/backup/slave-02-y.dcf" \
  >"$work/other/slave-02-y.dcf"
cc restore --dir "$work/other" || fail "restoring the changed files failed"
expect "wrote 0x6065:00 Following error window = 0x00001234 (was $window), read back 0x00001234"
expect "wrote 0x607C:00 Home offset = -777 (was $offset), read back -777"

# The restore of the backup (the state's last one), a dry run first.
cc restore --dry-run || fail "restore --dry-run failed"
expect "EtherCAT slave 1 (axis X, slave-01-x.dcf): 1 parameter(s) differ from the backup"
expect "would write 0x6065:00 Following error window: 0x00001234 -> $window"
expect "would write 0x607C:00 Home offset: -777 -> $offset"
expect "dry run: nothing written"
cc restore --dry-run >/dev/null
expect "would write 0x6065:00"  # still: the dry run wrote nothing
cc restore || fail "restore failed"
expect "wrote 0x6065:00 Following error window = $window (was 0x00001234), read back $window"
expect "wrote 0x607C:00 Home offset = $offset (was -777), read back $offset"
expect "restored 2 parameter(s) to 2 drive(s)"
# Read back: every parameter as in the backup, and a new backup has them.
cc restore --dry-run || fail "restore --dry-run after the restore failed"
expect "EtherCAT slave 1 (axis X, slave-01-x.dcf): every parameter as in the backup"
expect "EtherCAT slave 2 (axis Y, slave-02-y.dcf): every parameter as in the backup"
cc backup --dir "$work/again" || fail "the second backup failed"
[ "$(value "$work/again/slave-01-x.dcf" 6065)" = "$window" ] || fail "0x6065 reads $(value "$work/again/slave-01-x.dcf" 6065), backup $window"
[ "$(value "$work/again/slave-02-y.dcf" 607C)" = "$offset" ] || fail "0x607C reads back wrong"

# Bad input: nothing written (the dry run afterwards still finds every
# parameter as in the backup, X's window in particular).
mkdir -p "$work/bad"
sed '/^\[1018sub2\]$/,/^ParameterValue=/ s/^ParameterValue=.*/ParameterValue=0x00000999/' "$work/other/slave-01-x.dcf" \
  >"$work/bad/another.dcf"
if cc restore --file "$work/bad/another.dcf"; then fail "a backup of another drive was restored"; fi
expect "problem: EtherCAT slave 1 (axis X, another.dcf) is another drive: vendor 0x00000CC1 product 0x00000402"
expect "nothing was written"
awk 'NR == 12 { print "garbage" } { print }' "$work/other/slave-01-x.dcf" >"$work/bad/garbage.dcf"
if cc restore --file "$work/bad/garbage.dcf"; then fail "a file with a bad line was restored"; fi
expect "problem: $work/bad/garbage.dcf:12: \"garbage\": expected KEY=VALUE or a [section]; nothing was written"
sed 's/^EtherCATSlave=1$/EtherCATSlave=5/' "$work/other/slave-01-x.dcf" >"$work/bad/slave-05.dcf"
if cc restore --file "$work/other/slave-02-y.dcf" --file "$work/bad/slave-05.dcf"; then fail "a missing slave was restored"; fi
expect "problem: EtherCAT slave 5 (axis X, slave-05.dcf) does not answer"
expect "not written: 0x607C:00 Home offset: $offset -> -777"
if cc restore --file "$work/bad/none.dcf"; then fail "a missing file was restored"; fi
expect "problem: $work/bad/none.dcf: cannot be read (no such file?); nothing was written"
cc restore --dry-run || fail "restore --dry-run after bad input failed"
expect "EtherCAT slave 1 (axis X, slave-01-x.dcf): every parameter as in the backup"
expect "EtherCAT slave 2 (axis Y, slave-02-y.dcf): every parameter as in the backup"
echo "PASSED"
