#!/usr/bin/env bash
# halui started by [HAL]HALUI = halui (as LinuxCNC's launcher does), not by
# a HAL file, on a copy of configs/sim; the pins beyond the first set are
# played with `halcmd setp` and the controller must follow: flood, mist and
# lube on/off with their is-on pins, the spindle started and stepped up and
# down (halui.spindle.0.increase/decrease, runs-forward), the tool number,
# a joint jog (halui.joint.N.plus at halui.joint.jog-speed), abort.
#   halui_ini_panel.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
staged="$(mktemp -d /var/tmp/cnc-halui-ini-config.XXXXXX)"
trap 'rm -rf "$staged"' EXIT
cp -r "$config/." "$staged/"
# [HAL]HALUI in the [HAL] section: insert it after the section's header.
sed -i 's/^\[HAL\]$/[HAL]\nHALUI = halui/' "$staged/sim.ini"
grep -q '^HALUI = halui$' "$staged/sim.ini"
config="$staged"
# shellcheck source=cncd_on_copy.sh
source "$(dirname "${BASH_SOURCE[0]}")/cncd_on_copy.sh" haluiini
trap 'cleanup; rm -rf "$staged"' EXIT
halcmd() { "$bin/halcmd" "$@"; }
fail() { echo "FAIL: $*"; echo "--- messages"; cnc messages 2>/dev/null | tail -20 || true; echo "--- log"; tail -30 "$work/cncd.log"; exit 1; }
field() { cnc status --json | python3 -c "import json,sys; s=json.load(sys.stdin); print(eval(sys.argv[1], {'s': s}))" "$1"; }
wait_for() {
  local got=""
  for _ in $(seq 200); do
    got="$(field "$1")"
    [ "$got" = "$2" ] && { echo "ok   $3 ($1 = $got)"; return 0; }
    sleep 0.1
  done
  fail "$3: $1 is $got, expected $2"
}
wait_pin() {
  local got=""
  for _ in $(seq 100); do
    got="$(halcmd getp "$1")"
    [ "$got" = "$2" ] && { echo "ok   $1 = $got"; return 0; }
    sleep 0.1
  done
  fail "$1 is $got, expected $2"
}
press() { halcmd setp "$1" 1 && sleep 0.1 && halcmd setp "$1" 0 && sleep 0.05; }

cnc --timeout 30 wait-ready || fail "controller did not start"
halcmd getp halui.flood.on >/dev/null || fail "[HAL]HALUI = halui did not load halui"
press halui.estop.reset
press halui.machine.on
wait_for "s['task']['state']" "ON" "machine on"
press halui.flood.on
wait_for "s['io']['flood']" "True" "flood on from halui.flood.on"
wait_pin halui.flood.is-on TRUE
press halui.flood.off
wait_for "s['io']['flood']" "False" "flood off from halui.flood.off"
press halui.mist.on
wait_for "s['io']['mist']" "True" "mist on from halui.mist.on"
wait_pin halui.mist.is-on TRUE
press halui.mist.off
wait_for "s['io']['mist']" "False" "mist off"
press halui.lube.on
wait_for "s['io']['lube']" "True" "lube on from halui.lube.on"
wait_pin halui.lube.is-on TRUE
press halui.lube.off
wait_for "s['io']['lube']" "False" "lube off"
# Spindle: forward at the default speed, then one step up and one down.
press halui.spindle.0.forward
wait_for "s['spindles'][0]['enabled']" "True" "spindle on from halui.spindle.0.forward"
wait_pin halui.spindle.0.runs-forward TRUE
s0="$(field "s['spindles'][0]['speed']")"
press halui.spindle.0.increase
wait_for "s['spindles'][0]['speed'] > $s0" "True" "spindle faster from halui.spindle.0.increase"
s1="$(field "s['spindles'][0]['speed']")"
press halui.spindle.0.decrease
wait_for "s['spindles'][0]['speed'] < $s1" "True" "spindle slower from halui.spindle.0.decrease"
press halui.spindle.0.stop
wait_for "s['spindles'][0]['enabled']" "False" "spindle off"
wait_pin halui.tool.number "$(field "s['io']['tool_in_spindle']")"
# A joint jog (the machine is not homed: joint mode) at 120 units/min while held.
z0="$(field "'%.3f' % s['joints'][2]['pos_cmd']")"
halcmd setp halui.joint.jog-speed 120
halcmd setp halui.joint.2.minus 1
wait_for "s['joints'][2]['pos_cmd'] < $z0 - 0.5" "True" "joint 2 jogs down from halui.joint.2.minus"
halcmd setp halui.joint.2.minus 0
wait_for "abs(s['joints'][2]['velocity']) < 1e-6" "True" "joint 2 stops when halui.joint.2.minus falls"
# Abort clears the MDI queue: a long move aborted by halui.abort.
cnc mode manual
cnc --timeout 120 home all >/dev/null
cnc mode mdi
cnc mdi G53 G1 Z-60 F100 &
mdi=$!
wait_for "s['task']['interp_state'] != 'IDLE'" "True" "long MDI move running"
press halui.abort
wait_for "s['task']['interp_state']" "IDLE" "abort from halui.abort"
wait "$mdi" || true
z="$(field "s['motion']['position'][2]")"
python3 -c "import sys; sys.exit(0 if float('$z') > -59 else 1)" || fail "the move was not aborted (Z $z)"
press halui.estop.activate
wait_for "s['task']['state']" "ESTOP" "E-stop"
echo "PASS"
