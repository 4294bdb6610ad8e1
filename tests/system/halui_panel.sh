#!/usr/bin/env bash
# halui on the product path: cncd on a copy of configs/sim with
# `loadrt halui` and two [HALUI]MDI_COMMAND lines; a panel is played with
# `halcmd setp` on halui's pins, as buttons and an override knob would, and
# the controller's status (`cnc status --json`) must follow: E-stop reset,
# machine on, mode changes, an MDI command from the INI that moves Z,
# the feed override from counts and from the increase button; halui's
# status pins must show the same.
#   halui_panel.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1"
config="$2"
# The copy gets halui before cncd starts (cncd_on_copy.sh copies $config).
staged="$(mktemp -d /var/tmp/cnc-halui-config.XXXXXX)"
trap 'rm -rf "$staged"' EXIT
cp -r "$config/." "$staged/"
printf '\n[HALUI]\nMDI_COMMAND = G53 G0 Z-7\nMDI_COMMAND = G53 G0 Z-3\n' >> "$staged/sim.ini"
printf '\nloadrt halui\n' >> "$staged/sim.hal"
config="$staged"
# shellcheck source=cncd_on_copy.sh
source "$(dirname "${BASH_SOURCE[0]}")/cncd_on_copy.sh" halui
trap 'cleanup; rm -rf "$staged"' EXIT
halcmd() { "$bin/halcmd" "$@"; }
fail() { echo "FAIL: $*"; echo "--- messages"; cnc messages 2>/dev/null | tail -20 || true; echo "--- log"; tail -30 "$work/cncd.log"; exit 1; }
field() { cnc status --json | python3 -c "import json,sys; s=json.load(sys.stdin); print(eval(sys.argv[1], {'s': s}))" "$1"; }
# wait_for EXPR VALUE WHAT: polls the status for up to 20 s.
wait_for() {
  local got=""
  for _ in $(seq 200); do
    got="$(field "$1")"
    [ "$got" = "$2" ] && { echo "ok   $3 ($1 = $got)"; return 0; }
    sleep 0.1
  done
  fail "$3: $1 is $got, expected $2"
}
# press PIN: a button press the 10 ms poll cannot miss.
press() { halcmd setp "$1" 1 && sleep 0.1 && halcmd setp "$1" 0 && sleep 0.05; }
pin() { halcmd getp "$1"; }

cnc --timeout 30 wait-ready || fail "controller did not start"
[ "$(pin halui.estop.is-activated)" = "TRUE" ] || fail "halui.estop.is-activated should start TRUE"
press halui.estop.reset
press halui.machine.on
wait_for "s['task']['state']" "ON" "machine on from halui.machine.on"
for _ in $(seq 50); do [ "$(pin halui.machine.is-on)" = "TRUE" ] && break; sleep 0.1; done
[ "$(pin halui.machine.is-on)" = "TRUE" ] || fail "halui.machine.is-on stays FALSE"
press halui.home-all
for j in 0 1 2; do wait_for "s['joints'][$j]['homed']" "True" "joint $j homed from halui.home-all"; done
press halui.mode.mdi
wait_for "s['task']['mode']" "MDI" "mode MDI from halui.mode.mdi"
[ "$(pin halui.mode.is-mdi)" = "TRUE" ] || sleep 0.2
[ "$(pin halui.mode.is-mdi)" = "TRUE" ] || fail "halui.mode.is-mdi stays FALSE"
press halui.mode.manual
wait_for "s['task']['mode']" "MANUAL" "mode manual from halui.mode.manual"
# The second MDI_COMMAND of the INI; halui changes to MDI mode itself.
press halui.mdi-command-01
wait_for "'%.3f' % s['motion']['position'][2]" "-3.000" "Z moved by [HALUI]MDI_COMMAND #1"
press halui.mdi-command-00
wait_for "'%.3f' % s['motion']['position'][2]" "-7.000" "Z moved by [HALUI]MDI_COMMAND #0"
# Feed override: a knob's counts (scale 0.1 per count), then the button.
halcmd setp halui.feed-override.scale 0.1
sleep 0.1
halcmd setp halui.feed-override.counts -3
wait_for "'%.2f' % s['motion']['feed_scale']" "0.70" "feed override from 3 counts down"
press halui.feed-override.increase
wait_for "'%.2f' % s['motion']['feed_scale']" "0.80" "feed override from increase"
sleep 0.1
[ "$(pin halui.feed-override.value)" = "0.8" ] || fail "halui.feed-override.value is $(pin halui.feed-override.value)"
press halui.machine.off
wait_for "s['task']['state']" "OFF" "machine off from halui.machine.off"
press halui.estop.activate
wait_for "s['task']['state']" "ESTOP" "E-stop from halui.estop.activate"
echo "PASS"
