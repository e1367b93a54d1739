#!/usr/bin/env python3
"""Figures of a `zonemap bench` output directory (matplotlib, PNG): the paper's four figures
from the runs themselves (issue 17 §6), plus the zone map and the tick latency.

Reads OUT/runs/<scenario>/<run>/{summary.json,ticks.jsonl,estimate.tum,cotenant.jsonl,
cotenant.json} and OUT/scenarios/<scenario>/{zones.geojson,localization_gt.tum}; writes
OUT/figures/:

  memory_<scenario>.png        (a) memory over time in BYTES, Basic + VLM and Semantic + VLM side
                               by side (same axes): the map process's RSS, the co-tenant's RSS,
                               the device's usage (the cgroup's charge, or the ledger's sum), the
                               device limit, the map's MemoryThr in bytes; OOM kills and
                               co-tenant deaths marked
  trajectories_<scenario>.png  (b) ground truth, Basic only, Basic + VLM and Semantic + VLM in one
                               plot, Basic + VLM's last accepted loop closure marked
  cotenant_<scenario>.png      (c) the co-tenant's tokens/s and latency per request as PDF and CDF,
                               one curve per policy (stand-in co-tenant)
  cotenant_path_<scenario>.png (d) tokens/s and latency along the robot's path, one panel per
                               policy (each request placed where the robot was when it ended)
  timeline_<scenario>.png      (e) per co-tenant run, each request's decode tokens/s and latency
                               against the wall clock (a bar from its start to its end) over the
                               device's usage and, where the run recorded it, its swap
                               (ticks.jsonl's device_usage_bytes, device_swap_bytes,
                               map_swap_bytes), the device limit, OOM kills and co-tenant deaths
  zones_<scenario>.png         the zone map with the route, coloured by the active zone
  latency_<scenario>.png       tick time per policy after start-up: CDF and tail (issue 14)
  trajectories_all_<scenario>.png  every policy's estimate apart (only when more policies ran
                               than the paper's two)

Every figure states the device (cgroup or simulated ledger), its scale and the time compression.
With repeats (`zonemap bench --repeat N`) each configuration is drawn from one representative
repeat: the one whose mean tick time is nearest the median of its repeats (results.json's
`representative_repeat`, chosen by the bench; rep0 when results.json is missing); the footnote
says which.

Usage: scripts/plots.py OUT      (OUT may also be one run directory)
"""
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runs as R  # noqa: E402

POLICY_COLOURS = {
    "unbounded": "#7f7f7f",
    "basic": "#d62728",
    "radius": "#ff7f0e",
    "semantic": "#1f77b4",
    "predictive": "#2ca02c",
    "oracle": "#9467bd",
}
# The four configurations of the paper: colour by policy, line style by co-tenant.
CONFIG_STYLE = {
    ("basic", False): dict(color="#ff9896", ls="-"),
    ("basic", True): dict(color="#d62728", ls="-"),
    ("semantic", False): dict(color="#aec7e8", ls="-"),
    ("semantic", True): dict(color="#1f77b4", ls="-"),
}
GB = 1e9


def colour(policy):
    return POLICY_COLOURS.get(policy, "#17becf")


def style(run):
    return CONFIG_STYLE.get((run.policy, run.with_vlm), dict(color=colour(run.policy), ls="--"))


def savefig(fig, fig_dir, name):
    fig.savefig(os.path.join(fig_dir, name), dpi=110)
    plt.close(fig)


def footnote(fig, run, group=None):
    reps = ""
    shown = [r for r in (group or [run]) if r is not None and r.n > 1]
    if shown:
        reps = "; repeat shown (mean tick time nearest the median): " + ", ".join(
            f"{r.label} {r.representative + 1}/{r.n}" for r in shown)
    fig.text(0.005, 0.005, R.device_text(run) + "; co-tenant: a stand-in for VLM decoding" + reps,
             fontsize=7, color="#555555", ha="left", va="bottom")


def vlm_runs(runs):
    """The co-tenant runs to set side by side: Basic + VLM and Semantic + VLM first, then any
    other policy's (the bench matrix), one model: the profile's (the first co-tenant run's)."""
    with_ct = [r for r in runs if r.with_vlm and "unsliced" not in r.label]
    if not with_ct:
        return []
    model = (R.pick(runs, "basic", True) or R.pick(runs, "semantic", True) or with_ct[0]).model
    chosen = [R.pick(runs, p, True, model) for p in ("basic", "semantic")]
    chosen = [r for r in chosen if r is not None]
    for r in with_ct:
        if r.model == model and r.policy not in ("basic", "semantic") and r not in chosen:
            chosen.append(r)
    return chosen


# (a) memory over time, in bytes ----------------------------------------------------------------

def plot_memory(scenario, runs, fig_dir):
    group = vlm_runs(runs)
    if not group:  # no co-tenant ran: each policy's own memory, still in bytes
        group = [r for r in (R.pick(runs, "basic", False), R.pick(runs, "semantic", False)) if r]
        group = group or runs[:2]
    if not group:
        return
    fig, axes = plt.subplots(1, len(group), figsize=(6.5 * len(group), 4.6), squeeze=False,
                             sharey=True)
    for ax, run in zip(axes[0], group):
        ticks = run.ticks()
        if not ticks:
            ax.set_title(f"{run.label}: no ticks")
            continue
        xs, xlabel = run.tick_times()
        d = run.s.get("device") or {}
        have_device = any("device_usage_bytes" in t for t in ticks)

        def series(key):
            return [t.get(key, math.nan) / GB if t.get(key) is not None else math.nan for t in ticks]

        if any("map_rss_bytes" in t for t in ticks):
            ax.plot(xs, series("map_rss_bytes"), color=style(run)["color"], lw=1.4,
                    label="map process (RSS)")
        else:  # before issue 17: the keyframes the map held
            ax.plot(xs, series("resident_bytes"), color=style(run)["color"], lw=1.4,
                    label="map: resident keyframe bytes (no RSS recorded)")
        if any("cotenant_rss_bytes" in t for t in ticks):
            ax.plot(xs, series("cotenant_rss_bytes"), color="#2ca02c", lw=1.2,
                    label="co-tenant (RSS, stand-in)")
        if have_device:
            ax.plot(xs, series("device_usage_bytes"), color="k", lw=1.0, alpha=0.8,
                    label=f'device usage ({d.get("kind", "?")})')
        if any(t.get("device_limit_bytes") for t in ticks) and d.get("swap", {}).get("zram_charged"):
            ax.plot(xs, series("device_limit_bytes"), color="k", lw=1.0, ls="-.",
                    label="limit in force (device − zram's store)")
        limit = d.get("limit_bytes")
        if not limit and d.get("memory_bytes"):
            limit = d["memory_bytes"] - d.get("os_reserve_bytes", 0)
        if limit:
            ax.axhline(limit / GB, color="k", ls="--", lw=1.0,
                       label=f"device limit {limit / GB:.2f} GB")
        if run.k_max and run.s.get("slot_bytes"):
            thr = run.k_max * run.s["slot_bytes"]
            ax.axhline(thr / GB, color=style(run)["color"], ls=":", lw=1.0,
                       label=f"MemoryThr {run.k_max} kf = {thr / GB:.2f} GB")
        # OOM kills: where the device's counter steps up.
        prev, kills = 0, []
        for x, t in zip(xs, ticks):
            k = t.get("oom_kills", t.get("oom_events", 0)) or 0
            if k > prev:
                kills.append((x, k - prev))
            prev = max(prev, k)
        for i, (x, n) in enumerate(kills):
            ax.axvline(x, color="#9467bd", lw=1.2, ls="-.",
                       label=f"OOM kill ({sum(k for _, k in kills)} in all)" if i == 0 else None)
            ax.annotate(f"OOM x{n}" if n > 1 else "OOM", (x, 0.0),
                        xycoords=("data", "axes fraction"), xytext=(2, 4),
                        textcoords="offset points", fontsize=7, color="#9467bd")
        for i, x in enumerate(run.cotenant_deaths()):
            ax.plot([x], [0.97], marker="v", color="#2ca02c", ms=9, transform=ax.get_xaxis_transform(),
                    ls="none", label="co-tenant killed (restarted)" if i == 0 else None)
        if xlabel == "wall clock (s)" and ticks[0].get("startup") and xs[0] > 0:
            # The start-up tick loads the map's last working memory before any frame is
            # processed: its wall time, and the frames that arrived meanwhile, are dropped frames.
            ax.axvspan(0, xs[0], color="#dddddd", alpha=0.6, zorder=0,
                       label=f"start-up load ({xs[0]:.0f} s, {ticks[0].get('tick_ms', 0) / 1e3:.0f} s"
                             " tick; frames dropped)")
            ax.set_xlim(left=0)
        outcome = (run.s.get("map") or {}).get("outcome")
        ct = run.s.get("cotenant") or {}
        title = run.label + (f" ({run.model})" if run.with_vlm else "")
        sub = []
        if outcome:
            sub.append(f"map {outcome}")
        if ct.get("outcome"):
            sub.append(f'co-tenant {ct.get("symbol", "")} {ct["outcome"]}'.replace("  ", " "))
        if d.get("peak_bytes"):
            sub.append(f'peak {d["peak_bytes"] / GB:.2f} GB')
        ax.set_title(title + ("\n" + ", ".join(sub) if sub else ""), fontsize=10)
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
        ax.set_ylim(bottom=0)
    axes[0][0].set_ylabel("memory (GB)")
    fig.suptitle(f"{scenario}: memory over time", fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    footnote(fig, group[0], group)
    savefig(fig, fig_dir, f"memory_{scenario}.png")


# (b) trajectories ------------------------------------------------------------------------------

def last_closure(run):
    """(x, y, time, tick) of the last tick with an accepted loop closure, or None."""
    ticks = run.ticks()
    xs, _ = run.tick_times()
    for x_t, t in zip(reversed(xs), reversed(ticks)):
        if t.get("loop_closure"):
            return t.get("x"), t.get("y"), x_t, t.get("tick")
    return None


def plot_trajectories(out, scenario, runs, fig_dir):
    gt = R.read_tum(os.path.join(out, "scenarios", scenario, "localization_gt.tum"))
    chosen = [(R.pick(runs, p, v), p, v) for p, v in R.CONFIGS]
    chosen = [(r, p, v) for r, p, v in chosen if r is not None]
    if not chosen and not gt:
        return
    fig, ax = plt.subplots(figsize=(10, 8))
    if gt:
        ax.plot([p[1] for p in gt], [p[2] for p in gt], color="k", lw=1.6, zorder=2,
                label="ground truth")
    for run, p, v in chosen:
        est = R.read_tum(os.path.join(run.path, "estimate.tum"))
        if not est:
            continue
        ate = run.s.get("ate_rmse_m")
        st = style(run)
        ax.plot([q[1] for q in est], [q[2] for q in est], color=st["color"], lw=1.0, zorder=3,
                ls="--" if not v else "-",
                label=f'{R.config_name(p, v)} (ATE {ate:.2f} m, {R.closures_accepted(run.s)} '
                      f'loop closures)' if ate is not None else R.config_name(p, v))
    b = R.pick(runs, "basic", True)
    if b is not None:
        lc = last_closure(b)
        if lc and lc[0] is not None:
            ax.scatter([lc[0]], [lc[1]], marker="*", s=260, color="#d62728", edgecolor="k",
                       zorder=5, label=f"Basic + VLM: last accepted loop closure (tick {lc[3]})")
        est = R.read_tum(os.path.join(b.path, "estimate.tum"))
        if est and (b.s.get("map") or {}).get("outcome") == "killed":
            ax.scatter([est[-1][1]], [est[-1][2]], marker="X", s=120, color="#9467bd", zorder=5,
                       label="Basic + VLM: map process killed here")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{scenario}: trajectories (estimate in the map frame, unaligned)")
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.2)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    if chosen:
        footnote(fig, chosen[0][0], [c[0] for c in chosen])
    savefig(fig, fig_dir, f"trajectories_{scenario}.png")


def plot_trajectories_all(out, scenario, runs, fig_dir):
    """Every policy's estimate in a panel of its own: the bench matrix beyond the paper's two."""
    group = [r for r in runs if not r.with_vlm]
    if len({r.policy for r in group}) <= 2:
        return
    gt = R.read_tum(os.path.join(out, "scenarios", scenario, "localization_gt.tum"))
    n = len(group)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 4.5 * rows), squeeze=False)
    for i, run in enumerate(group):
        ax = axes[i // cols][i % cols]
        if gt:
            ax.plot([p[1] for p in gt], [p[2] for p in gt], color="k", lw=0.8, label="ground truth")
        est = R.read_tum(os.path.join(run.path, "estimate.tum"))
        if est:
            ax.plot([p[1] for p in est], [p[2] for p in est], color=colour(run.policy), lw=0.8,
                    label=f'{run.label} (ATE {run.s.get("ate_rmse_m", float("nan")):.2f} m)')
        ax.set_aspect("equal")
        ax.set_title(run.name, fontsize=9)
        ax.legend(fontsize=7)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    fig.tight_layout()
    savefig(fig, fig_dir, f"trajectories_all_{scenario}.png")


# (c) co-tenant tokens/s and latency: PDF and CDF -----------------------------------------------

def pdf_step(ax, values, span, **kw):
    """A density histogram drawn as a step curve, on bins shared by every run of the panel (with
    ~30 requests per run a histogram is honest; no smoothing is invented)."""
    import numpy as np
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return
    bins = max(5, min(30, int(math.sqrt(v.size)) * 2))
    lo, hi = span
    if hi <= lo:
        hi = lo + max(1e-9, abs(lo) * 0.01)
    h, edges = np.histogram(v, bins=bins, range=(lo, hi), density=True)
    ax.stairs(h, edges, **kw)


def cdf_step(ax, values, **kw):
    v = sorted(values)
    n = len(v)
    if n:
        ax.step(v, [(i + 1) / n for i in range(n)], where="post", **kw)


def plot_cotenant(scenario, runs, fig_dir):
    group = [r for r in vlm_runs(runs) if r.requests()]
    if not group:
        return
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    all_tps = [q["tokens_per_s"] for r in group for q in r.requests()]
    all_lat = [q["latency_ms"] / 1000.0 for r in group for q in r.requests()]
    tps_span, lat_span = (min(all_tps), max(all_tps)), (min(all_lat), max(all_lat))
    for run in group:
        req = run.requests()
        tps = [q["tokens_per_s"] for q in req]
        lat = [q["latency_ms"] / 1000.0 for q in req]
        ct = run.s.get("cotenant") or {}
        lab = f'{run.label}: {len(req)} requests, {ct.get("symbol", "")} {ct.get("outcome", "")}'.strip()
        st = style(run)
        pdf_step(axes[0][0], tps, tps_span, color=st["color"], lw=1.5, label=lab)
        cdf_step(axes[0][1], tps, color=st["color"], lw=1.5, label=lab)
        pdf_step(axes[1][0], lat, lat_span, color=st["color"], lw=1.5, label=lab)
        cdf_step(axes[1][1], lat, color=st["color"], lw=1.5, label=lab)
    axes[0][0].set_xlabel("decode tokens/s per request")
    axes[0][1].set_xlabel("decode tokens/s per request")
    axes[1][0].set_xlabel("request latency (s)")
    axes[1][1].set_xlabel("request latency (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("probability density")
    for ax in axes[:, 1]:
        ax.set_ylabel("fraction of requests")
        ax.set_ylim(0, 1.02)
    for ax in axes.flat:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0][0].set_title("tokens/s: PDF")
    axes[0][1].set_title("tokens/s: CDF")
    axes[1][0].set_title("latency: PDF")
    axes[1][1].set_title("latency: CDF")
    fig.suptitle(f"{scenario}: the co-tenant beside the map ({group[0].model}, stand-in)",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    footnote(fig, group[0], group)
    savefig(fig, fig_dir, f"cotenant_{scenario}.png")


# (d) tokens/s and latency along the robot's path -----------------------------------------------

def position_at(run, wall_s):
    """Where the robot was (the tick's x, y) at a wall-clock time: the last tick at or before it."""
    ticks = run.ticks()
    xs, _ = run.tick_times()
    if not ticks:
        return None
    import bisect
    i = bisect.bisect_right(xs, wall_s) - 1
    i = min(max(i, 0), len(ticks) - 1)
    t = ticks[i]
    if "x" not in t:
        return None
    when = "after" if wall_s > xs[-1] + 1.0 else "startup" if wall_s < xs[0] else "during"
    return t["x"], t["y"], when  # after the last tick the map had stopped; before the first it loaded


def plot_cotenant_path(out, scenario, runs, fig_dir):
    group = [r for r in vlm_runs(runs) if r.requests()]
    if not group:
        return
    gt = R.read_tum(os.path.join(out, "scenarios", scenario, "localization_gt.tum"))
    cols = len(group)
    fig, axes = plt.subplots(2, cols, figsize=(6 * cols, 9.5), squeeze=False)
    placed = {}
    for run in group:
        pts = []
        for q in run.requests():
            p = position_at(run, q["wall_s"])
            if p is not None:
                pts.append((p[0], p[1], q["tokens_per_s"], q["latency_ms"] / 1000.0, p[2]))
        placed[run.name] = pts
    all_pts = [p for v in placed.values() for p in v]
    if not all_pts:
        plt.close(fig)
        return
    ranges = [(min(p[2] for p in all_pts), max(p[2] for p in all_pts)),
              (min(p[3] for p in all_pts), max(p[3] for p in all_pts))]
    for c, run in enumerate(group):
        pts = placed[run.name]
        for row, (key, cmap, lab) in enumerate([(2, "viridis", "tokens/s"),
                                                (3, "magma_r", "latency (s)")]):
            ax = axes[row][c]
            if gt:
                ax.plot([p[1] for p in gt], [p[2] for p in gt], color="#bbbbbb", lw=0.8, zorder=1)
            ticks = run.ticks()
            if ticks and "x" in ticks[0]:
                ax.plot([t["x"] for t in ticks], [t["y"] for t in ticks], color="#666666",
                        lw=0.6, zorder=2)
            during = [p for p in pts if p[4] == "during"]
            after = [p for p in pts if p[4] == "after"]
            startup = [p for p in pts if p[4] == "startup"]
            sc = None
            for sub, marker, note in ((during, "o", None),
                                      (startup, "s", "ended during the map's start-up load "
                                                     "(placed at the start pose)"),
                                      (after, "X", "ended after the map stopped (placed at its "
                                                   "last pose)")):
                if sub:
                    sc = ax.scatter([p[0] for p in sub], [p[1] for p in sub],
                                    c=[p[key] for p in sub], cmap=cmap, vmin=ranges[row][0],
                                    vmax=ranges[row][1], s=36 if marker == "o" else 60,
                                    marker=marker, edgecolor="k", linewidth=0.3, zorder=3,
                                    label=f"{len(sub)} {note}" if note else None)
            if sc is not None:
                fig.colorbar(sc, ax=ax, label=lab, shrink=0.8)
            if after or startup:
                ax.legend(fontsize=7, loc="lower right")
            ax.set_aspect("equal")
            ax.set_title(f"{run.label}: {lab} ({len(pts)} requests)", fontsize=10)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
    fig.suptitle(f"{scenario}: the co-tenant along the robot's path (each request where the "
                 f"robot was when it ended)", fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    footnote(fig, group[0], group)
    savefig(fig, fig_dir, f"cotenant_path_{scenario}.png")


# (e) the per-request timeline over the device's memory ----------------------------------------

def plot_timeline(scenario, runs, fig_dir):
    """Per co-tenant run: each request's decode tokens/s and latency on the wall clock (a bar
    from its start to its end, so a request held up by pressure shows as a long bar), over the
    device's usage and swap from the map process's ticks (the same clock, docs/harness.md)."""
    group = [r for r in vlm_runs(runs) if r.requests() or r.ticks()]
    if not group:
        return
    cols = len(group)
    fig, axes = plt.subplots(2, cols, figsize=(7 * cols, 7.5), squeeze=False, sharex="col",
                             gridspec_kw={"height_ratios": [1.2, 1]})
    tps_max = max([q["tokens_per_s"] for r in group for q in r.requests()] or [1.0])
    for c, run in enumerate(group):
        top, bottom = axes[0][c], axes[1][c]
        req = run.requests()
        twin = top.twinx()
        for i, q in enumerate(req):
            start = q.get("started_wall_s")
            if start is None:
                start = q["wall_s"] - q["latency_ms"] / 1000.0
            top.plot([start, q["wall_s"]], [q["tokens_per_s"]] * 2, color=style(run)["color"],
                     lw=2.2, solid_capstyle="butt",
                     label="decode tokens/s (bar: request start → end)" if i == 0 else None)
        twin.plot([q["wall_s"] for q in req], [q["latency_ms"] / 1000.0 for q in req], "o",
                  color="#555555", ms=4, label="latency (s), at the request's end")
        top.set_ylim(0, tps_max * 1.15)
        twin.set_ylim(bottom=0)
        top.set_ylabel("decode tokens/s")
        twin.set_ylabel("request latency (s)")
        ct = run.s.get("cotenant") or {}
        top.set_title(f'{run.label} ({run.model}): {len(req)} requests, '
                      f'{ct.get("symbol", "")} {ct.get("outcome", "")}'.replace("  ", " "),
                      fontsize=10)
        h1, l1 = top.get_legend_handles_labels()
        h2, l2 = twin.get_legend_handles_labels()
        top.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper right")
        top.grid(alpha=0.3)

        ticks = run.ticks()
        xs, xlabel = run.tick_times()
        d = run.s.get("device") or {}

        def series(key):
            return [t[key] / GB if t.get(key) is not None else math.nan for t in ticks]

        if any("device_usage_bytes" in t for t in ticks):
            bottom.plot(xs, series("device_usage_bytes"), color="k", lw=1.1,
                        label=f'device usage ({d.get("kind", "?")})')
        if any("device_swap_bytes" in t for t in ticks):
            bottom.plot(xs, series("device_swap_bytes"), color="#9467bd", lw=1.1,
                        label="device swap (zram)")
        if any("map_swap_bytes" in t for t in ticks):
            bottom.plot(xs, series("map_swap_bytes"), color=style(run)["color"], lw=1.0, ls="--",
                        label="map process swapped out")
        if any(t.get("zram_mem_used_bytes") for t in ticks):
            bottom.plot(xs, series("zram_mem_used_bytes"), color="#8c564b", lw=1.0,
                        label="zram's store (DRAM, charged to the device)")
        if any(t.get("device_limit_bytes") for t in ticks) and d.get("swap", {}).get("zram_charged"):
            bottom.plot(xs, series("device_limit_bytes"), color="k", lw=1.0, ls="-.",
                        label="limit in force (device − zram's store)")
        limit = d.get("limit_bytes")
        if limit:
            bottom.axhline(limit / GB, color="k", ls=":", lw=1.0,
                           label=f"device limit {limit / GB:.2f} GB")
        prev = 0
        for i, (x, t) in enumerate(zip(xs, ticks)):
            k = t.get("oom_kills", 0) or 0
            if k > prev:
                for ax in (top, bottom):
                    ax.axvline(x, color="#9467bd", lw=1.0, ls="-.",
                               label="OOM kill" if ax is bottom and prev == 0 else None)
            prev = max(prev, k)
        for i, x in enumerate(run.cotenant_deaths()):
            bottom.plot([x], [0.97], marker="v", color="#2ca02c", ms=8, ls="none",
                        transform=bottom.get_xaxis_transform(),
                        label="co-tenant killed" if i == 0 else None)
        if ticks and ticks[0].get("startup") and xlabel == "wall clock (s)" and xs[0] > 0:
            for ax in (top, bottom):
                ax.axvspan(0, xs[0], color="#dddddd", alpha=0.6, zorder=0,
                           label="map start-up load" if ax is bottom else None)
        bottom.set_ylabel("memory (GB)")
        bottom.set_xlabel(xlabel)
        bottom.set_ylim(bottom=0)
        bottom.grid(alpha=0.3)
        if bottom.get_legend_handles_labels()[0]:
            bottom.legend(fontsize=7, loc="lower right")
        top.set_xlim(left=0)
    fig.suptitle(f"{scenario}: the co-tenant's requests over the device's memory (wall clock)",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    footnote(fig, group[0], group)
    savefig(fig, fig_dir, f"timeline_{scenario}.png")


# The zone map and the tick latency (kept from before issue 17) --------------------------------

def plot_zones(out, scenario, runs, fig_dir):
    import json
    path = os.path.join(out, "scenarios", scenario, "zones.geojson")
    if not os.path.exists(path):
        return
    with open(path) as f:
        gj = json.load(f)
    fig, ax = plt.subplots(figsize=(10, 8))
    cmap = plt.get_cmap("tab20")
    for i, feat in enumerate(gj.get("features", [])):
        ring = feat["geometry"]["coordinates"][0]
        kind = feat.get("properties", {}).get("kind", "")
        ax.fill([p[0] for p in ring], [p[1] for p in ring], color=cmap(i % 20),
                alpha=0.25 if kind != "corridor" else 0.12)
        ax.plot([p[0] for p in ring], [p[1] for p in ring], color="k", lw=0.3)
    sem = R.pick(runs, "semantic", False) or R.pick(runs, "semantic", True)
    if sem is not None and sem.ticks() and "zone" in sem.ticks()[0]:
        t = sem.ticks()
        sc = ax.scatter([q["x"] for q in t], [q["y"] for q in t], c=[q["zone"] for q in t],
                        cmap="tab20", s=2)
        fig.colorbar(sc, ax=ax, label="active zone id along the route (semantic)")
    ax.set_aspect("equal")
    ax.set_title(f"{scenario}: zones and the patrol route")
    fig.tight_layout()
    savefig(fig, fig_dir, f"zones_{scenario}.png")


def plot_latency(scenario, runs, fig_dir):
    group = [r for r in runs if not r.with_vlm] or runs
    series = []
    for run in group:
        ms = [t["tick_ms"] for t in run.ticks() if not t.get("startup") and "tick_ms" in t]
        if ms:
            series.append((run.s.get("policy_label") or run.policy, run.policy, ms,
                           (run.s.get("startup") or {}).get("tick_ms")))
    if not series:
        return
    fig, axes = plt.subplots(1, 2, figsize=(15, 5))
    for lab, pol, ms, startup in series:
        v = sorted(ms)
        n = len(v)
        p99 = v[max(0, math.ceil(0.99 * n) - 1)]  # nearest rank, as StreamingStats
        ls = "--" if lab.endswith("unsliced") else "-"
        axes[0].step(v, [(i + 1) / n for i in range(n)], where="post", color=colour(pol), ls=ls,
                     lw=1.3, label=f"{lab}: p99 {p99:.1f} ms, max {v[-1]:.0f} ms")
        axes[0].plot([p99], [0.99], "o", color=colour(pol), ms=4)
        axes[1].step(v, [(n - i - 1) / n if i < n - 1 else 0.5 / n for i in range(n)],
                     where="post", color=colour(pol), ls=ls, lw=1.3,
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
    savefig(fig, fig_dir, f"latency_{scenario}.png")


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    out = sys.argv[1]
    found = R.find_runs(out)
    if not found:
        print(f"plots.py: no runs under {out} (expected {out}/runs/<scenario>/<run>/summary.json; "
              "run `zonemap bench` first)", file=sys.stderr)
        sys.exit(1)
    single = os.path.exists(os.path.join(out, "summary.json"))
    fig_dir = os.path.join(out, "figures")
    os.makedirs(fig_dir, exist_ok=True)
    for scenario, runs in found.items():
        plot_memory(scenario, runs, fig_dir)
        plot_trajectories(out, scenario, runs, fig_dir)
        plot_trajectories_all(out, scenario, runs, fig_dir)
        plot_cotenant(scenario, runs, fig_dir)
        plot_cotenant_path(out, scenario, runs, fig_dir)
        plot_timeline(scenario, runs, fig_dir)
        if not single:
            plot_zones(out, scenario, runs, fig_dir)
        plot_latency(scenario, runs, fig_dir)
    print(f"plots.py: figures in {fig_dir}")


if __name__ == "__main__":
    main()
