#!/usr/bin/python3
"""Localization from pixels, measured (issue 26 §5): a robustness table and the likelihood's cost
per resident keyframe, each from runs made side by side in one invocation.

1. Robustness: one hospital generated in variants that differ in one thing only (the same seed,
   building, routes and décor seed), each replayed by the semantic policy at the same MemoryThr:
     baseline          the defaults (lighting spread 0.2, exposure 10 ms, repeated décor)
     lighting 0        the localization run lit exactly as the mapping run
     lighting 0.4      gain 1 +- 0.4 instead of +- 0.2
     no blur           exposure 0
     blur x3           exposure 30 ms
     unique décor      every poster and sign a design of its own (no aliasing)
   and the repeated and unique décor again with the closure gate off (what it does against
   aliasing). Columns: frames localized of ticks, closures rejected, ATE, tick p50 / p99,
   features p50.
2. Likelihood slope: the baseline replayed by unbounded, basic and semantic; per policy the
   resident keyframes (median), the likelihood stage (p50 ms), its cost per resident keyframe
   (median over ticks of likelihood / resident, us) and the postings the index walked (p50); and
   one least-squares slope of likelihood ms on resident keyframes over all three policies' ticks.

Every run is `zonemap run --time-compression 0 --device ledger` (as fast as the loop ticks, no
cgroup), so the figures are the loop's own; the machine's load is printed with them.

Usage: scripts/pixels_eval.py ZONEMAP OUT_DIR [--area M2] [--tasks N] [--scale S] [--seed N]
       [--memory-thr-share F] [--skip-robustness] [--skip-slope]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

# (directory, row, the one option that differs)
VARIANTS = [
    ("baseline", "baseline (lighting 0.2, exposure 10 ms, repeated décor)", []),
    ("light0", "lighting as mapped (spread 0)", ["--lighting-spread", "0"]),
    ("light04", "lighting spread 0.4", ["--lighting-spread", "0.4"]),
    ("noblur", "no motion blur (exposure 0)", ["--exposure", "0"]),
    ("blur30", "blur x3 (exposure 30 ms)", ["--exposure", "0.03"]),
    ("unique", "unique décor (no aliasing)", ["--decor", "unique"]),
]
# What the closure gate does against aliasing: the repeated and the unique décor again, gate off.
GATE_OFF = [("baseline", "closure gate off, repeated décor"), ("unique", "closure gate off, unique décor")]


def sh(*cmd):
    r = subprocess.run(list(cmd), capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"pixels_eval: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr.strip()}")
    return r.stdout


def generate(args, out, extra):
    if os.path.exists(os.path.join(out, "map.db")):
        return  # cached from an earlier invocation with the same arguments
    sh(args.zonemap, "sim", "hospital", "--seed", str(args.seed), "--area", str(args.area),
       "--tasks", str(args.tasks), "--footprint-scale", str(args.scale), "--quiet", "--out", out,
       *extra)


def keyframes(scenario):
    with open(os.path.join(scenario, "scenario.json")) as f:
        return int(json.load(f)["counts"]["keyframes"])


def gate_off_profile(out_dir):
    """The host profile with closure_gate_m = 0 (the gate off), written beside the runs."""
    src = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "profiles", "host.toml")
    lines = open(src).read().splitlines()
    i = lines.index("[localization]")
    lines.insert(i + 1, "closure_gate_m = 0.0  # pixels_eval: the closure gate off")
    path = os.path.join(out_dir, "host_gate_off.toml")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def run(args, scenario, policy, memory_thr, out, profile=None):
    sh(args.zonemap, "run", "--scenario", scenario, "--policy", policy, "--memory-thr",
       str(memory_thr), "--time-compression", "0", "--device", "ledger", "--out", out,
       *(["--profile", profile] if profile else []))
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    ticks = []
    with open(os.path.join(out, "ticks.jsonl")) as f:
        for line in f:
            ticks.append(json.loads(line))
    return summary, ticks


def pct(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))] if v else float("nan")


def robustness(args, memory_thr_of):
    print("\n### Robustness: one change at a time, semantic policy\n")
    print("| variant | frames localized / ticks | closures rejected | ATE (m) | tick p50 / p99 (ms) |"
          " features per frame (p50) |")
    print("|---|---:|---:|---:|---:|---:|")
    gate_off = gate_off_profile(args.out)
    rows = [(key, name, extra, None) for key, name, extra in VARIANTS]
    rows += [(key, name, dict((k, e) for k, _, e in VARIANTS)[key], gate_off) for key, name in GATE_OFF]
    for key, name, extra, profile in rows:
        scen = os.path.join(args.out, "scenarios", key)
        generate(args, scen, extra)
        s, ticks = run(args, scen, "semantic", memory_thr_of(scen),
                       os.path.join(args.out, "runs", key + ("_gate_off" if profile else "")), profile)
        feats = [t.get("features", 0) for t in ticks]
        print(f"| {name} | {s['frames_localized']} / {s['ticks']} | {s['closures_rejected']} | "
              f"{s['ate_rmse_m']:.3f} | {s['tick_ms']['p50']:.1f} / {s['tick_ms']['p99']:.1f} | "
              f"{pct(feats, 0.5):.0f} |")


def slope(args, memory_thr_of):
    scen = os.path.join(args.out, "scenarios", "baseline")
    generate(args, scen, [])
    print(f"\n### Likelihood over the resident keyframes ({keyframes(scen)} keyframes, "
          f"MemoryThr {memory_thr_of(scen)} for basic and semantic)\n")
    print("| policy | resident keyframes (p50) | likelihood p50 (ms) | per resident keyframe (us, p50)"
          " | postings walked (p50) | frames localized / ticks | tick p50 (ms) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    xs, ys = [], []
    for policy in ("unbounded", "basic", "semantic"):
        thr = keyframes(scen) if policy == "unbounded" else memory_thr_of(scen)
        s, ticks = run(args, scen, policy, thr, os.path.join(args.out, "runs", "slope_" + policy))
        rows = [t for t in ticks if t.get("stages_ms", {}).get("likelihood", 0) > 0
                and t.get("resident_keyframes", 0) > 0]
        res = [t["resident_keyframes"] for t in rows]
        lik = [t["stages_ms"]["likelihood"] for t in rows]
        per = [1000.0 * l / r for l, r in zip(lik, res)]
        post = [t.get("postings_walked", 0) for t in rows]
        xs += res
        ys += lik
        print(f"| {policy} | {pct(res, 0.5):.0f} | {pct(lik, 0.5):.3f} | {pct(per, 0.5):.2f} | "
              f"{pct(post, 0.5):.0f} | {s['frames_localized']} / {s['ticks']} | "
              f"{s['tick_ms']['p50']:.1f} |")
    if len(xs) > 2 and statistics.pvariance(xs) > 0:
        b, a = statistics.linear_regression(xs, ys)
        print(f"\nLeast squares over all three policies' ticks: likelihood = {a:.3f} ms + "
              f"{1000.0 * b:.2f} us x resident keyframes ({len(xs)} ticks).")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("zonemap")
    ap.add_argument("out")
    ap.add_argument("--area", type=float, default=800)
    ap.add_argument("--tasks", type=int, default=4)
    ap.add_argument("--scale", type=float, default=0.25)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--memory-thr-share", type=float, default=0.4,
                    help="MemoryThr of basic and semantic as a share of the map's keyframes")
    ap.add_argument("--skip-robustness", action="store_true")
    ap.add_argument("--skip-slope", action="store_true")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    def memory_thr_of(scen):
        return max(1, int(args.memory_thr_share * keyframes(scen)))

    print(f"pixels_eval: zonemap sim hospital --seed {args.seed} --area {args.area:.0f} --tasks "
          f"{args.tasks} --footprint-scale {args.scale}; load average {os.getloadavg()[0]:.1f}")
    if not args.skip_robustness:
        robustness(args, memory_thr_of)
    if not args.skip_slope:
        slope(args, memory_thr_of)


if __name__ == "__main__":
    main()
