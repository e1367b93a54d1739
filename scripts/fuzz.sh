#!/usr/bin/env bash
# Builds the libFuzzer targets (the `fuzz` preset: clang-14, ASan + UBSan) and runs each for a
# bounded time on a copy of its seed corpus (fuzz/corpus/<target>/, never modified here).
#   scripts/fuzz.sh [SECONDS_PER_TARGET=30] [TARGET...]
# Targets: zone_file payload dense_codec rtabmap_blob line_protocol. A crash stops with a non-zero exit and
# leaves the input as build/fuzz/findings/<target>/crash-*; copy it into fuzz/regressions/<target>/
# (tests/reliability replays every file there) and fix the code.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-30}"
shift || true
TARGETS=("$@")
if [ ${#TARGETS[@]} -eq 0 ]; then TARGETS=(zone_file payload dense_codec rtabmap_blob line_protocol); fi
JOBS="${JOBS:-2}"

cmake --preset fuzz >/dev/null
cmake --build build/fuzz --target zm_fuzzers -j "$JOBS"

status=0
for t in "${TARGETS[@]}"; do
  work="build/fuzz/findings/$t"
  corpus="build/fuzz/corpus/$t"
  mkdir -p "$work" "$corpus"
  cp -n fuzz/corpus/"$t"/* "$corpus"/ 2>/dev/null || true
  echo "== $t: ${SECONDS_PER_TARGET}s"
  if ! build/fuzz/fuzz/zm_fuzz_"$t" -max_total_time="$SECONDS_PER_TARGET" -timeout=10 -rss_limit_mb=2048 \
       -max_len=65536 -print_final_stats=1 -artifact_prefix="$work/" "$corpus" \
       > "$work/log.txt" 2>&1; then
    echo "!! $t found a crash (see $work/log.txt):"; ls "$work"/crash-* "$work"/leak-* "$work"/timeout-* "$work"/oom-* 2>/dev/null || true
    tail -40 "$work/log.txt"
    status=1
  else
    grep -E "stat::number_of_executed_units|cov:" "$work/log.txt" | tail -2
  fi
done
exit $status
