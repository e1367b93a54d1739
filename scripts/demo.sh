#!/usr/bin/env bash
# The main job (issue 17): the paper's experiment under real memory pressure. One memory cgroup
# the size of the orin-nano-8gb profile's device less its OS reserve holds the map process and
# the co-tenant (a stand-in for qwen3-vl 2B served by llama.cpp); frames arrive in real time at
# 1 Hz, time-compressed by the same factor for every run. The map is chosen by arithmetic so that
# Basic alone fits the device and Basic + the model does not (README, "The demo's arithmetic";
# `scripts/sweep.py demo` prints it):
#
#   1. generate the dense hospital (cached in $out/scenarios/hospital)
#   2. zonemap bench: Basic only, Semantic only, Basic + VLM, Semantic + VLM at the MemoryThr the
#      profile derives (--budgets 1: the byte share sets K_max), in the cgroup
#   3. Table I / Table II in the paper's form beside the paper's numbers (written and printed by
#      zonemap bench itself, $out/paper_tables.md, with its own tables), the figures
#      (scripts/plots.py, run by bench) in $out/figures
#
# Knobs (environment): ZM_DEMO_OUT (out/demo), ZM_DEMO_SCALE (device scale, 0.25: see below),
# ZM_DEMO_COMPRESSION (time compression, 10), ZM_DEMO_AREA (m², 2100: 2,429 keyframes),
# ZM_DEMO_TASKS (patrol tasks, 6), ZM_DEMO_DEVICE (cgroup; ledger = simulated),
# ZM_DEMO_POLICIES (basic,semantic), ZM_DEMO_REPEAT (runs per configuration, 3, interleaved:
# the tables show mean ± 95 % CI), ZM_DEMO_REQUESTS (co-tenant requests per run, 4).
#
# Requests are the profile's full 512 + 128 tokens (136 passes over the weights each: 8 of
# prompt processing at 64 tokens a pass, 128 of decode). The time budget (15 minutes on a fresh
# 2-core machine, the build included) pays for 12 runs (4 configurations x 3 repeats) by a
# shorter patrol than before (ZM_DEMO_TASKS=12: 707 frames, 71 s a run; now 6 tasks: 702 frames
# at 2 Hz, 351 loop frames, 35 s a run) and 4 requests a co-tenant run (one every 8.8 s: at this
# scale a request is ~9 s of decode on an idle core, longer beside Basic), so the co-tenant is
# busy for the patrol and the drain after it stays short. The map is the same 2,429 keyframes (the
# arithmetic below does not depend on the patrol); the robot visits fewer zones and Basic's
# start-up load is a larger part of each run. Measured on the idle 2-core VM with the issue 27
# device (pinned weights, zram charged): all 4 requests completed in each of the 6 co-tenant runs,
# 435 s from the start of this script to the last table, the build not included (at load 7-12,
# before the pinned weights: 675 s, 2-4 of 4 requests). README, "Results of make demo".
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$(date +%s)
out=${ZM_DEMO_OUT:-out/demo}
# Scale 0.25 by default: a quarter of the Orin's memory, weights, KV cache and keyframe footprint
# together (the same ratios: Basic alone 86 % of the device, Basic + the model 116 %). At full
# size (ZM_DEMO_SCALE=1) decode streams 1.9 GB a token, four times as long a request.
scale=${ZM_DEMO_SCALE:-0.25}
compression=${ZM_DEMO_COMPRESSION:-10}
area=${ZM_DEMO_AREA:-2100}
tasks=${ZM_DEMO_TASKS:-6}
device=${ZM_DEMO_DEVICE:-cgroup}
policies=${ZM_DEMO_POLICIES:-basic,semantic}
repeat=${ZM_DEMO_REPEAT:-3}
requests=${ZM_DEMO_REQUESTS:-4}
zonemap=build/host-release/app/zonemap
py=/usr/bin/python3
[ -x "$py" ] || py=python3

scen="$out/scenarios/hospital"
want="seed=1 area=$area tasks=$tasks scale=$scale features=orb"
if [ ! -f "$scen/map.db" ] || [ "$(cat "$scen/.demo-spec" 2>/dev/null)" != "$want" ]; then
  rm -rf "$scen"
  echo "demo: generating the hospital ($want)" >&2
  "$zonemap" sim hospital --seed 1 --area "$area" --tasks "$tasks" --footprint-scale "$scale" \
    --quiet --out "$scen"
  echo "$want" > "$scen/.demo-spec"
fi
"$py" - "$scen/scenario.json" <<'EOF' >&2
import json, sys
s = json.load(open(sys.argv[1]))
r = s["resident_bytes"]
print(f'demo: {s["counts"]["keyframes"]:,} keyframes resident {r["min"]:,}-{r["max"]:,} B '
      f'(median {r["median"]:,}), {s["counts"]["frames"]:,} frames at '
      f'{s["localization"]["rate_hz"]:g} Hz in the scenario')
EOF
"$py" scripts/sweep.py demo --scale "$scale" --scenario "$scen" >&2

"$zonemap" bench --scenarios "dir:$scen" --policies "$policies" --models none,qwen3-vl-2b \
  --budgets 1 --device "$device" --device-scale "$scale" --time-compression "$compression" \
  --repeat "$repeat" --cotenant-requests "$requests" --out "$out" "$@"
echo "demo: wall time $(( $(date +%s) - t0 )) s (build not included; make demo prints it all)"
