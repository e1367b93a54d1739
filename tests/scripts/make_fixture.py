#!/usr/bin/env python3
"""A tiny synthetic `zonemap bench` output for the script tests: one scenario, the paper's four
configurations (basic and semantic, without and with the co-tenant), written with the keys of
issue 17's experiment (docs/harness.md, README "summary.json"): basic's summaries in schema
version 1 (one count, loop_closures), semantic's in version 2 (closures_accepted beside
frames_localized, stages), so the scripts read both. The numbers are made up but
shaped like the experiment's: Basic + VLM's map is OOM-killed at tick 30 and its co-tenant
stalls; Semantic + VLM completes.

With --repeats: the same four configurations as `zonemap bench --repeat 3` writes them
(runs/tiny/<cell>/rep0..rep2, results.json with each cell's statistics). The statistics are
literal numbers worked by hand (mean and Student-t 95 % half-width), not computed here: the
tables (`zonemap bench --report-only`) only format what the bench computed (harness/repeats.h).

Usage: make_fixture.py OUT [--repeats]
"""
import json
import math
import os
import sys

N_TICKS = 60
LIMIT = 800 * 2**20  # 1/8 of the orin-nano-8gb device less its OS reserve, roughly
SLOT = 270_000


def gt_pose(i):
    a = i / N_TICKS * 2 * math.pi
    return 10 + 8 * math.cos(a), 6 + 5 * math.sin(a)


def write_run(out, name, policy, with_vlm, rep=None):
    d = os.path.join(out, "runs", "tiny", name)
    if rep is not None:
        d = os.path.join(d, f"rep{rep}")
    os.makedirs(d, exist_ok=True)
    killed = policy == "basic" and with_vlm
    n = 30 if killed else N_TICKS
    k_max = 1820
    err = 0.05 if policy == "semantic" else 0.12
    ticks, est = [], []
    kills = 0
    for i in range(n):
        x, y = gt_pose(i)
        x += err * math.sin(i)
        y += err * math.cos(i)
        map_rss = (2400 - i if policy == "basic" else k_max) * SLOT + 40e6
        ct = (240e6 + 10e6 * (i % 5)) if with_vlm else 0
        if killed and i == 25:
            kills = 1
        ticks.append({
            "tick": i, "stamp": i * 1.0, "wall_s": i * 0.1, "x": x, "y": y, "zone": i // 10,
            "resident_keyframes": 2400 - i if policy == "basic" else k_max,
            "resident_bytes": int(map_rss - 40e6), "tick_ms": 20 + (i % 7) * (30 if killed else 3),
            "startup": i == 0, "loop_closure": (i % 3 != 0) and not (killed and i > 20),
            "device_usage_bytes": int(min(LIMIT, map_rss + ct)), "map_rss_bytes": int(map_rss),
            "cotenant_rss_bytes": int(ct), "map_majflt": i, "map_minflt": 100 * i,
            "oom_kills": kills, "frames_dropped": 0,
        })
        est.append(f"{i * 1.0:.6f} {x:.4f} {y:.4f} 0 0 0 0 1")
    with open(os.path.join(d, "ticks.jsonl"), "w") as f:
        for t in ticks:
            f.write(json.dumps(t) + "\n")
    with open(os.path.join(d, "estimate.tum"), "w") as f:
        f.write("\n".join(est) + "\n")
    loop_closures = sum(1 for t in ticks if t["loop_closure"])
    if policy == "basic":
        closures = {"loop_closures": loop_closures}
    else:
        closures = {"schema_version": 2, "closures_accepted": loop_closures,
                    "frames_localized": loop_closures,
                    "stages": {k: {"p50_ms": 1.0, "p99_ms": 2.0, "mean_ms": 1.2}
                               for k in ("features", "quantize", "likelihood", "verify", "memory")}}
    s = {
        "policy": policy, "k_max": k_max, "slot_bytes": SLOT, "ticks": n,
        "update_rate_hz": (0.65 if killed else 0.95), **closures,
        "tick_ms": {"mean": sum(t["tick_ms"] for t in ticks) / n, "p50": 20, "p99": 200,
                    "max": 220, "count": n - 1},
        "ate_rmse_m": err, "rpe_trans_rmse_m": err * 1.3, "rpe_rot_rmse_deg": 0.4,
        "frames_arrived": N_TICKS, "frames_dropped": 12 if killed else 1,
        "time_compression": 10.0, "device_scale": 0.125,
        "device": {"kind": "cgroup", "limit_bytes": LIMIT, "peak_bytes": LIMIT if killed else 700e6,
                   "oom_kills": kills},
        "map": {"outcome": "killed" if killed else "completed"},
        "peak_resident_keyframes": 2400 if policy == "basic" else k_max,
        "peak_resident_bytes": 2400 * SLOT,
    }
    if with_vlm:
        reqs = []
        for j in range(12):
            end = 0.5 + j * 0.45
            tps = (4.0 + (j % 4) * 0.3) if not killed else (1.0 + (j % 3) * 0.5)
            lat = 2000 + 150 * (j % 5) if not killed else 9000 + 800 * (j % 4)
            reqs.append({"event": "request", "id": j, "stand_in": True, "mono_s": 1000 + end,
                         "wall_s": end, "ended_s": 1000 + end, "tokens_per_s": tps,
                         "latency_ms": lat})
        with open(os.path.join(d, "cotenant.jsonl"), "w") as f:
            f.write(json.dumps({"event": "start", "mono_s": 1000.0, "wall_s": 0.0,
                                "model": "qwen3-vl-2b"}) + "\n")
            for r in reqs:
                f.write(json.dumps(r) + "\n")
            if killed:
                f.write(json.dumps({"event": "stall", "wall_s": 3.0, "id": 6}) + "\n")
                f.write(json.dumps({"event": "exit", "source": "supervisor", "kind": "killed",
                                    "mono_s": 1002.0, "instance": 0}) + "\n")
            f.write('{"event": "end", "torn')  # a writer killed mid-line
        s["cotenant"] = {
            "model": "qwen3-vl-2b", "origin_mono_s": 1000.0, "outcome": "stalled" if killed else "completed",
            "symbol": "△" if killed else "○", "requests_completed": len(reqs), "restarts": 0,
            "tokens_per_s": sorted(r["tokens_per_s"] for r in reqs)[len(reqs) // 2],
            "latency_ms": {"p50": sorted(r["latency_ms"] for r in reqs)[len(reqs) // 2],
                           "p95": max(r["latency_ms"] for r in reqs)},
        }
        if rep is not None:
            s["cotenant"]["weights"] = "pinned"
    if rep is not None:
        s["tick_ms"]["mean"] += rep  # the repeats differ
    with open(os.path.join(d, "summary.json"), "w") as f:
        json.dump(s, f, indent=1)
    return s


def stat(values, mean, ci95):
    return {"n": len(values), "mean": mean, "ci95": ci95, "median": mean, "values": values}


# Update rate over three repeats: {0.90, 0.95, 1.00}: mean 0.95, sd 0.05, t(0.975, 2) = 4.302653,
# half-width 4.302653 x 0.05 / sqrt(3) = 0.124207. TPS aggregate of two runs (one had none):
# {3.0, 5.0}: mean 4, sd sqrt(2), t(0.975, 1) = 12.706205, half-width 12.706205.
RATE = stat([0.90, 0.95, 1.00], 0.95, 0.124207)
TPS_AGG = stat([3.0, 5.0], 4.0, 12.706205)


def main():
    out = sys.argv[1]
    repeats = "--repeats" in sys.argv[2:]
    sdir = os.path.join(out, "scenarios", "tiny")
    os.makedirs(sdir, exist_ok=True)
    with open(os.path.join(sdir, "localization_gt.tum"), "w") as f:
        for i in range(N_TICKS):
            x, y = gt_pose(i)
            f.write(f"{i * 1.0:.6f} {x:.4f} {y:.4f} 0 0 0 0 1\n")
    cells = []
    for policy in ("basic", "semantic"):
        for vlm in (False, True):
            name = f"{policy}-k1820-{'qwen3-vl-2b' if vlm else 'none'}"
            if not repeats:
                write_run(out, name, policy, vlm)
                continue
            summaries = [write_run(out, name, policy, vlm, rep) for rep in range(3)]
            stats = {"/update_rate_hz": RATE}
            if vlm:
                stats["/cotenant/tokens_per_s_aggregate"] = TPS_AGG
            cells.append({"scenario_name": "tiny", "cell": name, "policy": policy,
                          "policy_label": policy, "model": "qwen3-vl-2b" if vlm else "none",
                          "budget": "1", "k_max": 1820, "repeats": 3,
                          "representative_repeat": 1, "representative_by": "/tick_ms/mean",
                          "stats": stats, "runs": summaries})
    if repeats:
        with open(os.path.join(out, "results.json"), "w") as f:
            json.dump(cells, f, indent=1)


if __name__ == "__main__":
    main()
