#!/usr/bin/env bash
# Builds the libFuzzer targets (the `fuzz` preset: clang-14, ASan + UBSan) and runs each for a
# bounded time on a copy of its seed corpus (fuzz/corpus/<target>/, never modified here).
#   scripts/fuzz.sh [SECONDS_PER_TARGET=30] [TARGET...]
# Targets: zone_file payload dense_codec png_decoder rtabmap_blob line_protocol. A crash stops with a non-zero exit and
# leaves the input as build/fuzz/findings/<target>/crash-*; copy it into fuzz/regressions/<target>/
# (tests/reliability replays every file there) and fix the code.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-30}"
shift || true
TARGETS=("$@")
if [ ${#TARGETS[@]} -eq 0 ]; then TARGETS=(zone_file payload dense_codec png_decoder rtabmap_blob line_protocol); fi
JOBS="${JOBS:-2}"

cmake --preset fuzz >/dev/null
cmake --build build/fuzz --target zm_fuzzers -j "$JOBS"

# One target is one process on one core (libFuzzer's own loop): JOBS targets run side by side,
# each for its full time, and report in the order given.
run_target() {
  local t="$1" work="build/fuzz/findings/$1" corpus="build/fuzz/corpus/$1" rc=0
  mkdir -p "$work" "$corpus"
  cp -n fuzz/corpus/"$t"/* "$corpus"/ 2>/dev/null || true
  build/fuzz/fuzz/zm_fuzz_"$t" -max_total_time="$SECONDS_PER_TARGET" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$work/" "$corpus" > "$work/log.txt" 2>&1 || rc=$?
  echo "$rc" > "$work/rc"
}

running=0
for t in "${TARGETS[@]}"; do
  rm -f "build/fuzz/findings/$t/rc"
  run_target "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then wait -n || true; running=$((running - 1)); fi
done
wait

status=0
for t in "${TARGETS[@]}"; do
  work="build/fuzz/findings/$t"
  echo "== $t: ${SECONDS_PER_TARGET}s"
  if [ "$(cat "$work/rc" 2>/dev/null)" != 0 ]; then
    echo "!! $t found a crash (see $work/log.txt):"; ls "$work"/crash-* "$work"/leak-* "$work"/timeout-* "$work"/oom-* 2>/dev/null || true
    tail -40 "$work/log.txt"
    status=1
  else
    grep -E "stat::number_of_executed_units|cov:" "$work/log.txt" | tail -2
  fi
done
exit $status
