#!/usr/bin/env python3
"""Figures of a `zonemap bench` output directory (matplotlib, PNG).

Reads OUT/runs/<scenario>/<run>/{summary.json,ticks.jsonl,estimate.tum,cotenant.json} and
OUT/scenarios/<scenario>/{zones.geojson,localization_gt.tum} and writes OUT/figures/:

  memory_<scenario>.png        resident keyframes over time per policy, with and without the
                               co-tenant (the paper's memory-usage figure), MemoryThr marked
  trajectories_<scenario>.png  ground truth against each policy's estimate, loop closures marked
  zones_<scenario>.png         the zone map with the route, coloured by the active zone
  cotenant_<scenario>.png      co-tenant tokens/s and latency per policy (distributions), and
                               tokens/s along the robot's path (stand-in co-tenant)
  latency_<scenario>.png       tick time per policy after start-up: its CDF (log time axis,
                               p99 marked) and its tail (the share of ticks slower than t, log-log:
                               the slow ticks a load inside a tick makes) (issue 14)

Usage: scripts/plots.py OUT
"""
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

POLICY_COLOURS = {
    "unbounded": "#7f7f7f",
    "basic": "#d62728",
    "radius": "#ff7f0e",
    "semantic": "#1f77b4",
    "predictive": "#2ca02c",
    "oracle": "#9467bd",
}


def read_jsonl(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line:
                rows.append(json.loads(line))
    return rows


def read_tum(path):
    pts = []
    if not os.path.exists(path):
        return pts
    with open(path) as f:
        for line in f:
            if not line.strip() or line.startswith("#"):
                continue
            v = line.split()
            pts.append((float(v[0]), float(v[1]), float(v[2])))
    return pts


def runs_of(out, scenario):
    base = os.path.join(out, "runs", scenario)
    runs = []
    if not os.path.isdir(base):
        return runs
    for name in sorted(os.listdir(base)):
        d = os.path.join(base, name)
        s = os.path.join(d, "summary.json")
        if os.path.exists(s):
            with open(s) as f:
                runs.append((name, d, json.load(f)))
    return runs


def colour(policy):
    return POLICY_COLOURS.get(policy, "#17becf")


def plot_memory(out, scenario, runs, fig_dir):
    with_ct = [r for r in runs if r[2].get("cotenant")]
    without = [r for r in runs if not r[2].get("cotenant")]
    panels = [("without co-tenant", without), ("with co-tenant (stand-in)", with_ct)]
    panels = [p for p in panels if p[1]]
    if not panels:
        return
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 3.6 * len(panels)), squeeze=False)
    for ax, (title, group) in zip(axes[:, 0], panels):
        thr = None
        for name, d, s in group:
            ticks = read_jsonl(os.path.join(d, "ticks.jsonl"))
            if not ticks:
                continue
            xs = [t["tick"] for t in ticks]
            ys = [t["resident_keyframes"] for t in ticks]
            label = f'{run_label(s)} (peak {s.get("peak_resident_keyframes", max(ys))})'
            ax.plot(xs, ys, color=colour(s["policy"]), lw=1.2, label=label)
            if s["policy"] not in ("unbounded",):
                thr = s.get("k_max", thr)
        if thr:
            ax.axhline(thr, color="k", ls="--", lw=0.8, label=f"MemoryThr = {thr}")
        ax.set_title(f"{scenario}: resident keyframes, {title}")
        ax.set_xlabel("tick")
        ax.set_ylabel("resident keyframes")
        ax.legend(fontsize=8, loc="upper right")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(fig_dir, f"memory_{scenario}.png"), dpi=110)
    plt.close(fig)


def plot_trajectories(out, scenario, runs, fig_dir):
    gt = read_tum(os.path.join(out, "scenarios", scenario, "localization_gt.tum"))
    group = [r for r in runs if not r[2].get("cotenant")] or runs
    if not group:
        return
    n = len(group)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 4.5 * rows), squeeze=False)
    for i, (name, d, s) in enumerate(group):
        ax = axes[i // cols][i % cols]
        if gt:
            ax.plot([p[1] for p in gt], [p[2] for p in gt], color="k", lw=0.8, zorder=2,
                    label="ground truth")
        est = read_tum(os.path.join(d, "estimate.tum"))
        if est:
            ax.plot([p[1] for p in est], [p[2] for p in est], color=colour(s["policy"]), lw=0.8, zorder=3,
                    label=f'{run_label(s)} (ATE {s.get("ate_rmse_m", float("nan")):.2f} m)')
        ticks = read_jsonl(os.path.join(d, "ticks.jsonl"))
        lc = [(t["x"], t["y"]) for t in ticks if t.get("loop_closure")]
        if lc:
            shown = lc[:: max(1, len(lc) // 150)]  # a mark per stretch, not per tick
            ax.scatter([p[0] for p in shown], [p[1] for p in shown], s=3, alpha=0.5,
                       color="#bcbd22", zorder=1, label=f"loop closures ({len(lc)}, subsampled)")
        ax.set_aspect("equal")
        ax.set_title(name, fontsize=9)
        ax.legend(fontsize=7)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(fig_dir, f"trajectories_{scenario}.png"), dpi=110)
    plt.close(fig)


def plot_zones(out, scenario, runs, fig_dir):
    path = os.path.join(out, "scenarios", scenario, "zones.geojson")
    if not os.path.exists(path):
        return
    with open(path) as f:
        gj = json.load(f)
    fig, ax = plt.subplots(figsize=(10, 8))
    cmap = plt.get_cmap("tab20")
    for i, feat in enumerate(gj.get("features", [])):
        ring = feat["geometry"]["coordinates"][0]
        xs = [p[0] for p in ring]
        ys = [p[1] for p in ring]
        kind = feat.get("properties", {}).get("kind", "")
        ax.fill(xs, ys, color=cmap(i % 20), alpha=0.25 if kind != "corridor" else 0.12)
        ax.plot(xs, ys, color="k", lw=0.3)
    semantic = [r for r in runs if r[2]["policy"] == "semantic" and not r[2].get("cotenant")]
    if semantic:
        ticks = read_jsonl(os.path.join(semantic[0][1], "ticks.jsonl"))
        xs = [t["x"] for t in ticks]
        ys = [t["y"] for t in ticks]
        zs = [t["zone"] for t in ticks]
        sc = ax.scatter(xs, ys, c=zs, cmap="tab20", s=2)
        fig.colorbar(sc, ax=ax, label="active zone id along the route (semantic)")
    ax.set_aspect("equal")
    ax.set_title(f"{scenario}: zones and the patrol route")
    fig.tight_layout()
    fig.savefig(os.path.join(fig_dir, f"zones_{scenario}.png"), dpi=110)
    plt.close(fig)


def plot_cotenant(out, scenario, runs, fig_dir):
    group = [r for r in runs if r[2].get("cotenant")]
    if not group:
        return
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    labels, tps, lat = [], [], []
    for name, d, s in group:
        ct = s["cotenant"]
        labels.append(f'{s["policy"]}\n{ct.get("model", "")}')
        path = os.path.join(d, "cotenant.json")
        detail = {}
        if os.path.exists(path):
            with open(path) as f:
                detail = json.load(f)
        per = detail.get("per_request") or []
        tps.append([p[1] for p in per] or [ct.get("tokens_per_s") or 0.0])
        lat.append([p[2] for p in per] or [ct.get("latency_ms") or 0.0])
    axes[0].boxplot(tps, labels=labels)
    axes[0].set_title("co-tenant tokens/s per request (stand-in)")
    axes[1].boxplot(lat, labels=labels)
    axes[1].set_title("co-tenant latency per request, ms (stand-in)")
    for name, d, s in group:
        path = os.path.join(d, "cotenant.json")
        if not os.path.exists(path):
            continue
        with open(path) as f:
            detail = json.load(f)
        per = detail.get("per_request") or []
        ticks = read_jsonl(os.path.join(d, "ticks.jsonl"))
        pace = s.get("pace_speedup") or 0.0
        if not per or not ticks or pace <= 0:
            continue
        # Request end (wall seconds) -> frame stamp on the paced clock -> robot position.
        t0 = ticks[0]["stamp"]
        xs, ys, cs = [], [], []
        for end_s, rate, _ in per:
            stamp = t0 + end_s * pace
            tick = min(ticks, key=lambda t: abs(t["stamp"] - stamp))
            xs.append(tick["x"]); ys.append(tick["y"]); cs.append(rate)
        sc = axes[2].scatter(xs, ys, c=cs, cmap="viridis", s=18, marker="o",
                             label=s["policy"])
    axes[2].set_title("tokens/s where each request ended (stand-in)")
    axes[2].set_xlabel("x (m)")
    axes[2].set_ylabel("y (m)")
    axes[2].set_aspect("equal")
    axes[2].legend(fontsize=8)
    for ax in axes[:2]:
        ax.tick_params(axis="x", labelsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(fig_dir, f"cotenant_{scenario}.png"), dpi=110)
    plt.close(fig)


def run_label(summary):
    """A run's name in the figures: the policy, marked when its loads were not time-sliced."""
    loads = summary.get("loads") or {}
    return summary["policy"] + ("" if loads.get("sliced", True) else " (unsliced)")


def plot_latency(out, scenario, runs, fig_dir):
    group = [r for r in runs if not r[2].get("cotenant")] or runs
    series = []
    for name, d, s in group:
        ticks = read_jsonl(os.path.join(d, "ticks.jsonl"))
        ms = [t["tick_ms"] for t in ticks if not t.get("startup")]
        if ms:
            series.append((run_label(s), s["policy"], ms, (s.get("startup") or {}).get("tick_ms")))
    if not series:
        return
    fig, axes = plt.subplots(1, 2, figsize=(15, 5))
    for lab, pol, ms, startup in series:
        v = sorted(ms)
        n = len(v)
        p99 = v[max(0, math.ceil(0.99 * n) - 1)]  # nearest rank, as StreamingStats
        ls = "--" if lab.endswith("(unsliced)") else "-"
        axes[0].step(v, [(i + 1) / n for i in range(n)], where="post", color=colour(pol), ls=ls,
                     lw=1.3, label=f"{lab}: p99 {p99:.1f} ms, max {v[-1]:.0f} ms")
        axes[0].plot([p99], [0.99], "o", color=colour(pol), ms=4)
        axes[1].step(v, [(n - i - 1) / n if i < n - 1 else 0.5 / n for i in range(n)], where="post",
                     color=colour(pol), ls=ls, lw=1.3,
                     label=lab + (f" (start-up tick {startup:.0f} ms, apart)" if startup else ""))
    axes[0].set_xscale("log")
    axes[0].set_xlabel("tick time after start-up (ms, log scale)")
    axes[0].set_ylabel("fraction of ticks")
    axes[0].axhline(0.99, color="k", lw=0.5, ls=":")
    axes[0].set_title(f"{scenario}: tick time CDF per policy")
    axes[0].legend(fontsize=7, loc="lower right")
    axes[0].grid(alpha=0.3, which="both")
    axes[1].set_xscale("log")
    axes[1].set_yscale("log")
    axes[1].axhline(0.01, color="k", lw=0.5, ls=":")
    axes[1].set_xlabel("tick time after start-up (ms, log scale)")
    axes[1].set_ylabel("fraction of ticks slower (log scale)")
    axes[1].set_title("the tail: where loads inside a tick show")
    axes[1].legend(fontsize=7, loc="lower left")
    axes[1].grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(os.path.join(fig_dir, f"latency_{scenario}.png"), dpi=110)
    plt.close(fig)


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    out = sys.argv[1]
    fig_dir = os.path.join(out, "figures")
    os.makedirs(fig_dir, exist_ok=True)
    runs_dir = os.path.join(out, "runs")
    if not os.path.isdir(runs_dir):
        print(f"plots.py: {runs_dir} does not exist (run `zonemap bench` first)", file=sys.stderr)
        sys.exit(1)
    for scenario in sorted(os.listdir(runs_dir)):
        runs = runs_of(out, scenario)
        plot_memory(out, scenario, runs, fig_dir)
        plot_trajectories(out, scenario, runs, fig_dir)
        plot_zones(out, scenario, runs, fig_dir)
        plot_cotenant(out, scenario, runs, fig_dir)
        plot_latency(out, scenario, runs, fig_dir)
    print(f"plots.py: figures in {fig_dir}")


if __name__ == "__main__":
    main()
