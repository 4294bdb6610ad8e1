#!/usr/bin/env bash
# package.contents_and_dependencies: builds the Debian packages
# (scripts/package.sh) and checks what they hold: the standard layout, a
# manual page for every program in /usr/bin, the sample configurations,
# the helpers in /usr/lib/<triplet>/cnc, the dependencies dpkg-shlibdeps
# found, the postinst's capabilities and group, and no lintian error.
#   inspect_packages.sh SOURCE BUILD
set -euo pipefail
src="$1" build="$2"
out="$build/packages-test"
"$src/scripts/package.sh" --build-dir "$build" --out "$out" --no-lintian >"$build/packages-test.log" 2>&1 ||
  { cat "$build/packages-test.log"; exit 1; }
fail=0
bad() { echo "FAIL: $*"; fail=1; }
triplet="$(dpkg-architecture -qDEB_HOST_MULTIARCH)"

deb() { ls "$out"/"$1"_*.deb 2>/dev/null | head -n 1; }
for p in cnc cnc-configs cnc-comp; do [ -n "$(deb $p)" ] || bad "no package $p in $out"; done
[ $fail -eq 0 ] || exit 1

contents() { dpkg-deb -c "$1" | awk '{print $6}' | sed 's|^\./|/|'; }
field() { dpkg-deb -f "$1" "$2"; }

cnc="$(deb cnc)" configs="$(deb cnc-configs)" screen="$(deb cnc-screen)" comp="$(deb cnc-comp)"
conn="$(deb cnc-connectivity)"
files="$(contents "$cnc")"
for prog in cncd cnc halcmd cnc-scope cnc-rs274 cnc-canopen cnc-ethercat cnc-config cnc-can-up; do
  grep -qx "/usr/bin/$prog" <<<"$files" || bad "cnc: no /usr/bin/$prog"
done
for helper in cnc-cia402-sim ecat-sim cnc-modbus-sim cnc-canopen-node; do
  grep -qx "/usr/lib/$triplet/cnc/$helper" <<<"$files" || bad "cnc: no /usr/lib/$triplet/cnc/$helper"
done
all="$files"$'\n'"$(contents "$configs")"$'\n'"$(contents "$comp")"
grep -qx /usr/bin/cnc-comp <<<"$all" || bad "cnc-comp: no /usr/bin/cnc-comp"
grep -qx /usr/bin/cnc-commission <<<"$(contents "$comp")" \
  || bad "cnc-comp: no /usr/bin/cnc-commission"
[ -n "$screen" ] && all+=$'\n'"$(contents "$screen")"
if [ -n "$conn" ]; then
  cfiles_conn="$(contents "$conn")"
  all+=$'\n'"$cfiles_conn"
  for prog in cnc-mtconnect cnc-mqtt; do
    grep -qx "/usr/bin/$prog" <<<"$cfiles_conn" || bad "cnc-connectivity: no /usr/bin/$prog"
  done
  grep -q '^/usr/lib/python3/dist-packages/cnc\..*\.so$' <<<"$cfiles_conn" \
    || bad "cnc-connectivity: no Python module cnc in /usr/lib/python3/dist-packages"
fi
# Every program in /usr/bin has its manual page, which is not empty.
for prog in $(grep '^/usr/bin/.' <<<"$all" | xargs -n1 basename); do
  grep -qx "/usr/share/man/man1/$prog.1.gz" <<<"$all" || bad "no manual page for $prog"
done
grep -q '^/usr/local' <<<"$all" && bad "files under /usr/local"
for p in cnc cnc-configs cnc-comp ${screen:+cnc-screen} ${conn:+cnc-connectivity}; do
  grep -qx "/usr/share/doc/$p/copyright" <<<"$all" || bad "$p: no /usr/share/doc/$p/copyright"
done

cfiles="$(contents "$configs")"
for ini in sim/sim.ini canopen-mill/canopen-mill.ini ethercat-mill/ethercat-mill.ini gantry/gantry.ini \
           inch-mill/inch-mill.ini sim-modbus/sim-modbus.ini modbus-huanyang/huanyang.ini; do
  grep -qx "/usr/share/cnc/configs/$ini" <<<"$cfiles" || bad "cnc-configs: no /usr/share/cnc/configs/$ini"
  grep -qx "/usr/share/cnc/configs/$(dirname "$ini")/README.md" <<<"$cfiles" ||
    bad "cnc-configs: no README.md for $(dirname "$ini")"
done
grep -qx /usr/share/doc/cnc-configs/docs/install.md <<<"$cfiles" || bad "cnc-configs: no docs/install.md"
[ "$(field "$configs" Architecture)" = all ] || bad "cnc-configs is not Architecture: all"

# Dependencies: what dpkg-shlibdeps found for the programs, and ours.
deps="$(field "$cnc" Depends)"
for d in libc6 libstdc++6 libcap2-bin; do grep -q "\b$d\b" <<<"$deps" || bad "cnc: Depends lacks $d ($deps)"; done
grep -q "libmodbus" <<<"$deps" || bad "cnc: Depends lacks libmodbus ($deps)"
# The controller stays lean: the fitting's libraries come with cnc-comp only.
grep -q "opencv\|cholmod" <<<"$deps" && bad "cnc: depends on the compensation tool's libraries ($deps)"
if [ -n "$screen" ]; then
  sdeps="$(field "$screen" Depends)"
  grep -q "libqt6widgets6" <<<"$sdeps" || bad "cnc-screen: Depends lacks libqt6widgets6 ($sdeps)"
  grep -q "cnc (= " <<<"$sdeps" || bad "cnc-screen: does not depend on its cnc ($sdeps)"
fi
# The programs are stripped (the packages are not debug builds).
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
dpkg-deb -x "$cnc" "$tmp"
file "$tmp/usr/bin/cncd" | grep "stripped" >/dev/null && ! file "$tmp/usr/bin/cncd" | grep "not stripped" >/dev/null ||
  bad "cncd is not stripped"
dpkg-deb -e "$cnc" "$tmp/DEBIAN"
grep -q "setcap cap_sys_nice,cap_ipc_lock,cap_net_raw+ep /usr/bin/cncd" "$tmp/DEBIAN/postinst" ||
  bad "postinst does not give cncd its capabilities"
grep -q "groupadd --system cnc" "$tmp/DEBIAN/postinst" || bad "postinst does not create the group cnc"

if command -v lintian >/dev/null; then
  lintian --tag-display-limit 0 "$out"/*.deb >"$tmp/lintian.txt" 2>&1 || true
  if grep -q '^E:' "$tmp/lintian.txt"; then
    grep '^E:' "$tmp/lintian.txt"
    bad "lintian errors (docs/install.md, \"lintian\", lists what remains and why)"
  fi
  echo "lintian: $(grep -c '^W:' "$tmp/lintian.txt" || true) warnings"
fi
ls -l "$out"/*.deb
[ $fail -eq 0 ] && echo "packages: OK"
exit $fail
