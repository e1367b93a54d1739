#!/usr/bin/env bash
# The main job. It grows with the project into the simulated hospital comparison (semantic
# against basic, with and without a co-tenant); until the simulator and the tick loop exist it
# runs what exists and says what does not.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/host-release/app/zonemap
echo "zonemap demo: the simulator, the policies and the tick loop are not built yet;"
echo "zonemap demo: running what exists: the keyframe arena sized for an Orin Nano map share."
# 1.5 GiB map share, 64 KiB RGB-D keyframe slots, MemoryThr 800 keyframes (the paper's scale).
"$bin" arena --memory-thr 800 --budget-bytes $((1536 * 1024 * 1024)) --slot-bytes 65536 --prefault
if [ -x build/host-release/bench/zm_arena_bench ]; then
  build/host-release/bench/zm_arena_bench --benchmark_min_time=0.05
fi
