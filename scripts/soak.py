#!/usr/bin/env python3
"""Soak the REAL daemon: zonemapd fed through its line protocol for a million ticks.

A robot-side feeder (examples/robot/zonemap_protocol.py) replays a small simulated scenario's
frames over and over (stamps keep increasing, pass after pass) into `zonemapd --stdin`; every
`--features-every`-th frame carries its features (a loop-closure attempt), the others odometry
only, so a million ticks take minutes, not hours. It also pulls the levers a robot pulls, every
--period P ticks (50,000): a `route` line every 2P ticks, a `budget` down to half of K_max at
P/2 and back up P/5 later, and a burst of insane lines (a stamp going back, a position of
1e308 m, a non-unit quaternion, garbage) every P/5 ticks, starting at P/10. A reader parses every pose line zonemapd
writes back; a sampler reads zonemapd's resident set size (/proc/PID/status VmRSS).

Checks (exit 1 when one fails): one pose line per frame sent; resident <= K_max on every pose
line (and summary.json: no tick over budget at any instant); every insane line refused and
counted with its reason; RSS after warm-up (the first 10 % of ticks) flat: least-squares slope
within --max-slope bytes per 1,000 ticks and growth within --max-growth-mib (--no-rss-check:
not checked, for short runs, still warming, or under ASan, whose allocator is not ours).

    scripts/soak.py --build build/host-release --ticks 1000000 --out out/soak \\
        --plot out/soak/soak.png              # the documented run (docs/reliability.md)
    scripts/soak.py --build build/host-debug --ticks 20000 --out DIR   # the ctest (short)

The generated scenario's dense keyframes are at --footprint-scale 0.02 of the device's (about
90 x 68 pixels): features, poses, zones and every line are those of a full-size map, but a
keyframe load decodes in microseconds instead of ~8 ms, so a million ticks take ~15 minutes
rather than ~4.5 hours (measured: docs/reliability.md).

Writes OUT/soak.csv (tick, rss_kib, resident, k_max) and OUT/soak.json (the figures); --plot
draws RSS and resident over ticks (needs matplotlib; /usr/bin/python3 on Debian has it).
"""

import argparse
import json
import os
import shlex
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "examples", "robot"))
import zonemap_protocol as zp  # noqa: E402

INSANE = [  # (line, reason zonemapd must count it under); stamps are filled in
    ("frame {back:.6f} 1 1 0 0 0 0 1 0", "stamp_not_increasing"),
    ("frame {next:.6f} 1e308 1 0 0 0 0 1 0", "position_outside_map"),
    ("frame {next:.6f} 1 1 0 0 0 0 3 0", "quaternion_not_unit"),
    ("frame {next:.6f} 1 1", "syntax"),
    ("hello zonemapd", "syntax"),
]


def rss_kib(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def slope_per_1000(xs, ys):
    n = len(xs)
    if n < 2:
        return 0.0
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    return 1000.0 * sxy / sxx if sxx else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", help="build directory with app/zonemapd and app/zonemap")
    ap.add_argument("--zonemapd")
    ap.add_argument("--zonemap", help="to generate the scenario (zonemap sim hospital)")
    ap.add_argument("--scenario", help="an existing scenario directory (else one is generated)")
    ap.add_argument("--emulator", default="", help="command prefix, e.g. qemu-aarch64 -L SYSROOT")
    ap.add_argument("--ticks", type=int, default=1000000)
    ap.add_argument("--policy", default="semantic")
    ap.add_argument("--memory-thr", default="150", help="zonemapd --memory-thr")
    ap.add_argument("--features-every", type=int, default=10)
    ap.add_argument("--footprint-scale", default="0.02",
                    help="zonemap sim --footprint-scale of the generated scenario (1 = device)")
    ap.add_argument("--samples", type=int, default=400, help="RSS samples over the run")
    ap.add_argument("--max-slope", type=float, default=64.0,
                    help="bytes per 1,000 ticks allowed after warm-up")
    ap.add_argument("--max-growth-mib", type=float, default=2.0)
    ap.add_argument("--no-rss-check", action="store_true",
                    help="report the RSS figures without failing on them (short or ASan runs)")
    ap.add_argument("--period", type=int, default=50000,
                    help="ticks between budget levers (routes every 2x, insane bursts every /5)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--plot", help="write the figure here (PNG)")
    args = ap.parse_args()

    if not args.zonemapd and not args.build:
        ap.error("give --build DIR or --zonemapd BINARY")
    zonemapd = args.zonemapd or os.path.join(args.build, "app", "zonemapd")
    zonemap = args.zonemap or os.path.join(args.build or "", "app", "zonemap")
    emulator = shlex.split(args.emulator)
    os.makedirs(args.out, exist_ok=True)
    scenario = args.scenario or os.path.join(args.out, "scenario")
    if not os.path.exists(os.path.join(scenario, "frames.bin")):
        subprocess.run(emulator + [zonemap, "sim", "hospital", "--seed", "5", "--area", "400",
                                   "--tasks", "3", "--footprint-scale", args.footprint_scale,
                                   # the soak sends `frame` lines with features (a host with its
                                   # own front-end): the oracle's, named (issue 26)
                                   "--features", "oracle", "--quiet", "--out", scenario],
                       check=True, stdout=subprocess.DEVNULL)

    # One pass of the recorded run, formatted once: (stamp, line tail without the stamp).
    frames = zp.FramesFile(os.path.join(scenario, "frames.bin"))
    period = 1.0 / frames.rate_hz if frames.rate_hz > 0 else 0.5
    rows = []
    for i, (stamp, pos, quat, feats) in enumerate(frames):
        keep = feats if args.features_every and i % args.features_every == 0 else []
        line = zp.format_frame(stamp, pos, quat, keep)
        rows.append((stamp, line[line.index(" ", 6):]))  # after "frame <stamp>"
    frames.close()
    pass_s = rows[-1][0] - rows[0][0] + period
    gt = zp.read_tum(os.path.join(scenario, "localization_gt.tum"))
    route = zp.format_route(zp.route_from_truth(gt))

    run_dir = os.path.join(args.out, "run")
    cmd = emulator + [zonemapd, "--profile", "host", "--db", os.path.join(scenario, "map.db"),
                      "--stdin", "--out", run_dir, "--policy", args.policy,
                      "--memory-thr", args.memory_thr]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, bufsize=1 << 20)
    hello = zp.parse_hello(proc.stdout.readline().decode())
    k_max = int(hello["k_max"])

    expected = {}
    state = {"poses": 0, "violations": 0, "acks": [], "samples": [], "bad": 0}
    sample_every = max(1, args.ticks // args.samples)
    lever = max(10, args.period)

    def read():
        for raw in proc.stdout:
            if raw.startswith(b"pose "):
                t = raw.split()
                if len(t) != zp.POSE_TOKENS or t[9] != b"1":
                    state["bad"] += 1
                    continue
                resident, kmax = int(t[22]), int(t[23])
                if resident > kmax:
                    state["violations"] += 1
                state["poses"] += 1
                if state["poses"] % sample_every == 0:
                    rss = rss_kib(proc.pid)
                    if rss:  # 0: zonemapd has already exited (the last lines of a run)
                        state["samples"].append((state["poses"], rss, resident, kmax))
            elif raw.startswith(b"ack "):
                state["acks"].append(zp.parse_ack(raw.decode()))

    reader = threading.Thread(target=read)
    reader.start()
    t0 = time.time()
    out = proc.stdin
    last_stamp = None
    try:
        for tick in range(args.ticks):
            p, i = divmod(tick, len(rows))
            stamp = rows[i][0] + p * pass_s
            if tick % (2 * lever) == 0:
                out.write((route + "\n").encode())
            if tick % lever == lever // 2:
                out.write(("budget %d\n" % max(1, k_max // 2)).encode())
            if tick % lever == lever // 2 + lever // 5:
                out.write(("budget %d\n" % k_max).encode())
            if tick % (lever // 5) == lever // 10 and last_stamp is not None:
                for text, reason in INSANE:
                    out.write((text.format(back=last_stamp - 1.0, next=last_stamp + 1e-4)
                               + "\n").encode())
                    expected[reason] = expected.get(reason, 0) + 1
            out.write(("frame %.6f%s\n" % (stamp, rows[i][1])).encode())
            last_stamp = stamp
        out.close()
    except BrokenPipeError:
        pass
    reader.join()
    rc = proc.wait()
    wall = time.time() - t0

    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    failures = []
    if rc != 0:
        failures.append("zonemapd exited with %d" % rc)
    if state["poses"] != args.ticks:
        failures.append("%d pose lines for %d frames" % (state["poses"], args.ticks))
    if state["violations"] or state["bad"]:
        failures.append("%d pose lines with resident > K_max, %d malformed pose lines" %
                        (state["violations"], state["bad"]))
    if summary["over_budget_ticks"] != 0:
        failures.append("summary: %d ticks over budget" % summary["over_budget_ticks"])
    for reason, n in expected.items():
        if summary["malformed_by_reason"][reason] != n:
            failures.append("%s: %d refused, %d sent" %
                            (reason, summary["malformed_by_reason"][reason], n))
    budgets = [a for a in state["acks"] if a["what"] == "budget"]
    if any(a["resident"] > a["k_max"] for a in budgets):
        failures.append("a budget ack with resident above the new K_max")
    if args.ticks >= lever and not budgets:
        failures.append("no budget line acknowledged")

    samples = state["samples"]
    warm = [s for s in samples if s[0] > args.ticks // 10]
    slope_b = slope_per_1000([s[0] for s in warm], [1024.0 * s[1] for s in warm])
    growth_mib = (max(s[1] for s in warm) - warm[0][1]) / 1024.0 if warm else 0.0
    if abs(slope_b) > args.max_slope and not args.no_rss_check:
        failures.append("RSS slope %.1f bytes / 1000 ticks after warm-up" % slope_b)
    if growth_mib > args.max_growth_mib and not args.no_rss_check:
        failures.append("RSS grew %.2f MiB after warm-up" % growth_mib)

    with open(os.path.join(args.out, "soak.csv"), "w") as f:
        f.write("tick,rss_kib,resident,k_max\n")
        for s in samples:
            f.write("%d,%d,%d,%d\n" % s)
    figures = {
        "ticks": args.ticks, "wall_s": round(wall, 1),
        "us_per_tick": round(1e6 * wall / max(1, args.ticks), 1),
        "policy": args.policy, "k_max": k_max, "features_every": args.features_every,
        "scenario_frames": len(rows), "loop_closures": summary["closures_accepted"],
        "zone_loads": summary["zone_loads"], "keyframes_loaded": summary["keyframes_loaded"],
        "peak_resident_keyframes": summary["peak_resident_keyframes"],
        "over_budget_ticks": summary["over_budget_ticks"],
        "budget_changes": summary["control"]["budget_changes"],
        "routes_accepted": summary["control"]["routes_accepted"],
        "malformed_lines": summary["malformed_lines"],
        "rss_after_warmup_kib": warm[0][1] if warm else None,
        "rss_end_kib": samples[-1][1] if samples else None,
        "rss_max_after_warmup_kib": max(s[1] for s in warm) if warm else None,
        "rss_slope_bytes_per_1000_ticks": round(slope_b, 2),
        "rss_checked": not args.no_rss_check,
        "failures": failures,
    }
    with open(os.path.join(args.out, "soak.json"), "w") as f:
        json.dump(figures, f, indent=2)
    print(json.dumps(figures, indent=2))

    if args.plot and samples:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("soak: matplotlib missing, no figure (try /usr/bin/python3)", file=sys.stderr)
        else:
            fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
            ticks = [s[0] for s in samples]
            a1.plot(ticks, [s[1] / 1024.0 for s in samples], color="#1f77b4", lw=1)
            a1.set_ylabel("zonemapd RSS (MiB)")
            a1.axvspan(0, args.ticks // 10, color="#dddddd", lw=0, label="warm-up")
            a1.set_title("zonemapd soak: %s ticks through the line protocol, %s, K_max %d "
                         "(slope %.1f B / 1000 ticks)" % (format(args.ticks, ","), args.policy,
                                                           k_max, slope_b), fontsize=9)
            a1.legend(loc="lower right", fontsize=8)
            a2.plot(ticks, [s[2] for s in samples], ".", ms=2, color="#2ca02c",
                    label="resident keyframes (sampled)")
            a2.step(ticks, [s[3] for s in samples], where="post", color="#d62728", lw=1,
                    label="K_max in force (budget lines)")
            a2.set_ylabel("keyframes")
            a2.set_xlabel("tick")
            a2.set_ylim(0, k_max * 1.1)
            a2.legend(loc="lower right", fontsize=8)
            fig.tight_layout()
            fig.savefig(args.plot, dpi=110)
            print("soak: figure written to %s" % args.plot)

    if failures:
        for f in failures:
            print("soak: FAILED: " + f, file=sys.stderr)
        return 1
    print("soak: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
