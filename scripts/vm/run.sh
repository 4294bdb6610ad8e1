#!/usr/bin/env bash
# Runs a command against real kernel SocketCAN with an interface vcan0 (and
# vcan1) up, and returns its output and exit status.
#
#   scripts/vm/run.sh [--build-dir DIR] [--timeout SECONDS] [--vm|--direct] -- COMMAND [ARG...]
#
# Where the host kernel has vcan and we are root, the command runs directly in
# a private network namespace holding vcan0/vcan1 (nothing else on the host
# sees them). Otherwise (this project's CI: no AF_CAN in the host kernel) it
# boots Debian's own kernel (unpacked by scripts/setup.d/can-vm.sh) under
# qemu with software emulation (-accel tcg; KVM is never used), loads can,
# can-raw, can-dev, vcan and the virtio/9p modules, creates vcan0/vcan1,
# mounts the host root read-only over 9p, chroots into it and runs the
# command in the same working directory with the same PATH. The guest has no
# network card: traffic stays on the guest's vcan interfaces.
# Results come back on the serial console between marker lines.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"

build_dir="$root/build"
timeout_s=300
mode=auto
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build_dir="$2"; shift 2 ;;
    --timeout) timeout_s="$2"; shift 2 ;;
    --vm) mode=vm; shift ;;
    --direct) mode=direct; shift ;;
    --) shift; break ;;
    *) echo "vm/run.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[ $# -gt 0 ] || { echo "usage: $0 [--build-dir DIR] [--timeout S] [--vm|--direct] -- COMMAND [ARG...]" >&2; exit 2; }
case "$mode" in auto|vm|direct) ;; *) exit 2 ;; esac
[ "${CNC_VM_MODE:-}" = vm ] && mode=vm
[ "${CNC_VM_MODE:-}" = direct ] && mode=direct

host_has_vcan() {
  [ "$(id -u)" -eq 0 ] || return 1
  command -v unshare >/dev/null && command -v ip >/dev/null || return 1
  modprobe -q vcan 2>/dev/null && modprobe -q can-raw 2>/dev/null || return 1
  unshare --net sh -c 'ip link add dev vcan0 type vcan' 2>/dev/null
}

if [ "$mode" = direct ] || { [ "$mode" = auto ] && host_has_vcan; }; then
  # shellcheck disable=SC2016
  exec unshare --net sh -c 'set -e; ip link set lo up
    for i in 0 1; do ip link add dev vcan$i type vcan; ip link set vcan$i up; done
    exec "$@"' vcan-ns "$@"
fi

# --- virtual machine ---
cache="${CNC_VM_CACHE:-$root/.cache/can-vm}"
vmlinuz="$(ls "$cache"/kernel/boot/vmlinuz-* 2>/dev/null | head -n1 || true)"
if [ -z "$vmlinuz" ]; then
  echo "vm/run.sh: no kernel in $cache/kernel; run scripts/setup.sh (scripts/setup.d/can-vm.sh)" >&2
  exit 2
fi
kver="${vmlinuz##*/vmlinuz-}"
moddir="$cache/kernel/lib/modules/$kver/kernel"
for tool in qemu-system-x86_64 cpio; do
  command -v "$tool" >/dev/null || { echo "vm/run.sh: $tool missing; run scripts/setup.sh" >&2; exit 2; }
done
busybox=/bin/busybox
[ -x "$busybox" ] || { echo "vm/run.sh: $busybox missing (package busybox-static)" >&2; exit 2; }
modinfo=/sbin/modinfo
command -v modinfo >/dev/null && modinfo="$(command -v modinfo)"

mkdir -p "$build_dir/vm"
build_dir="$(cd "$build_dir" && pwd)"
vmdir="$build_dir/vm"
initrd="$vmdir/initramfs-$kver.cpio.gz"

# Modules in load order: each after the modules it depends on (modinfo).
wanted=(can can-raw can-dev vcan virtio_pci 9pnet_virtio 9p)
order=()
declare -A seen=()
find_module() {
  find "$moddir" \( -name "$1.ko" -o -name "${1//_/-}.ko" -o -name "${1//-/_}.ko" \) -print -quit
}
visit() {
  local m="$1" key="${1//-/_}"
  [ -n "${seen[$key]:-}" ] && return 0
  seen[$key]=1
  local f
  f="$(find_module "$m")"
  [ -n "$f" ] || { echo "vm/run.sh: module $m not found under $moddir" >&2; exit 2; }
  local deps d
  deps="$("$modinfo" -F depends "$f")"
  IFS=, read -ra d <<< "$deps"
  for dep in "${d[@]}"; do [ -n "$dep" ] && visit "$dep"; done
  order+=("$f")
}

if [ ! -f "$initrd" ] || [ "$initrd" -ot "$0" ] || [ "$initrd" -ot "$vmlinuz" ]; then
  for m in "${wanted[@]}"; do visit "$m"; done
  staging="$(mktemp -d "$vmdir/initramfs.XXXXXX")"
  mkdir -p "$staging"/{bin,dev,proc,sys,host,modules}
  cp "$busybox" "$staging/bin/busybox"
  : > "$staging/modules/order"
  i=0
  for f in "${order[@]}"; do
    name="$(printf '%02d-%s' "$i" "${f##*/}")"
    cp "$f" "$staging/modules/$name"
    echo "$name" >> "$staging/modules/order"
    i=$((i + 1))
  done
  cat > "$staging/init" <<'INIT'
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev 2>/dev/null
for m in $(cat /modules/order); do
  insmod "/modules/$m" || echo "CNC-VM-ERROR insmod $m failed"
done
job=""
keep=""
for w in $(cat /proc/cmdline); do
  case "$w" in
    cnc.job=*) job="${w#cnc.job=}" ;;
    cnc.keep=*) keep="${w#cnc.keep=}" ;;
  esac
done
ip link set lo up
for i in 0 1; do ip link add dev vcan$i type vcan && ip link set vcan$i up; done
if mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=262144,cache=loose host /host; then
  mount -t proc proc /host/proc
  mount -t sysfs sys /host/sys
  mount -o bind /dev /host/dev
  # The guest writes to a fresh /tmp; a checkout that lies under the host's
  # /tmp (cnc.keep) stays visible through a bind mount of the original.
  if [ -n "$keep" ]; then
    mkdir -p /hosttmp
    mount -o bind /host/tmp /hosttmp
  fi
  mount -t tmpfs tmpfs /host/tmp
  if [ -n "$keep" ]; then
    mkdir -p "/host$keep"
    mount -o bind "/hosttmp${keep#/tmp}" "/host$keep" || echo "CNC-VM-ERROR cannot keep $keep visible"
  fi
  mount -t tmpfs tmpfs /host/run 2>/dev/null
  mount -t tmpfs tmpfs /host/dev/shm 2>/dev/null
  echo
  echo "CNC-VM-BEGIN"
  chroot /host /bin/sh "$job" </dev/null 2>&1
  rc=$?
  echo "CNC-VM-END rc=$rc"
else
  echo "CNC-VM-ERROR cannot mount the host root over 9p"
fi
sync
poweroff -f
INIT
  chmod +x "$staging/init"
  # Parallel runs (ctest -j) may build it at once: each writes its own file
  # and renames it into place atomically.
  ( cd "$staging" && find . | cpio -o -H newc --quiet | gzip -1 > "$initrd.tmp.$$" )
  mv "$initrd.tmp.$$" "$initrd"
  rm -rf "$staging"
fi

# Under software emulation the kernel's own xz decompression takes seconds:
# boot the uncompressed ELF image through its PVH entry (CONFIG_PVH) instead.
kernel="$vmdir/vmlinux-$kver"
if [ ! -f "$kernel" ] || [ "$kernel" -ot "$vmlinuz" ]; then
  off="$(grep -abo $'\xfd7zXZ\x00' "$vmlinuz" | head -n1 | cut -d: -f1 || true)"
  if [ -n "$off" ] && command -v xz >/dev/null; then
    { tail -c +$((off + 1)) "$vmlinuz" | xz -dc > "$kernel.tmp.$$"; } 2>/dev/null || true
  fi
  if [ -s "$kernel.tmp.$$" ] && [ "$(head -c 4 "$kernel.tmp.$$" | od -An -tx1 | tr -d ' ')" = 7f454c46 ]; then
    mv "$kernel.tmp.$$" "$kernel"
  else
    rm -f "$kernel.tmp.$$"
    cp "$vmlinuz" "$kernel.tmp.$$" && mv "$kernel.tmp.$$" "$kernel"
  fi
fi

# The job: same folder, same PATH, the command with its arguments quoted.
jobdir="$(mktemp -d "$vmdir/job.XXXXXX")"
trap 'rm -rf "$jobdir"' EXIT
job="$jobdir/job.sh"
{
  echo "export PATH=$(printf '%q' "$PATH")"
  echo "export HOME=/tmp TMPDIR=/tmp CNC_IN_VM=1 GTEST_COLOR=no TERM=dumb"
  for v in GTEST_FILTER GTEST_COLOR CNC_NO_REALTIME CNC_TEST_SEED; do
    [ -n "${!v:-}" ] && echo "export $v=$(printf '%q' "${!v}")"
  done
  echo "cd $(printf '%q' "$PWD") || exit 97"
  printf 'exec'; printf ' %q' "$@"; echo
} > "$job"
chmod 0644 "$job"

# A checkout under /tmp: the guest's fresh /tmp must not hide it (the
# top folder under /tmp that holds the build and the working directory).
keep=""
for d in "$PWD" "$vmdir"; do
  case "$d" in
    /tmp/?*) top="${d#/tmp/}"; top="/tmp/${top%%/*}"
             if [ -n "$keep" ] && [ "$keep" != "$top" ]; then
               echo "vm/run.sh: the build ($vmdir) and the working directory ($PWD) lie in different folders under /tmp" >&2
               exit 2
             fi
             keep="$top" ;;
  esac
done
case "$keep" in *[[:space:]]*) echo "vm/run.sh: a checkout under /tmp must not have blanks in its path ($keep)" >&2; exit 2 ;; esac

out="$jobdir/console.txt"
set +e
timeout --kill-after=5 "$timeout_s" qemu-system-x86_64 -accel tcg -cpu max -smp 2 -m 768 \
  -nodefaults -vga none -nographic -no-reboot -nic none -monitor none -serial stdio \
  -kernel "$kernel" -initrd "$initrd" \
  -virtfs local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap \
  -append "console=ttyS0 quiet loglevel=1 panic=-1 mitigations=off cnc.job=$job${keep:+ cnc.keep=$keep}" </dev/null > "$out" 2>&1
qrc=$?
set -e
tr -d '\r' < "$out" > "$out.clean"
if grep -q "^CNC-VM-ERROR" "$out.clean"; then
  grep "^CNC-VM-ERROR" "$out.clean" >&2
fi
if ! grep -q "CNC-VM-BEGIN$" "$out.clean"; then
  echo "vm/run.sh: the guest did not reach the job (qemu exit $qrc); console:" >&2
  tail -n 40 "$out.clean" >&2
  exit 125
fi
sed -n '/CNC-VM-BEGIN$/,/^CNC-VM-END rc=/p' "$out.clean" | sed '1d;/^CNC-VM-END rc=/d'
rcline="$(grep -a "^CNC-VM-END rc=" "$out.clean" | tail -n1 || true)"
if [ -z "$rcline" ]; then
  echo "vm/run.sh: the job did not finish (qemu exit $qrc, timeout ${timeout_s}s)" >&2
  exit 124
fi
exit "${rcline#CNC-VM-END rc=}"
