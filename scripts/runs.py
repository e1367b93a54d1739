"""Reading a `zonemap bench` / `zonemap run` output: run directories, their summaries, ticks and
co-tenant requests, and which run is which of the paper's four configurations.

Shared by scripts/plots.py (the figures), scripts/paper_tables.py (Table I/II in the paper's
form) and scripts/sweep.py (where Basic breaks). Standard library only, so the tables print
where matplotlib is missing.

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


class Run:
    """One run directory: its summary and, read on demand, its ticks and co-tenant lines."""

    def __init__(self, name, path, summary):
        self.name = name
        self.path = path
        self.s = summary
        self._ticks = None
        self._requests = None

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
            out.append({"wall_s": end, "tokens_per_s": l.get("tokens_per_s"),
                        "latency_ms": l.get("latency_ms")})
        if not out:
            per = report.get("per_request") or (self.s.get("cotenant") or {}).get("per_request") or []
            for end, tps, lat in per:
                # per_request ends are monotonic seconds; relative to the origin when known.
                out.append({"wall_s": end - (origin or 0.0) if end > 1e5 else end,
                            "tokens_per_s": tps, "latency_ms": lat})
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


def find_runs(out):
    """{scenario: [Run]} for OUT/runs/<scenario>/<run>/summary.json, or a single run directory
    (OUT/summary.json) as scenario "run"."""
    if os.path.exists(os.path.join(out, "summary.json")):
        return {"run": [Run(os.path.basename(os.path.normpath(out)), out,
                            read_json(os.path.join(out, "summary.json")))]}
    base = os.path.join(out, "runs")
    result = {}
    if not os.path.isdir(base):
        return result
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
