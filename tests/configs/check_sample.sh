#!/usr/bin/env bash
# configs.<name>.passes_the_check: a sample configuration of configs/ loads
# with `cncd --check --strict` (INI, HAL files, every component created,
# every key known and used). The samples for real buses name hardware
# (socketcan:can0, raw:eth0) that a test host lacks, so a copy is checked
# with the in-process buses in their place: `socketcan:NAME` becomes
# `virtual:NAME` with simulated drives at the configured node IDs, and
# `raw:NAME` becomes `sim:NAME` with a segment of simulated slaves, loaded
# first; everything else is checked as shipped. Also: a README.md.
#   check_sample.sh BIN_DIR CONFIG_DIR
set -euo pipefail
bin="$1" dir="$2"
name="$(basename "$dir")"
[ -f "$dir/README.md" ] || { echo "FAIL: $dir has no README.md (what to change for a real machine)"; exit 1; }
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cp -r "$dir" "$tmp/$name"
inis=("$tmp/$name"/*.ini)
[ -f "${inis[0]}" ] || { echo "FAIL: no INI file in $dir"; exit 1; }
for ini in "${inis[@]}"; do
  if grep -qE '^[[:space:]]*INTERFACE[[:space:]]*=[[:space:]]*raw:' "$ini"; then
    # An EtherCAT segment of simulated slaves, one per [ETHERCAT]SLAVE.
    nic="$(sed -n -E 's/^[[:space:]]*INTERFACE[[:space:]]*=[[:space:]]*raw:([^[:space:]]+).*/\1/p' "$ini" | head -n 1)"
    slaves="$(grep -c '^\[ETHERCAT_SLAVE_' "$ini")"
    sed -i -E 's/^([[:space:]]*INTERFACE[[:space:]]*=[[:space:]]*)raw:([^[:space:]]+)/\1sim:\2/' "$ini"
    for hal in "$tmp/$name"/*.hal; do
      sed -i -E "0,/^loadrt ethercat\$/s//loadrt ethercat_sim name=$nic drives=$slaves\nloadrt ethercat/" "$hal"
    done
  fi
  if grep -qE '^[[:space:]]*INTERFACE[[:space:]]*=[[:space:]]*socketcan:' "$ini"; then
    # Simulated drives (cia402_sim, default plant) answer on each virtual
    # bus at the node IDs of its [CANOPEN*] section.
    sims=""
    while read -r iface nodes; do
      k=$(( $(wc -w <<<"$sims") ))
      sec="CHECK_SIM_$k"
      printf '\n[%s]\nINTERFACE = virtual:%s\nNODE = %s\n' "$sec" "$iface" "$nodes" >>"$ini"
      for n in $nodes; do printf '\n[%s_NODE_%s]\nNAME = node-%s\n' "$sec" "$n" "$n" >>"$ini"; done
      sims="$sims $sec"
    done < <(awk '
      function flush() { if (iface != "" && nodes != "") print iface, nodes; iface = ""; nodes = "" }
      /^[ \t]*\[/ { flush(); sec = $0; gsub(/[][ \t\r]/, "", sec); canopen = (sec ~ /^CANOPEN(_[0-9]+)?$/); next }
      canopen && /^[ \t]*INTERFACE[ \t]*=[ \t]*socketcan:/ { v = $0; sub(/^[^:]*:/, "", v); sub(/[ ,\t\r].*$/, "", v); iface = v }
      canopen && /^[ \t]*NODE[ \t]*=/ { v = $0; sub(/^[^=]*=[ \t]*/, "", v); sub(/[ \t\r]*$/, "", v); nodes = v }
      END { flush() }' "$ini")
    list="$(echo $sims | tr ' ' ',')"
    for hal in "$tmp/$name"/*.hal; do
      sed -i -E "0,/^loadrt canopen/s//loadrt cia402_sim sections=$list\n&/" "$hal"
    done
  fi
  sed -i -E 's/^([[:space:]]*INTERFACE[[:space:]]*=[[:space:]]*)socketcan:([^[:space:],]+)/\1virtual:\2/' "$ini"
  echo "== cncd --check --strict $name/$(basename "$ini")"
  CNC_NO_REALTIME=1 "$bin/cncd" --check --strict "$ini"
done
