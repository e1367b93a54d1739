#!/usr/bin/env python3
"""The paper's Table I and Table II in the paper's form, from a `zonemap bench` output, with the
paper's own numbers beside ours (../shared/docs/evaluation.md).

Table I: one row per metric, one column per configuration (Basic only, Basic + VLM, Semantic
only, Semantic + VLM); each cell "ours (paper)". Table II: one row per model and policy: outcome,
requests completed, median and aggregate tokens/s, latency p50 / mean / p95 (○ completed, △
stalled, × failed to start, † killed). With repeats (`zonemap bench --repeat N`) every number of
ours is mean ± 95 % CI over the cell's runs, from results.json (computed there once; formatted
here by runs.fmt_stat).
Above both: the device (memory cgroup, or the ledger: "simulated"), its limit and scale, and the
time compression, which every report states.

Usage: scripts/paper_tables.py OUT [--md FILE]   (prints markdown; --md also writes it)
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runs as R  # noqa: E402
from runs import fmt_stat  # noqa: E402

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


# Table I's metrics: (row, the summary.json pointer of ours, decimals). TimeTotal is the mean
# tick time after the start-up tick (time_total_ms.steady; tick_ms.mean before issue 27). Loop
# closures are the accepted ones, as RTAB-Map counts them (closures_accepted; loop_closures in
# summaries of schema version 1, which counted the same).
T1_METRICS = [("/update_rate_hz", 2), ("/closures_accepted", 0), ("/time_total_ms/steady", 1),
              ("/ate_rmse_m", 3), ("/rpe_trans_rmse_m", 3), ("/rpe_rot_rmse_deg", 2)]
# TimeTotal the other ways (lib/runtime/summary.h, TimeTotalJson); the paper has one number.
T1_TIME_TOTAL = [
    ("avg TimeTotal incl. the start-up tick (ms)", "/time_total_ms/with_startup"),
    ("avg TimeTotal without the idle-time loads (ms)", "/time_total_ms/without_idle_loads"),
    ("avg TimeTotal with the idle-time loads (ms)", "/time_total_ms/with_idle_loads"),
]


# Pointers of summaries older than the current schema, for the same figure: TimeTotal before
# issue 27 was tick_ms.mean; schema version 1 had one count, loop_closures, for the closures
# accepted and the frames localized.
LEGACY = {"/time_total_ms/steady": "/tick_ms/mean", "/closures_accepted": "/loop_closures",
          "/frames_localized": "/loop_closures"}


def stat_or_legacy(run, pointer):
    """The cell's statistic, or the one an older summary kept it under (LEGACY)."""
    st = run.stat(pointer)
    if st is None and pointer in LEGACY:
        st = run.stat(LEGACY[pointer])
    return st


def header_n(cols):
    """Each column's n as its header states it: "(1 run)" or "(n = 3)"."""
    return [(f" (1 run)" if c.n == 1 else f" (n = {c.n})") if c else "" for c in cols]


def tally_text(run, pointer, symbols=True):
    """An outcome over the repeats: "○ completed" when all agree, else "○ completed 2, † killed 1"."""
    parts = []
    tally = run.tally(pointer)
    for v, k in tally:
        if v is None:
            continue
        sym = SYMBOL.get(v, "") if symbols else ""
        text = f"{sym} {v}".strip()
        parts.append(text if len(tally) == 1 else f"{text} {k}")
    return ", ".join(parts) or "–"


def extra_rows(cols):
    """What the paper's table leaves implicit and ours must state: frames, device, outcomes."""
    def st(r, p, d, scale=1.0):
        return fmt_stat(r.stat(p), d, scale, r.n) if r else "–"

    def frames(r):
        return f'{st(r, "/frames_dropped", 0)} of {st(r, "/frames_arrived", 0)}'

    def peak(r):
        p = "/device/peak_bytes" if r.stat("/device/peak_bytes") else "/device/peak_sum_bytes"
        return st(r, p, 2, 1e-9) + " GB" if r.stat(p) else "–"

    def ct_outcome(r):
        if not r.with_vlm:
            return "–"
        text = tally_text(r, "/cotenant/outcome")
        restarts = r.stat("/cotenant/restarts")
        if restarts and restarts.get("max"):
            text += f', restarts {fmt_stat(restarts, 1, 1.0, r.n)}'
        return text

    rows = [(name, lambda r, p=p: st(r, p, 1)) for name, p in T1_TIME_TOTAL]
    rows += [
        ("frames localized (a closure accepted on the frame)",
         lambda r: fmt_stat(stat_or_legacy(r, "/frames_localized"), 0, 1.0, r.n)),
        ("frames dropped of arrived", frames),
        ("device OOM kills", lambda r: st(r, "/device/oom_kills", 1)),
        ("device peak", peak),
        ("device swap peak (MB)", lambda r: st(r, "/device/swap/peak_bytes", 1, 1e-6)),
        ("device DRAM peak: usage + zram's store (GB)",
         lambda r: st(r, "/device/dram_peak_bytes", 2, 1e-9) if r.stat("/device/dram_peak_bytes")
         else "–"),
        ("limit writes refused: over the device's DRAM",
         lambda r: st(r, "/device/limit_charge_refusals", 0)
         if r.stat("/device/limit_charge_refusals") else "–"),
        ("map major faults", lambda r: st(r, "/map/major_faults", 0)),
        ("map process outcome", lambda r: tally_text(r, "/map/outcome")),
        ("co-tenant outcome", ct_outcome),
    ]
    return [(name, [f(r) if r is not None else "–" for r in cols]) for name, f in rows]


def table1(runs):
    cols = [R.pick(runs, p, v, None) for p, v in R.CONFIGS]
    if not any(cols):
        return None, cols
    ns = header_n(cols)
    head = "| metric | " + " | ".join(R.config_name(p, v) + n
                                      for (p, v), n in zip(R.CONFIGS, ns)) + " |"
    lines = [head, "|---" * 5 + "|"]
    for i, (metric, paper) in enumerate(PAPER_T1.items()):
        pointer, dec = T1_METRICS[i]
        cells = []
        for j, c in enumerate(cols):
            ours = fmt_stat(stat_or_legacy(c, pointer), dec, 1.0, c.n) if c else "–"
            cells.append(f"{ours} ({fmt(paper[j], dec if i != 2 else 2)})")
        lines.append(f"| {metric} | " + " | ".join(cells) + " |")
    for name, cells in extra_rows(cols):
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines), cols


# Table II's columns of ours: (header, pointer, decimals).
T2_COLUMNS = [
    ("requests completed", "/cotenant/requests_completed", 1),
    ("TPS median", "/cotenant/tokens_per_s", 2),
    ("TPS aggregate", "/cotenant/tokens_per_s_aggregate", 2),
    ("latency p50 (ms)", "/cotenant/latency_ms/p50", 0),
    ("latency mean (ms)", "/cotenant/latency_ms/mean", 0),
    ("latency p95 (ms)", "/cotenant/latency_ms/p95", 0),
    ("major faults", "/cotenant/major_faults", 0),
]


def table2(runs):
    models = []
    for r in runs:
        if r.with_vlm and r.model not in models:
            models.append(r.model)
    if not models:
        return None
    lines = ["| model (stand-in) | policy | runs | outcome | "
             + " | ".join(h for h, _, _ in T2_COLUMNS) + " |",
             "|---|---|---|---|" + "---|" * len(T2_COLUMNS)]
    for m in models:
        for p in ("basic", "semantic"):
            r = R.pick(runs, p, True, m)
            if r is None:
                continue
            planned = r.stat("/cotenant/requests_planned")
            cells = [fmt_stat(r.stat(ptr), d, 1.0, r.n) for _, ptr, d in T2_COLUMNS]
            if planned and planned.get("n"):
                cells[0] += f' of {fmt(int(planned["mean"]), 0)}'
            lines.append(f"| {m} | {p.capitalize()} | {r.n} | "
                         f"{tally_text(r, '/cotenant/outcome')} | " + " | ".join(cells) + " |")
        paper = PAPER_T2.get(m)
        if paper:
            for name, (sym, tps, lat) in (("Basic", paper[:3]), ("Semantic", paper[3:])):
                lines.append(f"| {m}: the paper | {name} | 1 | {sym} | | {fmt(tps, 2)} | – | "
                             f"{fmt(lat, 0)} | – | – | – |")
    return "\n".join(lines)


def weights_text(cols):
    """How the co-tenant's weights were held (summary.json cotenant.weights, issue 27 §1)."""
    ct = [c for c in cols if c and c.with_vlm]
    kinds = sorted({v for c in ct for v, _ in c.tally("/cotenant/weights") if v})
    return f" (weights {', '.join(kinds)})" if kinds else ""


def repeats_text(cols):
    ns = sorted({c.n for c in cols if c})
    if ns == [1]:
        return "One run per configuration."
    return (f"{' or '.join(map(str, ns))} runs per configuration, interleaved (ABAB...); the "
            "figures show each configuration's representative run (mean tick time nearest the "
            "median).")


def table_section(heading, table, note):
    """A table under its heading with its note below, or nothing where the table is empty."""
    return [f"### {heading}\n", table + "\n", note] if table else []


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
                     ". The co-tenant is a stand-in for VLM decoding" + weights_text(cols) +
                     ". " + repeats_text(cols) + " Each cell: ours (the paper's, Jetson Orin "
                     "Nano 8 GB).\n")
        parts += table_section(
            "Table I analogue: SLAM with and without the co-tenant", t1,
            "Each cell: ours, mean ± 95 % CI over the column's runs (Student's t, "
            "n − 1 dof; one run: its value), then (the paper's, one run). avg "
            "TimeTotal = the mean tick time after the start-up tick (RTAB-Map's "
            "TimeTotal is its per-frame processing time); incl. the start-up tick: "
            "the start-up load counted in; without the idle-time loads: the ticks' "
            "own steps, the waits on idle-time loads taken out; with the idle-time "
            "loads: every idle-time load's wall time charged to the ticks, as if "
            "loaded inside them (RTAB-Map's loads are).\n")
        parts += table_section(
            "Table II analogue: the co-tenant beside SLAM", table2(runs),
            "○ completed, △ stalled (watchdog), × failed to start, † killed (OOM; "
            "restarted by the supervisor). TPS median = the median request's decode "
            "tokens/s; TPS aggregate = all answer tokens ÷ all decode time (slow "
            "requests weigh by their length); latency = a request's start to its "
            "last token (prompt processing + decode); p50/p95 nearest rank over the "
            "run's completed requests. Each cell: mean ± 95 % CI over the runs "
            "(Student's t), a per-run figure averaged. The paper's Table II gives "
            "one run's median TPS and latency.\n")
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
