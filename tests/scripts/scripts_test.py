#!/usr/bin/env python3
"""Behaviour of scripts/runs.py, scripts/sweep.py and scripts/plots.py on a tiny synthetic bench
output (make_fixture.py): the runs and cells read, the sweep's arithmetic against numbers worked
by hand and against the C++ tests' K_max, the five figures written; with repeats
(make_fixture.py --repeats), the cells and their representative repeat, and `zonemap bench
--report-only` writing the paper-form tables from that results.json (the tables are C++'s:
app/paper_tables.h; tests/app/paper_tables_test.cc checks their content). Exit 77 (ctest:
skipped, with the reason printed) when matplotlib is missing, after the other checks have run.

Usage: scripts_test.py SOURCE_DIR WORK_DIR
"""
import os
import shutil
import struct
import subprocess
import sys

SRC, WORK = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.join(SRC, "scripts"))
import runs  # noqa: E402
import sweep  # noqa: E402

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


shutil.rmtree(WORK, ignore_errors=True)
subprocess.run([sys.executable, os.path.join(SRC, "tests/scripts/make_fixture.py"), WORK], check=True)

# Runs: the four configurations are told apart; the torn last co-tenant line is skipped.
found = runs.find_runs(WORK)
check(list(found) == ["tiny"] and len(found["tiny"]) == 4, "four runs of one scenario found")
bv = runs.pick(found["tiny"], "basic", True)
check(bv is not None and bv.with_vlm and bv.model == "qwen3-vl-2b", "Basic + VLM picked")
check(bv is not None and len(bv.requests()) == 12, "12 requests read, the torn line skipped")
check(runs.pick(found["tiny"], "semantic", False).with_vlm is False, "Semantic only has no VLM")
check(bv is not None and bv.cotenant_deaths() == [2.0], "the co-tenant's kill on the wall clock")

# Repeats (zonemap bench --repeat 3): a cell per configuration, its representative repeat, the
# statistics results.json carries.
REP = WORK + "-repeats"
shutil.rmtree(REP, ignore_errors=True)
subprocess.run([sys.executable, os.path.join(SRC, "tests/scripts/make_fixture.py"), REP,
                "--repeats"], check=True)
rfound = runs.find_runs(REP)
check(len(rfound.get("tiny", [])) == 4, "repeats: four cells, not twelve runs")
rb = runs.pick(rfound["tiny"], "basic", True)
check(rb is not None and rb.n == 3 and len(rb.repeats) == 3 and rb.path.endswith("rep1"),
      "repeats: the representative repeat (results.json's) is the one shown")
check(rb is not None and rb.stat("/update_rate_hz")["n"] == 3, "repeats: the cell's statistic")

# The paper-form tables of that results.json, by the one producer: `zonemap bench --report-only`
# ($ZONEMAP set by tests/scripts/CMakeLists.txt). The cells are the statistics results.json
# carries (make_fixture.py works them by hand), formatted by the C++ writer.
zonemap = os.environ.get("ZONEMAP")
if zonemap:
    r = subprocess.run([zonemap, "bench", "--report-only", "--no-plots", "--out", REP],
                       capture_output=True, text=True)
    check(r.returncode == 0, f"zonemap bench --report-only ran ({r.stderr.strip()[-200:]})")
    path = os.path.join(REP, "paper_tables.md")
    rtext = open(path).read() if os.path.exists(path) else ""
    check("| metric | Basic only (n = 3) | Basic + VLM (n = 3) |" in rtext,
          "paper_tables.md: n in the header")
    check("| update rate (Hz) ↑ | 0.95 ± 0.12 (0.96) |" in rtext,
          "paper_tables.md: mean ± CI (the paper's)")
    check("| loop closures ↑ | – (53) |" in rtext,
          "paper_tables.md: a statistic results.json lacks is –, the paper's beside it")
    check("3 runs per configuration, interleaved" in rtext, "paper_tables.md: repeats stated")
    check("(weights pinned)" in rtext, "paper_tables.md: the co-tenant's weights stated")
    check("| 4.00 ± 12.71 (n = 2) |" in rtext,
          "paper_tables.md: a statistic two of three runs had says n = 2")
    check("| map process outcome | ○ completed | † killed |" in rtext,
          "paper_tables.md: outcomes tallied over the runs, with their symbols")
    check("| qwen3-vl-2b: the paper | Basic | 1 | △ | | 32.43 | – | 9,642 |" in rtext,
          "paper_tables.md: the paper's Table II row beside ours")
    check(r.stdout.count("| update rate (Hz) ↑ | 0.95 ± 0.12 (0.96) |") == 1,
          "the paper-form tables are printed too")
else:
    print("SKIPPED: $ZONEMAP unset, zonemap bench --report-only not run")

# Sweep arithmetic, worked by hand for orin-nano-8gb (8 GiB, 1.75 GiB OS, 1.9 GB weights,
# 0.5 GiB headroom, 256 MiB overhead). The budget is the program's (`zonemap budget --stdin`,
# $ZONEMAP set by tests/scripts/CMakeLists.txt).
prof = sweep.load_profile(os.path.join(SRC, "profiles/orin-nano-8gb.toml"))
b = sweep.budget(prof, 2_200_000, 10**6)
share = b["map_share_bytes"]
check(share == 4_274_015_488, f"map share 4,274,015,488 B (got {share:,})")
# tests/harness (docs/harness.md): 2.2 MB keyframes give K_max 1820 on this profile.
check(b["k_max"] == 1820 and sweep.k_max(prof, 2_200_000, 10**6) == 1820,
      "K_max 1820 at 2.2 MB, from DeriveBudget")
check(sweep.k_max(prof, 2_200_000, 500) == 500, "a map smaller than the budget: K_max is the map")
check(sweep.k_max(prof, 5_000_000_000, 10**6) is None, "no room for one slot: no K_max")
check(sweep.k_max(prof, 2_200_000, 10**6, model="qwen3.5-0.8b") >
      sweep.k_max(prof, 2_200_000, 10**6, model="qwen3-vl-4b"),
      "a profile written for a smaller model derives a larger K_max")
check(sweep.kv_bytes("qwen3-vl-2b", 640) == 73_400_320, "qwen3-vl-2b KV at 640 tokens 73.4 MB")
check(sweep.kv_bytes("qwen3-vl-2b", 4096) == 469_762_048, "qwen3-vl-2b KV at n_ctx 469.8 MB")
check(sweep.kv_bytes("gemma3-4b", 640) == 20_480 * 640 + 118_784 * 640, "gemma3 window KV")
a = sweep.demo_arithmetic(prof)
limit = 8 * 2**30 - int(1.75 * 2**30)
check(a["limit"] == limit, "device limit = memory - OS reserve")
slot = 2_156_976
check((a["n_hi"] * slot + prof["overhead"] <= limit < (a["n_hi"] + 1) * slot + prof["overhead"]),
      "n_hi: the largest map Basic alone fits")
extra = 1_900_000_000 + 73_400_320
check((a["n_lo"] * slot + prof["overhead"] + extra > limit >= (a["n_lo"] - 1) * slot
       + prof["overhead"] + extra), "n_lo: the smallest map Basic + the model overflows")
check(a["n_lo"] < a["n_hi"] and a["k_max"] < a["n_lo"], "the demo's window exists above K_max")
for m in sweep.MODELS:
    for f in sweep.FOOTPRINTS:
        for n in (100, 1000, 5000, 60000):
            p = sweep.grid_point(prof, n, f, m)
            if p["semantic_demand_bytes"] is not None and p["semantic_demand_bytes"] > prof["memory"]:
                failures.append(f"Semantic crosses at its own MemoryThr: {m} {f} {n}")
check(not any(x.startswith("Semantic crosses") for x in failures),
      "Semantic never crosses the device at the MemoryThr derived for its model")
p = sweep.grid_point(prof, 2500, slot, "qwen3-vl-2b")
check(p["basic_demand_bytes"] > prof["memory"] and p["basic_alone_bytes"] < prof["memory"],
      "2,500 dense keyframes: Basic alone fits, Basic + qwen3-vl-2b does not")
p = sweep.grid_point(prof, 2500, slot, "qwen3-vl-4b")
check(p["semantic_frozen_demand_bytes"] > prof["memory"],
      "a 3.3 GB model beside a MemoryThr frozen for 1.9 GB crosses (the paper's ×)")

try:
    import matplotlib  # noqa: F401
except ImportError as e:
    print(f"SKIPPED: the figures were not checked: {e} (install python3-matplotlib)")
    sys.exit(1 if failures else 77)

subprocess.run([sys.executable, os.path.join(SRC, "scripts/plots.py"), WORK], check=True)
subprocess.run([sys.executable, os.path.join(SRC, "scripts/plots.py"), REP], check=True)


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return struct.unpack(">II", head[16:24])


for base in (WORK, REP):
    for name in ("memory", "trajectories", "cotenant", "cotenant_path", "timeline"):
        size = png_size(os.path.join(base, "figures", f"{name}_tiny.png"))
        check(size is not None and size[0] > 400 and size[1] > 300,
              f"figure {name}_tiny.png written ({os.path.basename(base)})")
out = os.path.join(WORK, "sweep")
r = subprocess.run([sys.executable, os.path.join(SRC, "scripts/sweep.py"), "derive", "--out", out],
                   capture_output=True, text=True)
check(r.returncode == 0 and "| qwen3-vl-2b | 1.9 GB | 73.4 MB |" in r.stdout,
      "sweep derive prints the crossing table")
check(png_size(os.path.join(out, "sweep_orin-nano-8gb.png")) is not None, "sweep figure written")

if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
print("all checks passed")
