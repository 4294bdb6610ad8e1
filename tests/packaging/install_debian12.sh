#!/usr/bin/env bash
# package.installs_and_runs_the_demo_on_debian12 (slow): installs the
# packages (scripts/package.sh) into a clean Debian 12 root made with
# mmdebstrap, then, as an ordinary user of the group cnc, copies the
# installed sim configuration with cnc-config and runs the demo program on
# it with the installed cncd and cnc, as scripts/demo.sh does; the Modbus
# sample loads too (loadusr finds cnc-modbus-sim among the helpers). Needs root
# (mmdebstrap --mode=root, chroot, mount) and the Debian archive.
#   install_debian12.sh SOURCE BUILD
set -euo pipefail
src="$1" build="$2"
out="$build/packages-install-test"
t0=$(date +%s)
"$src/scripts/package.sh" --build-dir "$build" --out "$out" --no-lintian >"$build/packages-install-test.log" 2>&1 ||
  { cat "$build/packages-install-test.log"; exit 1; }
debs=("$out"/cnc_*.deb "$out"/cnc-configs_*.deb)
[ -f "${debs[0]}" ] && [ -f "${debs[1]}" ] || { echo "FAIL: no packages in $out"; exit 1; }
includes=()
for d in "${debs[@]}" "$out"/cnc-screen_*.deb; do [ -f "$d" ] && includes+=(--include="$(realpath "$d")"); done

root="$(mktemp -d /tmp/cnc-debian12.XXXXXX)"
cleanup() {
  umount -R "$root/proc" "$root/dev/shm" 2>/dev/null || true
  rm -rf --one-file-system "$root"
}
trap cleanup EXIT
rmdir "$root"
# The hook bind-mounts the local packages into the chroot for apt.
mmdebstrap --mode=root --variant=apt --hook-dir=/usr/share/mmdebstrap/hooks/file-mirror-automount \
  "${includes[@]}" bookworm "$root"
t1=$(date +%s)
echo "mmdebstrap with the packages: $((t1 - t0)) s (packages built and root made)"

mount -t proc proc "$root/proc"
mkdir -p "$root/dev/shm"
mount -t tmpfs -o mode=1777 shm "$root/dev/shm"
in_root() { chroot "$root" "$@"; }

# The package made the group and gave cncd its capabilities.
in_root getent group cnc
caps="$(in_root getcap /usr/bin/cncd)"
echo "$caps"
for c in cap_sys_nice cap_ipc_lock cap_net_raw; do grep -q "$c" <<<"$caps" || { echo "FAIL: cncd lacks $c"; exit 1; }; done
in_root useradd --create-home --groups cnc machinist

cat >"$root/home/machinist/run-demo.sh" <<'DEMO'
set -euo pipefail
cd "$HOME"
cnc-config list
cnc-config copy sim
cnc-config check sim
# loadusr finds the simulators' processes in /usr/lib/<triplet>/cnc.
cnc-config copy sim-modbus
cnc-config check sim-modbus
ini="$HOME/cnc/configs/sim/sim.ini"
# The segment and sockets go to the group cnc (docs/install.md).
sed -i 's/^\[EMC\]$/[EMC]\nOPERATOR_GROUP = cnc/' "$ini"
cncd "$ini" 2>"$HOME/cncd.log" &
daemon=$!
trap 'kill $daemon 2>/dev/null || true' EXIT
cnc wait-ready
stat -c '%U %G %a %n' /dev/shm/cnc-default* 
[ "$(stat -c '%U %G %a' /dev/shm/cnc-default)" = "machinist cnc 660" ]
cnc estop-reset
cnc on
cnc home all
cnc mode auto
cnc open "$HOME/cnc/configs/sim/nc_files/demo.ngc"
cnc run
cnc wait-program
cnc status | tee "$HOME/status.txt"
grep -q "SCHED_FIFO" "$HOME/status.txt" && echo "servo thread: SCHED_FIFO (capabilities in force)" ||
  echo "servo thread: not SCHED_FIFO (this container's bounding set lacks CAP_SYS_NICE?)"
cnc shutdown
wait $daemon
trap - EXIT
echo "demo finished as $(id -un)"
DEMO
in_root chown -R machinist:machinist /home/machinist
in_root runuser -u machinist -- env HOME=/home/machinist bash /home/machinist/run-demo.sh ||
  { echo "FAIL: the demo as an ordinary user; cncd's log:"; cat "$root/home/machinist/cncd.log"; exit 1; }
echo "install test: OK in $(( $(date +%s) - t0 )) s"
