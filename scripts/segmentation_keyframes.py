#!/usr/bin/env python3
"""Zones as memory units: the keyframe count of every automatic zone after the simulator's
mapping run, per shared floor plan.

For each MAP_map.png in FLOORPLAN_DIR: `zonemap sim floorplan` (mapping run only matters: one
patrol task, small payloads) -> `zonemap zones segment map.yaml` (the automatic zones) ->
`zonemap zones annotate --band 0.5 --json` (the default doorway band) -> per-zone keyframe
counts. Then the same with the oversize split (`zones segment --db map.db --max-zone-keyframes
CAP`) annotated with the default band and with `--band 0`.

Usage: scripts/segmentation_keyframes.py ZONEMAP FLOORPLAN_DIR OUT_DIR [CAP]
"""
import json
import os
import statistics
import subprocess
import sys


def sh(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def counts(zonemap, db, zones, band):
    j = json.loads(sh(zonemap, "zones", "annotate", db, zones, "--band", str(band), "--json"))
    return sorted(z["keyframes"] for z in j["zones"]), j["keyframes"], j["unassigned"]


def describe(c):
    q = statistics.quantiles(c, n=10) if len(c) > 1 else c * 9
    return (f"{len(c)} | {sum(1 for v in c if v == 0)} | {c[0]} | {statistics.median(c):.0f} | "
            f"{q[8]:.0f} | {c[-1]}")


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    zonemap, plans, out = sys.argv[1:4]
    cap = int(sys.argv[4]) if len(sys.argv) > 4 else 60
    print("| map | keyframes | run | zones | empty | min | median | p90 | max |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for f in sorted(os.listdir(plans)):
        if not f.endswith("_map.png"):
            continue
        name = f[:-len("_map.png")]
        d = os.path.join(out, name)
        sh(zonemap, "sim", "floorplan", os.path.join(plans, f), "--gt",
           os.path.join(plans, name + "_gt.png"), "--tasks", "1", "--dense", "32x24",
           "--max-features", "60", "--features", "oracle", "--quiet", "--out", d)
        db, grid = os.path.join(d, "map.db"), os.path.join(d, "map.yaml")
        auto, capped = os.path.join(d, "auto.geojson"), os.path.join(d, "auto_cap.geojson")
        sh(zonemap, "zones", "segment", grid, "--out", auto)
        sh(zonemap, "zones", "segment", grid, "--out", capped, "--db", db,
           "--max-zone-keyframes", str(cap))
        for label, zones, band in (("automatic, band 0.5 m", auto, 0.5),
                                   (f"cap {cap}, band 0.5 m", capped, 0.5),
                                   (f"cap {cap}, band 0", capped, 0.0)):
            c, total, unassigned = counts(zonemap, db, zones, band)
            note = f" ({unassigned} unassigned)" if unassigned else ""
            print(f"| {name} | {total}{note} | {label} | {describe(c)} |")


if __name__ == "__main__":
    main()
