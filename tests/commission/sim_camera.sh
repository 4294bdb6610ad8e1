#!/usr/bin/env bash
# The simulated camera on the spindle for `cnc-commission axis L comp-run
# --camera exec:...`: one picture of the glass scale (cnc-vision-sim scale:
# 0.1 mm pitch, 2.5 um/px, 320x240, blur, noise, a tilt) at the value of
# HAL pin PIN of the running controller (the drive simulator's true table
# position) plus 10 mm, written to OUT.
#   sim_camera.sh BIN PIN OUT
set -eu
bin="$1" pin="$2" out="$3"
pos="$("$bin/halcmd" getp "$pin")"
at="$(awk -v p="$pos" 'BEGIN { printf "%.9f", 10 + p }')"
exec "$bin/cnc-vision-sim" scale --out "$out" --at "$at" --width 320 --height 240 --blur 1.2 --angle 1.5 \
  --seed "$RANDOM" >/dev/null
