#!/usr/bin/env python3
"""Where Basic breaks (issue 17 §7): map size x keyframe footprint x model.

Basic (RTAB-Map's memory management) starts from the map's last working memory: for a map built
without memory management, every node (docs/memory.md, "Start-up"), and it transfers one node a
tick down to MemoryThr. Its peak demand on the device is therefore

    Basic   = OS reserve + map process (overhead) + N x slot + model weights + KV cache

against the device's memory (equivalently: everything but the OS reserve against the cgroup's
limit). Semantic holds at most K_max = DeriveBudget(profile) keyframes, an arena reserved at
start-up:

    Semantic = OS reserve + overhead + K_max x slot + weights + KV cache

with K_max = (memory - OS reserve - weights - kv_cache_bytes - headroom - overhead) / slot, so
Semantic's demand is the device less the headroom (plus the rounding), whatever the map's size:
it crosses only if the co-tenant's KV cache outgrows the headroom, or if the model is swapped
for a bigger one while MemoryThr stays frozen (`zonemap bench --models`: the paper fixes
MemoryThr while trying models; column "frozen share").

Modes:
  scripts/sweep.py derive [--profile P] [--out DIR]
      the whole grid by arithmetic: a table (markdown, CSV) and a figure (sweep_<profile>.png)
  scripts/sweep.py measure [--profile P] [--scale S] [--out DIR] [--ticks T] [--compression X]
      generates maps around Basic's crossing at device scale S (default 1/8, with the memory
      cgroup device), runs Basic + VLM and Semantic + VLM on each, then the table and figure with
      the measured points on them. A few minutes: `make sweep`, kept out of `make test`.
  scripts/sweep.py demo [--profile P] [--scenario DIR]
      the arithmetic that picks `make demo`'s map (README, "The demo's arithmetic")

K_max and the map share are the program's: `zonemap budget --stdin` answers with
lib/runtime/budget.h's DeriveBudget (the one derivation of K_max), so every mode needs a built
zonemap ($ZONEMAP, default build/host-release/app/zonemap). The arithmetic left here is Basic's
demand and the co-tenant's KV cache; the model table is the program's too (`zonemap budget
--list-models`).
"""
import argparse
import atexit
import collections.abc
import csv
import json
import math
import os
import re
import subprocess
import sys
import tomllib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runs as R  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

class _ModelTable(collections.abc.Mapping):
    """The co-tenant's model table, asked of the program (`zonemap budget --list-models`: harness/
    cotenant.cc's CotenantModels, the one table): name -> (weights (the paper's, decimal), KV
    bytes per token of context, KV bytes per token within the sliding window, the window, fixed
    recurrent state), smallest weights first (the tables' and the figure's order)."""

    def __init__(self):
        self._table = None

    def _load(self):
        if self._table is None:
            cmd = [zonemap_exe(), "budget", "--list-models"]
            try:
                out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            except (OSError, subprocess.CalledProcessError) as e:
                raise SystemExit(f"sweep: cannot run {' '.join(cmd)} ({e}): build it, or set ZONEMAP")
            models = sorted(json.loads(out), key=lambda m: m["weights_bytes"])  # stable
            self._table = {m["name"]: (m["weights_bytes"], m["kv_bytes_per_token"],
                                       m["window_bytes_per_token"], m["window_tokens"],
                                       m["state_bytes"]) for m in models}
        return self._table

    def __getitem__(self, name):
        return self._load()[name]

    def __iter__(self):
        return iter(self._load())

    def __len__(self):
        return len(self._load())


MODELS = _ModelTable()
# Resident bytes per keyframe: the sparse keyframes before issue 17 (~0.1 MB), then RTAB-Map's
# reported process memory per node, 1.9 MB (rtabmap#494) to 2.3 MB (rtabmap#82), and 2.16 MB,
# the largest keyframe of the default dense scenario (docs/sim.md) = its slot.
FOOTPRINTS = [100_000, 1_000_000, 1_900_000, 2_156_976, 2_300_000]
MAP_SIZES = list(range(250, 6001, 250))

_UNITS = {"": 1, "B": 1, "KB": 1e3, "MB": 1e6, "GB": 1e9, "KIB": 2**10, "MIB": 2**20,
          "GIB": 2**30}


def parse_bytes(v):
    """A profile's byte value: an integer, or "1.9GB" / "1.75GiB" (lib/runtime/profile.cc)."""
    if isinstance(v, int):
        return v
    m = re.fullmatch(r"\s*([0-9.]+)\s*([A-Za-z]*)\s*", str(v))
    if not m or m.group(2).upper() not in _UNITS:
        raise ValueError(f"not a byte size: {v!r}")
    return int(round(float(m.group(1)) * _UNITS[m.group(2).upper()]))


def load_profile(name):
    path = name if name.endswith(".toml") else os.path.join(ROOT, "profiles", name + ".toml")
    with open(path, "rb") as f:
        p = tomllib.load(f)
    d, m, mp, ct = p["device"], p["model"], p["map"], p.get("cotenant", {})
    return {
        "name": os.path.splitext(os.path.basename(path))[0],
        "path": os.path.abspath(path),
        "memory": parse_bytes(d["memory_bytes"]),
        "os_reserve": parse_bytes(d.get("os_reserve_bytes", 0)),
        "model": m.get("name", ""),
        "weights": parse_bytes(m.get("weights_bytes", 0)),
        "kv_cache": parse_bytes(m.get("kv_cache_bytes", 0)),
        "headroom": parse_bytes(mp.get("headroom_bytes", 0)),
        "overhead": parse_bytes(mp.get("overhead_bytes", 0)),
        "request_tokens": int(ct.get("prompt_tokens", 256)) + int(ct.get("answer_tokens", 64)),
        "context_tokens": int(ct.get("context_tokens", 4096)),
        "kv_allocation": ct.get("kv_allocation", "per_request"),
    }


def scale_profile(prof, scale):
    """--device-scale S (harness/device_scale.h): every byte of the memory split times S (nearest
    byte), keyframe counts unchanged. The model's weights and KV scale with it (scale_models)."""
    p = dict(prof)
    for k in ("memory", "os_reserve", "weights", "kv_cache", "headroom", "overhead"):
        p[k] = int(round(p[k] * scale)) if p[k] else 0
    p["scale"] = scale
    return p


def kv_bytes(model, tokens):
    """KV cache of one sequence at a context of `tokens` (docs/harness.md's formula)."""
    _, per, win_per, win, state = MODELS[model]
    return state + tokens * per + min(tokens, win) * win_per


def cotenant_kv(prof, model):
    """What the co-tenant's KV cache holds at most: one request's context (per_request), or all
    n_ctx from start-up (at_load, llama.cpp's)."""
    tokens = prof["request_tokens"] if prof["kv_allocation"] == "per_request" else prof["context_tokens"]
    return kv_bytes(model, tokens)


def model_bytes(prof, model):
    """The co-tenant's weights and KV cache at the profile's device scale."""
    sc = prof.get("scale", 1.0)
    return int(round(MODELS[model][0] * sc)), int(round(cotenant_kv(prof, model) * sc))


_BUDGET_PROCS = {}  # (profile, scale, override) -> a running `zonemap budget --stdin`
_BUDGETS = {}       # (profile, scale, override, keyframes, slot) -> its answer


def budget(prof, slot, n, model=None, cotenant=None):
    """The program's budget (DeriveBudget, semantic policy) for a map of n keyframes of at most
    `slot` bytes under prof at its device scale: the dict `zonemap budget` prints (k_max,
    map_share_bytes, ...), None when it refuses (no room for one slot). model: a profile written
    for that model (its share derived anew); cotenant: as `zonemap run --cotenant` (the share
    frozen). One process per profile variant answers all of its maps."""
    key = (prof["path"], prof.get("scale", 1.0), model, cotenant)
    proc = _BUDGET_PROCS.get(key)
    cmd = [zonemap_exe(), "budget", "--stdin", "--profile", prof["path"], "--policy", "semantic",
           "--device-scale", f"{prof.get('scale', 1.0):.17g}"]
    cmd += ["--model", model] if model else []
    cmd += ["--cotenant", cotenant] if cotenant else []
    if proc is None:
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        except OSError as e:
            raise SystemExit(f"sweep: cannot run {cmd[0]} ({e}): build it, or set ZONEMAP")
        _BUDGET_PROCS[key] = proc
    if key + (n, slot) not in _BUDGETS:
        proc.stdin.write(f"{n} {slot}\n")
        proc.stdin.flush()
        line = proc.stdout.readline()
        if not line:
            raise SystemExit(f"sweep: `{' '.join(cmd)}` stopped answering (exit {proc.wait()})")
        _BUDGETS[key + (n, slot)] = json.loads(line)
    b = _BUDGETS[key + (n, slot)]
    return None if "error" in b else b


@atexit.register
def _close_budgets():
    for proc in _BUDGET_PROCS.values():
        proc.stdin.close()  # end of input: it exits
        proc.wait()


def k_max(prof, slot, n, model=None):
    """K_max for a bounded policy (None: no room for one slot); see budget()."""
    b = budget(prof, slot, n, model=model)
    return b["k_max"] if b else None


def grid_point(prof, n, slot, model):
    w, kv = model_bytes(prof, model)
    base = prof["os_reserve"] + prof["overhead"] + w + kv
    basic = base + n * slot
    k_own = k_max(prof, slot, n, model=model)
    k_frozen = k_max(prof, slot, n)  # MemoryThr as derived for the profile's model
    return {
        "keyframes": n, "slot_bytes": slot, "model": model, "weights_bytes": w, "kv_bytes": kv,
        "basic_demand_bytes": basic,
        "basic_alone_bytes": prof["os_reserve"] + prof["overhead"] + n * slot,
        "k_max": k_own,
        "semantic_demand_bytes": base + k_own * slot if k_own else None,
        "k_max_frozen": k_frozen,
        "semantic_frozen_demand_bytes": base + k_frozen * slot if k_frozen else None,
        "device_bytes": prof["memory"],
    }


def crossing(prof, slot, model):
    """The largest map Basic + this model fits: N* = (memory - OS - overhead - weights - KV) / slot."""
    room = prof["memory"] - prof["os_reserve"] - prof["overhead"] - sum(model_bytes(prof, model))
    return max(0, room // slot)


def gb(v):
    return "–" if v is None else f"{v / 1e9:.2f}"


def derive(prof):
    rows = [grid_point(prof, n, s, m) for m in MODELS for s in FOOTPRINTS for n in MAP_SIZES]
    return rows


def derive_tables(prof, rows):
    dev = prof["memory"]
    lines = [f"Profile `{prof['name']}`: device {dev / 2**30:.2f} GiB, OS reserve "
             f"{prof['os_reserve'] / 2**30:.2f} GiB, map process overhead "
             f"{prof['overhead'] / 2**20:.0f} MiB, headroom {prof['headroom'] / 2**30:.2f} GiB, "
             f"KV cache {prof['kv_allocation']} ({prof['request_tokens']} tokens a request, "
             f"n_ctx {prof['context_tokens']}).", "",
             "#### Where Basic + the model crosses the device (N* = largest map that fits)", "",
             "| model | weights | KV | " + " | ".join(f"N* at {s / 1e6:.2f} MB/kf" for s in FOOTPRINTS)
             + " | Basic alone fits up to (2.16 MB) | Semantic K_max (own share / frozen) | "
               "Semantic demand, own share / frozen (GB) |",
             "|---|---|---|" + "---|" * len(FOOTPRINTS) + "---|---|---|"]
    alone = (prof["memory"] - prof["os_reserve"] - prof["overhead"]) // 2_156_976
    for m in MODELS:
        p = grid_point(prof, 100_000, 2_156_976, m)
        over_own = p["semantic_demand_bytes"] is not None and p["semantic_demand_bytes"] > dev
        over_frz = p["semantic_frozen_demand_bytes"] is not None and p["semantic_frozen_demand_bytes"] > dev
        lines.append(
            f"| {m} | {MODELS[m][0] / 1e9:.1f} GB | {p['kv_bytes'] / 1e6:.1f} MB | "
            + " | ".join(f"{crossing(prof, s, m):,}" for s in FOOTPRINTS)
            + f" | {alone:,} | {p['k_max'] or '–'} / {p['k_max_frozen'] or '–'} | "
              f"{gb(p['semantic_demand_bytes'])}{' ✗' if over_own else ' ✓'} / "
              f"{gb(p['semantic_frozen_demand_bytes'])}{' ✗' if over_frz else ' ✓'} |")
    lines += ["", f"Semantic's demand is for a map larger than K_max (smaller maps demand less); "
              f"✓ = within the device's {dev / 1e9:.2f} GB, ✗ = over it. Frozen = MemoryThr derived "
              f"with the profile's model ({prof['model']}) and kept when the model changes, as "
              "`zonemap bench --models` does.", "",
              "#### Basic's peak demand with the profile's footprint (2.16 MB/kf), GB (✗ = over "
              f"the device's {dev / 1e9:.2f} GB)", "",
              "| keyframes | map alone | " + " | ".join(MODELS) + " |",
              "|---|---|" + "---|" * len(MODELS)]
    for n in (500, 1000, 1500, 1820, 2000, 2250, 2500, 2750, 3000, 3500, 4000, 5000, 6000):
        cells = []
        for m in MODELS:
            p = grid_point(prof, n, 2_156_976, m)
            cells.append(f"{gb(p['basic_demand_bytes'])}{' ✗' if p['basic_demand_bytes'] > dev else ''}")
        a = grid_point(prof, n, 2_156_976, prof["model"] or "qwen3-vl-2b")["basic_alone_bytes"]
        lines.append(f"| {n:,} | {gb(a)}{' ✗' if a > dev else ''} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(rows, path):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def plot(prof, measured, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    dev = prof["memory"] / 1e9
    colours = dict(zip(MODELS, ["#2ca02c", "#1f77b4", "#9467bd", "#d62728", "#ff7f0e"]))
    fig, axes = plt.subplots(1, 2, figsize=(15, 5.6))
    ax = axes[0]
    ns = list(range(0, 6001, 50))
    slot = 2_156_976
    for m in MODELS:
        ys = [grid_point(prof, max(n, 1), slot, m)["basic_demand_bytes"] / 1e9 for n in ns]
        lo = [grid_point(prof, max(n, 1), 1_900_000, m)["basic_demand_bytes"] / 1e9 for n in ns]
        hi = [grid_point(prof, max(n, 1), 2_300_000, m)["basic_demand_bytes"] / 1e9 for n in ns]
        ax.plot(ns, ys, color=colours[m], lw=1.5, label=f"Basic + {m}")
        ax.fill_between(ns, lo, hi, color=colours[m], alpha=0.12)
        sem = [grid_point(prof, max(n, 1), slot, m)["semantic_demand_bytes"] for n in ns]
        ax.plot(ns, [v / 1e9 if v else math.nan for v in sem], color=colours[m], lw=1.0, ls=":")
    alone = [(prof["os_reserve"] + prof["overhead"] + n * slot) / 1e9 for n in ns]
    ax.plot(ns, alone, color="k", lw=1.0, ls="-.", label="Basic alone (no model)")
    ax.axhline(dev, color="k", lw=1.4, label=f"device {dev:.2f} GB")
    ax.set_xlabel("map size (keyframes); Basic's start-up working memory = the whole map")
    ax.set_ylabel("peak demand incl. OS reserve (GB)")
    ax.set_title(f"{prof['name']}: Basic (solid, band 1.9-2.3 MB/kf) vs Semantic at its own "
                 f"MemoryThr (dotted), 2.16 MB/kf", fontsize=9)
    ax.set_ylim(0, max(14, dev * 1.6))
    ax.grid(alpha=0.3)
    # measured points: demand by arithmetic at full size, marker by what happened
    marks = {"ok": ("o", "below the limit"), "oom": ("X", "OOM kill"),
             "limit": ("D", "at the limit, no kill (reclaim: the co-tenant slows)"),
             "stall": ("^", "co-tenant stalled / killed"), "fail": ("s", "failed to start")}
    seen = set()
    for p in measured:
        n, m, pol = p["keyframes"], p["model"], p["policy"]
        # placed by the share of the device it demanded at its own scale (the crossing in
        # keyframes shifts a little with the scale: the footprint does not scale exactly)
        dem = p["demand_fraction"] * prof["memory"]
        mk, lab = marks[p["verdict"]]
        ax.scatter([n], [dem / 1e9], marker=mk, s=80, facecolor=colours.get(m, "k") if pol == "basic" else "white",
                   edgecolor="k", zorder=5,
                   label=f"measured at 1/{round(1 / p['scale'])}: {lab}" if (mk, lab) not in seen else None)
        seen.add((mk, lab))
    ax.legend(fontsize=6.5, loc="lower right")
    ax = axes[1]
    fs = [f / 1e6 for f in FOOTPRINTS]
    for m in MODELS:
        ax.plot(fs, [crossing(prof, f, m) for f in FOOTPRINTS], "o-", color=colours[m],
                label=f"{m} ({MODELS[m][0] / 1e9:.1f} GB)")
    ax.plot(fs, [(prof["memory"] - prof["os_reserve"] - prof["overhead"]) // f for f in FOOTPRINTS],
            "k-.", label="no model (Basic alone)")
    ax.axvspan(1.9, 2.3, color="#cccccc", alpha=0.4, label="RTAB-Map's per-node memory")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("resident bytes per keyframe (MB, log)")
    ax.set_ylabel("largest map Basic fits, N* (keyframes, log)")
    ax.set_title("where Basic's demand crosses the device", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def demo_arithmetic(prof, slot=2_156_976, median=2_098_464):
    m = prof["model"]
    w, kv = model_bytes(prof, m)
    limit = prof["memory"] - prof["os_reserve"]
    b = budget(prof, slot, 10**9) or {}
    share, k = b.get("map_share_bytes"), b.get("k_max")
    n_lo = (limit - prof["overhead"] - w - kv) // slot + 1   # smallest map Basic + model overflows
    n_hi = (limit - prof["overhead"]) // slot                # largest map Basic alone fits
    return {"limit": limit, "share": share, "k_max": k, "weights": w, "kv": kv,
            "n_lo": n_lo, "n_hi": n_hi, "slot": slot, "median": median}


def print_demo(prof, scenario=None):
    info = None
    if scenario:
        with open(os.path.join(scenario, "scenario.json")) as f:
            info = json.load(f)
        a = demo_arithmetic(prof, slot=info["resident_bytes"]["max"],
                            median=info["resident_bytes"]["median"])
    else:
        a = demo_arithmetic(prof)
    print(f"""device limit  = memory - OS reserve = {prof['memory']:,} - {prof['os_reserve']:,} = {a['limit']:,} B ({a['limit'] / 2**30:.2f} GiB)
map share     = memory - OS reserve - weights - kv_cache_bytes - headroom
              = {prof['memory']:,} - {prof['os_reserve']:,} - {prof['weights']:,} - {prof['kv_cache']:,} - {prof['headroom']:,} = {a['share']:,} B
K_max         = (share - overhead) / slot = ({a['share']:,} - {prof['overhead']:,}) / {a['slot']:,} = {a['k_max']:,}
co-tenant     = weights {a['weights']:,} B + KV {a['kv']:,} B ({prof['kv_allocation']}, {prof['request_tokens']} tokens)
Basic alone fits          : N x slot + overhead <= limit               -> N <= {a['n_hi']:,}
Basic + model overflows   : N x slot + overhead + weights + KV > limit -> N >= {a['n_lo']:,}
the demo's window         : {a['n_lo']:,} <= N <= {a['n_hi']:,} (and N > K_max = {a['k_max']:,}, so Basic's start-up overshoots MemoryThr)""")
    if info:
        n = info["counts"]["keyframes"]
        alone = n * a["slot"] + prof["overhead"]
        both = alone + a["weights"] + a["kv"]
        inside = a["n_lo"] <= n <= a["n_hi"]
        print(f"this map ({scenario}): N = {n:,} keyframes of at most {a['slot']:,} B: Basic alone "
              f"{alone / 1e9:.2f} GB = {100 * alone / a['limit']:.0f} % of the limit, Basic + model "
              f"{both / 1e9:.2f} GB = {100 * both / a['limit']:.0f} %: "
              + ("inside the window" if inside else "OUTSIDE the window"))


# Measured runs -----------------------------------------------------------------------------

def zonemap_exe():
    return os.environ.get("ZONEMAP", os.path.join(ROOT, "build/host-release/app/zonemap"))


def run_cmd(cmd, log):
    print("+ " + " ".join(cmd), file=sys.stderr, flush=True)
    with open(log, "a") as f:
        f.write("+ " + " ".join(cmd) + "\n")
        f.flush()
        return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode


def ensure_map(out, n_target, scale, log):
    """A generated hospital of about n_target keyframes at footprint scale S. The keyframe count
    is not monotonic in the area (the layout changes with it), so the area is corrected up to
    four times from the density seen, and the closest map is kept."""
    exe = zonemap_exe()
    d = os.path.join(out, "maps", f"n{n_target}")
    info = os.path.join(d, "scenario.json")
    if os.path.exists(info):
        with open(info) as f:
            return d, json.load(f)["counts"]["keyframes"]
    area = n_target / 1.2  # keyframes per m2 of the generated hospital (3,634 on 3,000 m2)
    best = None  # (error, area)
    last = area
    for _ in range(4):
        last = area
        subprocess.run(["rm", "-rf", d])
        rc = run_cmd([exe, "sim", "hospital", "--seed", "1", "--quiet", "--area", f"{area:.0f}",
                      "--tasks", "4", "--footprint-scale", f"{scale:g}", "--out", d], log)
        if rc != 0:
            raise SystemExit(f"sweep: generating a map of {n_target} keyframes failed (see {log})")
        with open(info) as f:
            n = json.load(f)["counts"]["keyframes"]
        if best is None or abs(n - n_target) < best[0]:
            best = (abs(n - n_target), area)
        if abs(n - n_target) <= 0.06 * n_target:
            return d, n
        area *= n_target / n
    if best[1] != last:  # the last try was not the closest: make the closest again
        subprocess.run(["rm", "-rf", d])
        run_cmd([exe, "sim", "hospital", "--seed", "1", "--quiet", "--area", f"{best[1]:.0f}",
                 "--tasks", "4", "--footprint-scale", f"{scale:g}", "--out", d], log)
    with open(info) as f:
        return d, json.load(f)["counts"]["keyframes"]


def verdict(summary):
    d = summary.get("device") or {}
    ct = summary.get("cotenant") or {}
    if (summary.get("map") or {}).get("outcome") == "killed" or (d.get("oom_kills") or 0) > 0:
        return "oom"
    if ct.get("outcome") == "failed_to_start":
        return "fail"
    if ct.get("outcome") in ("stalled", "killed"):
        return "stall"
    if d.get("limit_bytes") and (d.get("peak_bytes") or 0) >= 0.99 * d["limit_bytes"]:
        return "limit"  # held at the limit: the kernel reclaimed (the co-tenant's weights) instead
    return "ok"


def measure(prof, args):
    out = args.out
    os.makedirs(out, exist_ok=True)
    log = os.path.join(out, "sweep.log")
    model = prof["model"]
    # The slot at this scale: the largest resident keyframe of a probe map (the footprint does
    # not scale exactly with S: docs/sim.md, "Footprint scale").
    probe, _ = ensure_map(out, 2400, args.scale, log)
    with open(os.path.join(probe, "scenario.json")) as f:
        slot = json.load(f)["resident_bytes"]["max"]
    sprof = scale_profile(prof, args.scale)
    n_star = crossing(sprof, slot, model)
    k = demo_arithmetic(sprof, slot=slot)["k_max"]
    print(f"sweep: at scale {args.scale:g} the slot is {slot:,} B: K_max {k:,}, Basic + {model} "
          f"crosses above N* = {n_star:,} keyframes", file=sys.stderr)
    # Grid points by arithmetic: below and above Basic + model's crossing, all above K_max so
    # Basic's start-up overshoots MemoryThr; plus the largest Basic alone fits.
    targets = sorted({max(k + 100, int(n_star * f)) for f in (0.85, 1.1, 1.3, 1.6)})
    measured = []
    for n_target in targets:
        scen, n = ensure_map(out, n_target, args.scale, log)
        for policy in ("basic", "semantic"):
            rdir = os.path.join(out, "runs", f"n{n_target}", f"{policy}-{model}")
            if not os.path.exists(os.path.join(rdir, "summary.json")):
                cmd = [zonemap_exe(), "run", "--scenario", scen, "--out", rdir, "--policy", policy,
                       "--profile", prof["name"], "--cotenant", model, "--device", args.device,
                       "--device-scale", f"{args.scale:g}", "--time-compression",
                       f"{args.compression:g}", "--max-ticks", str(args.ticks), "--quiet"]
                rc = run_cmd(cmd, log)
                if not os.path.exists(os.path.join(rdir, "summary.json")):
                    print(f"sweep: {rdir}: no summary.json (exit {rc}; see {log})", file=sys.stderr)
                    continue
            s = json.load(open(os.path.join(rdir, "summary.json")))
            run = R.Run(os.path.basename(rdir), rdir, s)
            d = s.get("device") or {}
            ct = s.get("cotenant") or {}
            measured.append({
                "keyframes": n, "model": model, "policy": policy, "scale": args.scale,
                "k_max_program": s.get("k_max"), "device": R.device_text(run),
                "limit_bytes": d.get("limit_bytes"), "peak_bytes": d.get("peak_bytes"),
                "oom_kills": d.get("oom_kills"), "map_outcome": (s.get("map") or {}).get("outcome"),
                "cotenant_outcome": ct.get("outcome"), "tokens_per_s": ct.get("tokens_per_s"),
                "latency_ms": R.latency_p50(ct), "update_rate_hz": s.get("update_rate_hz"),
                "frames_dropped": s.get("frames_dropped"), "verdict": verdict(s),
                # by arithmetic at this scale, this map's slot: the share of the device demanded
                "demand_fraction": grid_point(sprof, n, slot, model)[
                    "basic_demand_bytes" if policy == "basic" else "semantic_demand_bytes"]
                / sprof["memory"],
            })
            planned = budget(sprof, s.get("slot_bytes") or slot, n, cotenant=model) or {}
            if policy == "semantic" and s.get("k_max") and planned.get("k_max") != s["k_max"]:
                raise SystemExit(f"sweep: K_max planned {planned.get('k_max')} != the run's "
                                 f"{s['k_max']} ({rdir}): the sweep's budget flags differ from "
                                 "the run's")
    return measured


def measured_table(measured):
    def num(v, decimals):
        return "–" if v is None else f"{v:,.{decimals}f}"

    lines = ["| keyframes | policy | demand / device by arithmetic | device peak / limit (MB) | "
             "OOM kills | map | co-tenant | TPS | latency ms | update rate (Hz) | frames dropped |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for p in measured:
        lines.append(
            f"| {p['keyframes']:,} | {p['policy']} | {100 * p['demand_fraction']:.0f} % | "
            f"{num((p['peak_bytes'] or 0) / 1e6, 0)} / {num((p['limit_bytes'] or 0) / 1e6, 0)} | "
            f"{num(p['oom_kills'], 0)} | {p['map_outcome'] or '–'} | {p['cotenant_outcome'] or '–'} | "
            f"{num(p['tokens_per_s'], 2)} | {num(p['latency_ms'], 0)} | "
            f"{num(p['update_rate_hz'], 2)} | {num(p['frames_dropped'], 0)} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=["derive", "measure", "demo"])
    ap.add_argument("--profile", default="orin-nano-8gb")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "sweep"))
    ap.add_argument("--scale", type=float, default=None,
                    help="device scale (measure: default 0.125; demo: 1)")
    ap.add_argument("--device", default="cgroup")
    ap.add_argument("--ticks", type=int, default=150)
    ap.add_argument("--compression", type=float, default=10.0)
    ap.add_argument("--scenario", help="demo: a generated scenario directory to check")
    args = ap.parse_args()
    prof = load_profile(args.profile)
    if args.mode == "demo":
        print_demo(scale_profile(prof, args.scale or 1.0), args.scenario)
        return
    if args.scale is None:
        args.scale = 0.125
    os.makedirs(args.out, exist_ok=True)
    rows = derive(prof)
    write_csv(rows, os.path.join(args.out, f"sweep_{prof['name']}.csv"))
    text = "### Where Basic breaks: map size x keyframe footprint x model (derived)\n\n" + derive_tables(prof, rows)
    measured = measure(prof, args) if args.mode == "measure" else []
    if measured:
        with open(os.path.join(args.out, "measured.json"), "w") as f:
            json.dump(measured, f, indent=1)
        text += ("\n\n### Measured at device scale " + f"{args.scale:g} ({measured[0]['device']}; "
                 f"{args.ticks} frames each)\n\n" + measured_table(measured))
    with open(os.path.join(args.out, f"sweep_{prof['name']}.md"), "w") as f:
        f.write(text + "\n")
    print(text)
    try:
        plot(prof, measured, os.path.join(args.out, f"sweep_{prof['name']}.png"))
        print(f"\nsweep: {args.out}/sweep_{prof['name']}.{{md,csv,png}}")
    except ImportError as e:
        print(f"sweep: no figure ({e}); the tables are in {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
