#!/usr/bin/env python3
"""The paper's Table I and Table II in the paper's form, from a `zonemap bench` output, with the
paper's own numbers beside ours (../shared/docs/evaluation.md).

Table I: one row per metric, one column per configuration (Basic only, Basic + VLM, Semantic
only, Semantic + VLM); each cell "ours (paper)". Table II: one row per model, Basic's and
Semantic's outcome, tokens/s and latency (○ completed, △ stalled, × failed to start, † killed).
Above both: the device (memory cgroup, or the ledger: "simulated"), its limit and scale, and the
time compression, which every report states.

Usage: scripts/paper_tables.py OUT [--md FILE]   (prints markdown; --md also writes it)
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runs as R  # noqa: E402

# ../shared/docs/evaluation.md, Table I (Jetson Orin Nano 8 GB, RTAB-Map, qwen3-vl 2B).
PAPER_T1 = {
    "update rate (Hz) ↑": (0.96, 0.65, 0.96, 0.95),
    "loop closures ↑": (53, 31, 35, 33),
    "avg TimeTotal (ms) ↓": (779.41, 5064.87, 566.06, 784.81),
    "ATE RMSE (m) ↓": (0.14, 0.31, 0.18, 0.19),
    "RPE translation RMSE (m) ↓": (0.20, 0.42, 0.24, 0.22),
    "RPE rotation RMSE (deg) ↓": (0.38, 1.00, 0.57, 0.32),
}
# Table II: model -> (Basic outcome, TPS, latency ms, Semantic outcome, TPS, latency ms).
PAPER_T2 = {
    "qwen3-vl-2b": ("△", 32.43, 9642, "○", 33.36, 10260),
    "qwen3-vl-4b": ("×", None, None, "×", None, None),
    "qwen3.5-0.8b": ("△", 29.80, 30396, "○", 31.22, 23812),
    "qwen3.5-2b": ("×", None, None, "×", None, None),
    "gemma3-4b": ("○", 14.38, 13175, "○", 15.19, 11880),
}
SYMBOL = {"completed": "○", "stalled": "△", "failed_to_start": "×", "killed": "†",
          "failed": "×"}


def fmt(v, decimals):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, int) and decimals == 0:
        return f"{v:,}"
    return f"{v:,.{decimals}f}"


def t1_values(run):
    """Our value of each Table I metric for one run (None where the run has none)."""
    s = run.s
    tm = s.get("tick_ms") or {}
    return [s.get("update_rate_hz"), s.get("loop_closures"), tm.get("mean"), s.get("ate_rmse_m"),
            s.get("rpe_trans_rmse_m"), s.get("rpe_rot_rmse_deg")]


DECIMALS = [2, 0, 1, 3, 3, 2]


def extra_rows(cols):
    """What the paper's table leaves implicit and ours must state: frames, device, outcomes."""
    def get(run, f):
        return f(run) if run is not None else None

    def frames(r):
        a, d = r.s.get("frames_arrived"), r.s.get("frames_dropped")
        return f"{a - d:,} of {a:,}" if a is not None and d is not None else fmt(r.s.get("ticks"), 0)

    def oom(r):
        d = r.s.get("device") or {}
        v = d.get("oom_kills", r.s.get("oom_events"))
        return fmt(v, 0) if v is not None else "–"

    def peak(r):
        d = r.s.get("device") or {}
        v = d.get("peak_bytes") or d.get("peak_sum_bytes")
        return f"{v / 1e9:.2f} GB" if v else "–"

    def map_outcome(r):
        m = (r.s.get("map") or {}).get("outcome")
        return f'{SYMBOL.get(m, "")} {m}'.strip() if m else "–"

    def ct_outcome(r):
        c = r.s.get("cotenant") or {}
        o = c.get("outcome")
        if not o:
            return "–"
        extra = f', {c["restarts"]} restarts' if c.get("restarts") else ""
        return f'{SYMBOL.get(o, c.get("symbol", ""))} {o}{extra}'.strip()

    rows = [
        ("frames processed / arrived", frames),
        ("device OOM kills", oom),
        ("device peak", peak),
        ("map process outcome", map_outcome),
        ("co-tenant outcome", ct_outcome),
    ]
    return [(name, [get(r, f) or "–" for r in cols]) for name, f in rows]


def table1(runs):
    cols = [R.pick(runs, p, v, None) for p, v in R.CONFIGS]
    if not any(cols):
        return None, cols
    head = "| metric | " + " | ".join(R.config_name(p, v) for p, v in R.CONFIGS) + " |"
    lines = [head, "|---" * 5 + "|"]
    ours = [t1_values(c) if c else [None] * 6 for c in cols]
    for i, (metric, paper) in enumerate(PAPER_T1.items()):
        cells = []
        for j in range(4):
            v = ours[j][i]
            cells.append(f"{fmt(v, DECIMALS[i])} ({fmt(paper[j], DECIMALS[i] if i != 2 else 2)})")
        lines.append(f"| {metric} | " + " | ".join(cells) + " |")
    for name, cells in extra_rows(cols):
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines), cols


def table2(runs):
    models = []
    for r in runs:
        if r.with_vlm and r.model not in models:
            models.append(r.model)
    if not models:
        return None
    lines = ["| model (stand-in) | Basic | TPS | latency ms | Semantic | TPS | latency ms |",
             "|---|---|---|---|---|---|---|"]
    for m in models:
        cells = []
        for p in ("basic", "semantic"):
            r = R.pick(runs, p, True, m)
            c = (r.s.get("cotenant") or {}) if r else {}
            o = c.get("outcome")
            sym = SYMBOL.get(o, c.get("symbol", "–")) if o else "–"
            cells += [sym + (f" {o}" if o else ""), fmt(c.get("tokens_per_s"), 2),
                      fmt(R.latency_p50(c), 0)]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
        p = PAPER_T2.get(m)
        if p:
            lines.append(f"| {m}: the paper | {p[0]} | {fmt(p[1], 2)} | {fmt(p[2], 0)} | {p[3]} | "
                         f"{fmt(p[4], 2)} | {fmt(p[5], 0)} |")
    return "\n".join(lines)


def render(out):
    found = R.find_runs(out)
    if not found:
        raise SystemExit(f"paper_tables.py: no runs under {out}")
    parts = []
    for scenario, runs in found.items():
        t1, cols = table1(runs)
        first = next((c for c in cols if c), runs[0])
        k = sorted({c.k_max for c in cols if c and c.k_max})
        parts.append(f"## {scenario}: the paper's tables\n")
        tcs = sorted({c.time_compression or 0 for c in cols if c})
        differ = (f" (first run; NOT the same in every run: "
                  f"{', '.join(f'{t:g}x' if t else 'unpaced' for t in tcs)})" if len(tcs) > 1 else "")
        parts.append(R.device_text(first) + differ +
                     (f"; MemoryThr (K_max) {', '.join(map(str, k))}" if k else "") +
                     ". The co-tenant is a stand-in for VLM decoding. Each cell: ours (the "
                     "paper's, Jetson Orin Nano 8 GB).\n")
        if t1:
            parts.append("### Table I analogue: SLAM with and without the co-tenant\n")
            parts.append(t1 + "\n")
            parts.append("avg TimeTotal = the mean tick time (RTAB-Map's TimeTotal is its "
                         "per-frame processing time).\n")
        t2 = table2(runs)
        if t2:
            parts.append("### Table II analogue: the co-tenant beside SLAM\n")
            parts.append(t2 + "\n")
            parts.append("○ completed, △ stalled (watchdog), × failed to start, † killed (OOM; "
                         "restarted by the supervisor). TPS = median decode tokens/s, latency = "
                         "median request latency.\n")
    return "\n".join(parts)


def main():
    args = sys.argv[1:]
    if not args or args[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    text = render(args[0])
    print(text)
    if "--md" in args:
        with open(args[args.index("--md") + 1], "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
