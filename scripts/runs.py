"""Reading a `zonemap bench` / `zonemap run` output: run directories, their summaries, ticks and
co-tenant requests, and which run is which of the paper's four configurations.

Shared by scripts/plots.py (the figures) and scripts/sweep.py (where Basic breaks). Standard
library only. The tables are not made here: `zonemap bench` writes every one of them, Table I
and Table II in the paper's form included (paper_tables.md: app/paper_tables.h).

With repeats (`zonemap bench --repeat N`, issue 27 §4) a cell's runs are
OUT/runs/<scenario>/<cell>/rep<r>/ and OUT/results.json holds, per cell, every repeat's summary
and the statistics over them ({n, mean, ci95, median, ...} per JSON pointer of summary.json),
computed once by the bench (harness/repeats.h); the scripts only read them. A cell
is one Run: its `s`, ticks and requests are the representative repeat's (results.json's
`representative_repeat`: the repeat whose mean tick time is nearest the median; rep0 without
results.json), `stat(pointer)` the cell's statistic. Without results.json (a single run, an
older output) a statistic is the one run's value, n = 1.

A run directory holds summary.json, ticks.jsonl (one line per tick), estimate.tum and, with a
co-tenant, cotenant.jsonl (its event lines, docs/harness.md "Event lines") and cotenant.json
(its report). Keys written before issue 17's experiment are read too (they lack the device and
wall-clock fields; the figures then fall back to what there is and say so).
"""
import json
import math
import os

# The paper's configurations, in its column order (Table I).
CONFIGS = [("basic", False), ("basic", True), ("semantic", False), ("semantic", True)]


def config_name(policy, with_vlm):
    return f'{policy.capitalize()} {"+ VLM" if with_vlm else "only"}'


def read_json(path):
    with open(path) as f:
        return json.load(f)


def read_jsonl(path):
    """Every JSON object of a .jsonl file; a torn last line (a killed writer) is skipped."""
    rows = []
    if not os.path.exists(path):
        return rows
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def read_tum(path):
    """(stamp, x, y) of a TUM trajectory file; [] when it is missing."""
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


def closures_accepted(summary, default="?"):
    """Loop closures accepted: closures_accepted, or loop_closures in a summary of schema
    version 1 (the same count)."""
    return summary.get("closures_accepted", summary.get("loop_closures", default))


def json_pointer(doc, pointer):
    """The value at a JSON pointer ("/tick_ms/mean"), None where there is none."""
    cur = doc
    for part in pointer.split("/")[1:]:
        part = part.replace("~1", "/").replace("~0", "~")
        if not isinstance(cur, dict) or part not in cur:
            return None
        cur = cur[part]
    return cur


class Run:
    """One run directory (or one cell of repeats, shown by its representative repeat): its
    summary and, read on demand, its ticks and co-tenant lines."""

    def __init__(self, name, path, summary, cell=None, repeats=None, representative=0):
        self.name = name
        self.path = path
        self.s = summary
        self.cell = cell  # results.json's entry (stats over the repeats), or None
        self.repeats = repeats if repeats is not None else [self]
        self.representative = representative
        self._ticks = None
        self._requests = None

    @property
    def n(self):
        """Runs in the cell."""
        return self.cell.get("repeats", len(self.repeats)) if self.cell else len(self.repeats)

    def stat(self, pointer):
        """The cell's statistic at a JSON pointer of summary.json ({n, mean, ci95, ...}), from
        results.json; without it the one run's value as n = 1 (no statistic is computed here)."""
        if self.cell is not None:
            return (self.cell.get("stats") or {}).get(pointer)
        v = json_pointer(self.s, pointer)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        return {"n": 1, "mean": v, "ci95": 0.0, "median": v, "values": [v]}

    def mean(self, pointer):
        st = self.stat(pointer)
        return st["mean"] if st and st.get("n") else None

    def tally(self, pointer):
        """A string field over the repeats: [(value, count)] in first-seen order."""
        out = {}
        runs = (self.cell or {}).get("runs") or [r.s for r in self.repeats]
        for s in runs:
            v = json_pointer(s, pointer)
            out[v] = out.get(v, 0) + 1
        return list(out.items())

    def representative_note(self):
        if self.n <= 1:
            return "1 run"
        return (f"repeat {self.representative + 1} of {self.n} shown (mean tick time nearest "
                f"the median)" if self.cell else f"repeat {self.representative + 1} of {self.n} shown")

    @property
    def policy(self):
        return self.s.get("policy", "?")

    @property
    def with_vlm(self):
        ct = self.s.get("cotenant")
        if isinstance(ct, dict) and ct:
            return True
        model = self.s.get("model")
        return bool(model) and model != "none"

    @property
    def model(self):
        ct = self.s.get("cotenant") or {}
        return ct.get("model") or self.s.get("model") or "none"

    @property
    def label(self):
        base = self.s.get("policy_label") or self.policy
        return f'{base} + VLM' if self.with_vlm else f'{base} only'

    @property
    def k_max(self):
        return self.s.get("k_max")

    @property
    def time_compression(self):
        tc = self.s.get("time_compression")
        if tc:
            return float(tc)
        pace = self.s.get("pace_speedup")
        return float(pace) if pace else None

    def ticks(self):
        if self._ticks is None:
            self._ticks = read_jsonl(os.path.join(self.path, "ticks.jsonl"))
        return self._ticks

    def tick_times(self):
        """Seconds on the experiment's wall clock per tick (`wall_s`), else the frames' stamps
        divided by the time compression; and which clock it is, for the axis label."""
        ticks = self.ticks()
        if ticks and all("wall_s" in t for t in ticks):
            return [t["wall_s"] for t in ticks], "wall clock (s)"
        tc = self.time_compression or 1.0
        if ticks and all("stamp" in t for t in ticks):
            t0 = ticks[0]["stamp"]
            return [(t["stamp"] - t0) / tc for t in ticks], "frame stamp / time compression (s)"
        return [t.get("tick", i) for i, t in enumerate(ticks)], "tick"

    def requests(self):
        """Completed co-tenant requests as dicts with wall_s (end), tokens_per_s, latency_ms.

        From cotenant.jsonl's `request` lines (wall_s when the experiment wrote it, else the
        monotonic end less the report's origin), else the report's per_request triples."""
        if self._requests is not None:
            return self._requests
        out = []
        lines = read_jsonl(os.path.join(self.path, "cotenant.jsonl"))
        report = {}
        rp = os.path.join(self.path, "cotenant.json")
        if os.path.exists(rp):
            report = read_json(rp)
        origin = report.get("origin_mono_s") or (self.s.get("cotenant") or {}).get("origin_mono_s")
        if origin is None:
            starts = [l["mono_s"] for l in lines if "mono_s" in l]
            origin = min(starts) if starts else 0.0
        for l in lines:
            if l.get("event") != "request":
                continue
            if "wall_s" in l:
                end = l["wall_s"]
            elif "ended_s" in l:
                end = l["ended_s"] - origin
            else:
                continue
            start = l["started_s"] - origin if "started_s" in l and "wall_s" not in l else None
            out.append({"wall_s": end, "tokens_per_s": l.get("tokens_per_s"),
                        "latency_ms": l.get("latency_ms"), "started_wall_s": start})
        if not out:
            per = report.get("per_request") or (self.s.get("cotenant") or {}).get("per_request") or []
            for end, tps, lat in per:
                # per_request ends are monotonic seconds; relative to the origin when known.
                out.append({"wall_s": end - (origin or 0.0) if end > 1e5 else end,
                            "tokens_per_s": tps, "latency_ms": lat, "started_wall_s": None})
        out = [r for r in out if r["tokens_per_s"] is not None and r["latency_ms"] is not None]
        out.sort(key=lambda r: r["wall_s"])
        self._requests = out
        return out

    def cotenant_deaths(self):
        """Wall-clock seconds at which the supervisor saw the co-tenant die by a signal (its
        `exit` lines of kind killed or crashed: an OOM kill is a SIGKILL)."""
        rp = os.path.join(self.path, "cotenant.json")
        origin = read_json(rp).get("origin_mono_s") if os.path.exists(rp) else None
        if origin is None:
            origin = (self.s.get("cotenant") or {}).get("origin_mono_s")
        out = []
        for l in read_jsonl(os.path.join(self.path, "cotenant.jsonl")):
            if l.get("event") == "exit" and l.get("kind") in ("killed", "crashed"):
                if "wall_s" in l:
                    out.append(l["wall_s"])
                elif "mono_s" in l and origin is not None:
                    out.append(l["mono_s"] - origin)
        return out


def read_cells(out):
    """results.json's cells by (scenario, cell directory name); {} without it (or an older,
    pre-repeat results.json)."""
    path = os.path.join(out, "results.json")
    if not os.path.exists(path):
        return {}
    try:
        cells = read_json(path)
    except (OSError, json.JSONDecodeError):
        return {}
    return {(c["scenario_name"], c["cell"]): c for c in cells
            if isinstance(c, dict) and "cell" in c and "stats" in c}


def find_runs(out):
    """{scenario: [Run]} for OUT/runs/<scenario>/<cell>/rep<r>/summary.json (one Run per cell, its
    repeats inside) or OUT/runs/<scenario>/<run>/summary.json (before repeats), or a single run
    directory (OUT/summary.json) as scenario "run"."""
    if os.path.exists(os.path.join(out, "summary.json")):
        return {"run": [Run(os.path.basename(os.path.normpath(out)), out,
                            read_json(os.path.join(out, "summary.json")))]}
    base = os.path.join(out, "runs")
    result = {}
    if not os.path.isdir(base):
        return result
    cells = read_cells(out)
    for scenario in sorted(os.listdir(base)):
        sdir = os.path.join(base, scenario)
        if not os.path.isdir(sdir):
            continue
        runs = []
        for name in sorted(os.listdir(sdir)):
            d = os.path.join(sdir, name)
            s = os.path.join(d, "summary.json")
            if os.path.exists(s):
                runs.append(Run(name, d, read_json(s)))
                continue
            reps = sorted((e for e in os.listdir(d) if e.startswith("rep") and e[3:].isdigit()
                           and os.path.exists(os.path.join(d, e, "summary.json"))),
                          key=lambda e: int(e[3:])) if os.path.isdir(d) else []
            if not reps:
                continue
            rep_runs = [Run(name, os.path.join(d, e), read_json(os.path.join(d, e, "summary.json")))
                        for e in reps]
            cell = cells.get((scenario, name))
            i = cell.get("representative_repeat", 0) if cell else 0
            i = i if 0 <= i < len(rep_runs) else 0
            runs.append(Run(name, rep_runs[i].path, rep_runs[i].s, cell=cell, repeats=rep_runs,
                            representative=i))
        if runs:
            result[scenario] = runs
    return result


def pick(runs, policy, with_vlm, model=None):
    """The run of one configuration (policy, with/without the co-tenant, optionally a model);
    when several budgets ran, the one with the smallest K_max (the tightest: the paper's)."""
    c = [r for r in runs if r.policy == policy and r.with_vlm == with_vlm
         and (model is None or not with_vlm or r.model == model)
         and "unsliced" not in (r.s.get("policy_label") or "")]
    if not c:
        return None
    return min(c, key=lambda r: r.k_max if r.k_max is not None else math.inf)


def latency_p50(ct):
    """The co-tenant report's latency: a number (before issue 17) or {p50, p95}."""
    v = ct.get("latency_ms") if ct else None
    if isinstance(v, dict):
        return v.get("p50")
    return v


def device_text(run):
    """How the device was modelled, for every report: kind, limit, scale, time compression."""
    s = run.s
    d = s.get("device") or {}
    kind = d.get("kind")
    parts = []
    if kind == "cgroup":
        parts.append("device: memory cgroup (the kernel's OOM killer)")
    elif kind == "ledger":
        parts.append("device: ledger (SIMULATED: no memory cgroup)")
    else:
        parts.append("device: ledger (SIMULATED; written before the cgroup device existed)")
    if d.get("limit_bytes"):
        parts.append(f'limit {d["limit_bytes"] / 2**30:.2f} GiB')
    scale = s.get("device_scale") or d.get("scale") or (s.get("cotenant") or {}).get("device_scale")
    parts.append(f"device scale {scale:g}" if scale else "device scale 1")
    tc = run.time_compression
    parts.append(f"time compression {tc:g}x" if tc else "no time compression (unpaced)")
    return ", ".join(parts)
