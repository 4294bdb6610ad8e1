#!/usr/bin/env bash
# Fuzzes every parser (docs/fuzzing.md): builds the libFuzzer targets with
# clang-14 in build-fuzz (CNC_FUZZ: coverage instrumentation, AddressSanitizer
# and UndefinedBehaviorSanitizer in every library) and runs each target in
# turn for SECONDS (default 60).
#   scripts/fuzz.sh [SECONDS] [TARGET...]      targets: interp params ini hal
#                                              tooltable eds esi comp_table measurement
# (in any order: a number is the time, a name a target; no target: all).
# Environment: CNC_FUZZ_BUILD (build folder, default build-fuzz),
# CNC_FUZZ_FLAGS (more libFuzzer flags, e.g. "-jobs=2 -workers=2").
# Each target's growing corpus starts from its seeds (the project's own
# files and the examples in docs/) and its regression corpus (corpus/<target>/
# next to the harness); findings (crash-*, leak-*, timeout-*, oom-*) land in
# build-fuzz/fuzz/findings/<target>/ and make the script exit 1. Reproduce
# one with build-fuzz/bin/<target>_fuzz FILE or, without clang, with
# build/bin/<target>_fuzz_replay FILE. A finding, once fixed, goes into the
# regression corpus so that ctest replays it.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { echo "usage: scripts/fuzz.sh [SECONDS] [TARGET...]" >&2; exit 2; }
seconds=60
targets=()
for a in "$@"; do
  case "$a" in
    -h|--help) usage ;;
    -*) echo "fuzz: unknown option '$a'" >&2; usage ;;
  esac
  if [[ "$a" =~ ^[0-9]+$ ]]; then
    [ "$a" -ge 1 ] || usage
    seconds="$a"
  else
    targets+=("$a")
  fi
done
build="${CNC_FUZZ_BUILD:-$root/build-fuzz}"
for tool in clang-14 clang++-14 cmake ninja; do
  command -v "$tool" >/dev/null || { echo "fuzz: $tool not found (scripts/setup.sh installs scripts/deps/fuzz.txt)" >&2; exit 2; }
done

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
CC=clang-14 CXX=clang++-14 cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCNC_FUZZ=ON \
  -DCNC_BUILD_BENCH=OFF -DCNC_BUILD_HMI=OFF "${launcher[@]}" >/dev/null

# The targets: one list file per harness, written by cmake (cnc_fuzz_target).
all=()
for f in "$build"/fuzz/*.txt; do all+=("$(basename "$f" .txt)"); done
[ ${#targets[@]} -eq 0 ] && targets=("${all[@]}")
for t in "${targets[@]}"; do
  [ -f "$build/fuzz/$t.txt" ] || { echo "fuzz: no target '$t' (have: ${all[*]})" >&2; exit 2; }
done
ninja -C "$build" "${targets[@]/%/_fuzz}"

summary=()
found=0
for t in "${targets[@]}"; do
  list="$build/fuzz/$t.txt"
  work="$build/fuzz/corpus/$t"
  findings="$build/fuzz/findings/$t"
  mkdir -p "$work" "$findings"
  corpus="$(sed -n 's/^corpus //p' "$list")"
  dict="$(sed -n 's/^dict //p' "$list")"
  # Seeds into the working corpus (names kept unique by a short hash).
  while read -r seed; do
    if [ -d "$seed" ]; then
      find "$seed" -type f -print0 | while IFS= read -r -d '' s; do
        cp -n "$s" "$work/seed-$(echo "$s" | md5sum | cut -c1-8)-$(basename "$s")"
      done
    elif [ -f "$seed" ]; then
      cp -n "$seed" "$work/seed-$(echo "$seed" | md5sum | cut -c1-8)-$(basename "$seed")"
    fi
  done < <(sed -n 's/^seed //p' "$list")
  args=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
        -artifact_prefix="$findings/")
  [ -n "$dict" ] && args+=(-dict="$dict")
  dirs=("$work")
  [ -d "$corpus" ] && dirs+=("$corpus")
  echo "fuzz: $t for $seconds s"
  log="$build/fuzz/$t.log"
  # shellcheck disable=SC2086
  before="$(mktemp)"
  ls "$findings" >"$before"
  if "$build/bin/${t}_fuzz" "${args[@]}" ${CNC_FUZZ_FLAGS:-} "${dirs[@]}" >"$log" 2>&1; then
    result="nothing found"
  else
    found=1
    new="$(ls "$findings" | comm -13 "$before" - | sed "s|^|$findings/|" | tr '\n' ' ')"
    if [ -n "$new" ]; then
      result="FOUND: ${new}(log: $log)"
    else
      result="FAILED to run (log: $log)"
    fi
  fi
  rm -f "$before"
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1 || true)"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1 || true)"
  rss="$(sed -n 's/^stat::peak_rss_mb: *//p' "$log" | tail -1 || true)"
  cov="$( (grep -o 'cov: [0-9]* ft: [0-9]*' "$log" || true) | tail -1)"
  summary+=("$(printf '%-12s %9s execs %6s/s  %-22s peak %5s MB  corpus %5s  %s' "$t" "${execs:-?}" "${rate:-?}" \
    "${cov:-?}" "${rss:-?}" "$(ls "$work" | wc -l)" "$result")")
done
echo
printf '%s\n' "${summary[@]}"
exit "$found"
