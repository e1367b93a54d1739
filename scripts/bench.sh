#!/usr/bin/env bash
# Runs every benchmark program of the release build and prints its figures.
set -euo pipefail
cd "$(dirname "$0")/.."
for b in build/host-release/bench/zm_*_bench; do
  [ -x "$b" ] || continue
  echo "== $(basename "$b")"
  "$b" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
done
