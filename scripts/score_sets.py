#!/usr/bin/python3
"""Scores `zonemap zones segment` on sets of maps with ground truth (<name>_map.png and
<name>_gt.png per DIR: ../shared/data/floorplans, scripts/render_r2v.py's and render_sim.py's
output) and prints one markdown row per DIR (mean precision, recall and mean IoU over its maps,
the mean and largest segmentation time), or with --per-map one row per map. "IoU shown" is the
mean IoU over the GT rooms the map shows (from 200 free cells; a room the robot never entered is
left out, where mean IoU counts it 0: docs/segmentation.md, issue 28, second round).
--merge-model runs another layout merge model than the compiled-in one (docs/segmentation.md,
issue 28); --param K=V (repeatable) passes a segmentation option to every run, as
`zones segment --param` does (the probes of issue 28's second and third rounds). --oracle merges
the layout pieces by the ground truth instead of by a model (`zones segment --merge-oracle`): the
best any merge of the cut's pieces can score, so what is left below it is the cut's (issue 28,
eleventh round).

Usage: scripts/score_sets.py ZONEMAP DIR [DIR ...] [--per-map]
           [--merge-model MODEL.json | --oracle] [--param K=V ...]
"""
import argparse
import json
import os
import subprocess
import tempfile


def score(zonemap, map_png, gt_png, extra):
    out = subprocess.run([zonemap, "zones", "segment", map_png, "--out", os.devnull, "--score",
                          gt_png, "--json"] + extra, check=True, capture_output=True,
                         text=True).stdout
    j = json.loads(out)
    s = j["score"]
    return 100 * s["precision"], 100 * s["recall"], 100 * s["mean_iou"], j["segment_ms"], \
        s["gt_rooms"], j["zones"], 100 * s["mean_iou_shown"], s["gt_rooms_shown"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("zonemap")
    ap.add_argument("dirs", nargs="+", metavar="DIR")
    ap.add_argument("--per-map", action="store_true")
    ap.add_argument("--merge-model")
    ap.add_argument("--param", action="append", default=[], metavar="K=V")
    ap.add_argument("--oracle", action="store_true")
    a = ap.parse_args()
    if a.oracle and a.merge_model:
        ap.error("--oracle merges by the ground truth: no --merge-model with it")
    for d in a.dirs:
        if not os.path.isdir(d) or not any(f.endswith("_map.png") for f in os.listdir(d)):
            ap.error(f"{d}: no <name>_map.png in it (render_r2v.py writes plan/, scan/, robot/ "
                     "under its OUT_DIR)")
    extra = ["--merge-model", a.merge_model] if a.merge_model else []
    trace_dir = tempfile.TemporaryDirectory() if a.oracle else None
    if trace_dir:  # the oracle runs only as a trace's; the rows are not wanted here
        extra += ["--merge-oracle", "--merge-trace", os.path.join(trace_dir.name, "pairs.csv")]
    for kv in a.param:
        extra += ["--param", kv]
    if a.per_map:
        print("| map | GT rooms (shown) | zones | precision % | recall % | mean IoU % | "
              "IoU shown % | segmentation ms |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
    else:
        print("| set | maps | precision % | recall % | mean IoU % | IoU shown % | mean / max ms |")
        print("|---|---:|---:|---:|---:|---:|---:|")
    for d in a.dirs:
        rows = []
        for f in sorted(os.listdir(d)):
            if not f.endswith("_map.png"):
                continue
            name = f[: -len("_map.png")]
            p, r, i, ms, g, z, i_s, g_s = score(a.zonemap, os.path.join(d, f),
                                                os.path.join(d, name + "_gt.png"), extra)
            rows.append((p, r, i, i_s, ms))
            if a.per_map:
                print(f"| {name} | {g} ({g_s}) | {z} | {p:.1f} | {r:.1f} | {i:.1f} | {i_s:.1f} | "
                      f"{ms:.0f} |", flush=True)
        m = [sum(x[k] for x in rows) / len(rows) for k in range(5)]
        print(f"| {'**mean**' if a.per_map else d} | {len(rows)} | {m[0]:.1f} | {m[1]:.1f} | "
              f"{m[2]:.1f} | {m[3]:.1f} | {m[4]:.0f} / {max(x[4] for x in rows):.0f} |",
              flush=True)


if __name__ == "__main__":
    main()
