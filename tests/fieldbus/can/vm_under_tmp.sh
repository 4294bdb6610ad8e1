#!/usr/bin/env bash
# The VM harness works for a checkout under /tmp: the guest mounts a fresh
# tmpfs on /tmp, which used to hide the job file and the build. A build
# folder and a working directory under /tmp must stay visible in the guest.
#   vm_under_tmp.sh SCRIPTS_VM_RUN
set -euo pipefail
run="$1"
top="$(mktemp -d /tmp/cnc-vm-tmp.XXXXXX)"
trap 'rm -rf "$top"' EXIT
mkdir -p "$top/checkout/build"
echo "visible in the guest" > "$top/checkout/marker"
cd "$top/checkout"
out="$("$run" --vm --build-dir "$top/checkout/build" --timeout 200 -- sh -c 'cat marker; test -w /tmp && echo tmp-writable')"
echo "$out"
echo "$out" | grep "^visible in the guest$" >/dev/null || { echo "FAIL: the checkout under /tmp is hidden in the guest"; exit 1; }
echo "$out" | grep "^tmp-writable$" >/dev/null || { echo "FAIL: the guest's /tmp is not writable"; exit 1; }
echo PASS
