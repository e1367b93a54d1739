#!/usr/bin/env bash
# The main job: the simulated hospital comparison. Generates the default hospital (cached in
# out/demo/scenarios), then replays its patrol under basic (RTAB-Map's retrieval), semantic
# (Algorithm 1) and predictive, plus unbounded as the accuracy ceiling, at one MemoryThr, with
# and without the co-tenant stand-in (qwen3-vl-2b sized), on the orin-nano-8gb profile. Prints
# the Table I / Table II analogues and writes figures to out/demo/figures.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${ZM_DEMO_OUT:-out/demo}
exec build/host-release/app/zonemap bench --quick --out "$out" "$@"
