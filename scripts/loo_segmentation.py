#!/usr/bin/env python3
"""Leave-one-out evaluation of `zonemap zones segment` on the shared floor plans.

The segmentation's free choices (below: CANDIDATES, each value a physical quantity) are picked
by the best mean IoU over the OTHER maps, then the held-out map is scored with that pick, for
each map in turn: the per-map table shows what a new building would get from the procedure that
chose the defaults. The last rows show the pick over all maps (what the code's defaults must
equal) and the published numbers. Optionally a second directory of held-out maps is scored with
the all-maps pick only (never used to choose anything).

Usage: scripts/loo_segmentation.py ZONEMAP FLOORPLAN_DIR [HELDOUT_DIR ...]
Standard library only; each run is `zonemap zones segment MAP --score GT --param K=V ... --json`.
"""
import itertools
import json
import os
import subprocess
import sys
import tempfile

# Each choice is a physical quantity with a plausible range, not a per-map fit:
#   wall_min_length_m: shortest straight run that counts as a wall when decluttering (0 = off);
#   door_max_width_m: widest gap between collinear walls taken as a door (0 = off); at most
#   1.2 m, the narrowest corridor building codes allow, so that two room walls aligned across a
#   corridor never close it (wider doors are left to the clearance hierarchy);
#   merge_min_opening_m: narrowest opening that joins two segments into one room;
#   merge_no_constriction_ratio: a border this wide relative to the narrower segment is no
#   constriction at all (0 = off).
CANDIDATES = {
    "wall_min_length_m": [0.0, 1.0, 1.5],
    "door_max_width_m": [0.0, 0.9, 1.2],
    "merge_min_opening_m": [1.8, 2.4],
    "merge_no_constriction_ratio": [0.0, 0.8],
}
PUBLISHED = [("ROSE² (published, 11 maps)", 89.0, 93.9, 73.3),
             ("ipa morphological (published)", 85.0, 82.3, 51.2),
             ("ipa distance transform (published)", 88.3, 79.8, 54.7),
             ("ipa Voronoi (published)", 85.9, 71.9, 28.7)]


def maps_in(directory):
    return sorted(f[:-len("_map.png")] for f in os.listdir(directory) if f.endswith("_map.png"))


def run(zonemap, directory, name, params, out):
    cmd = [zonemap, "zones", "segment", os.path.join(directory, name + "_map.png"),
           "--score", os.path.join(directory, name + "_gt.png"),
           "--out", os.path.join(out, name + ".geojson"), "--json"]
    for k, v in params:
        cmd += ["--param", f"{k}={v}"]
    j = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    s = j["score"]
    return {"p": 100 * s["precision"], "r": 100 * s["recall"], "iou": 100 * s["mean_iou"],
            "zones": j["zones"], "gt": s["gt_rooms"], "ms": j["segment_ms"]}


def label(params):
    return ", ".join(f"{k}={v:g}" for k, v in params)


def mean(rows, key):
    return sum(r[key] for r in rows) / len(rows)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    zonemap, plans, heldout = sys.argv[1], sys.argv[2], sys.argv[3:]
    names = maps_in(plans)
    grid = [tuple(zip(CANDIDATES, values)) for values in itertools.product(*CANDIDATES.values())]
    out = tempfile.mkdtemp(prefix="zm_loo_")
    results = {(c, n): run(zonemap, plans, n, c, out) for c in grid for n in names}

    def best(pool):
        # Ties (rare) go to the earlier candidate in grid order.
        return max(grid, key=lambda c: sum(results[(c, n)]["iou"] for n in pool) / len(pool))

    print("| held-out map | pick (chosen on the other maps) | GT rooms | zones | precision % "
          "| recall % | mean IoU % |")
    print("|---|---|---:|---:|---:|---:|---:|")
    loo_rows = []
    for n in names:
        pick = best([m for m in names if m != n])
        r = results[(pick, n)]
        loo_rows.append(r)
        print(f"| {n} | {label(pick)} | {r['gt']} | {r['zones']} | {r['p']:.1f} | {r['r']:.1f} "
              f"| {r['iou']:.1f} |")
    print(f"| **leave-one-out mean** | | | | **{mean(loo_rows, 'p'):.1f}** | "
          f"**{mean(loo_rows, 'r'):.1f}** | **{mean(loo_rows, 'iou'):.1f}** |")
    final = best(names)
    rows = [results[(final, n)] for n in names]
    print(f"| all {len(names)} maps, pick on all ({label(final)}) | | | | {mean(rows, 'p'):.1f} "
          f"| {mean(rows, 'r'):.1f} | {mean(rows, 'iou'):.1f} |")
    for name, p, r, i in PUBLISHED:
        print(f"| {name} | | | | {p} | {r} | {i} |")
    print(f"\nPick on all maps (the code's defaults): {label(final)}")
    for directory in heldout:
        print(f"\nHeld-out maps in {directory}, pick on all shared maps ({label(final)}):\n")
        print("| map | GT rooms | zones | precision % | recall % | mean IoU % | runtime ms |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        rows = []
        for n in maps_in(directory):
            r = run(zonemap, directory, n, final, out)
            rows.append(r)
            print(f"| {n} | {r['gt']} | {r['zones']} | {r['p']:.1f} | {r['r']:.1f} | "
                  f"{r['iou']:.1f} | {r['ms']:.0f} |")
        print(f"| **mean** | | | **{mean(rows, 'p'):.1f}** | **{mean(rows, 'r'):.1f}** | "
              f"**{mean(rows, 'iou'):.1f}** | |")


if __name__ == "__main__":
    main()
