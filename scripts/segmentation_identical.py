#!/usr/bin/python3
"""Checks that two builds of `zonemap zones segment` give byte-identical zones: for every
<name>_map.png of each DIR (../shared/data/floorplans, scripts/render_r2v.py's and
render_sim.py's output), the GeoJSON and the --labels PNG of both, with the defaults and, with
--rules too, with the rule merges (--param layout_merge_threshold=0). For changes that must not
move any zone (issue 28's runtime work: docs/segmentation.md, "Runtime"); prints each map whose
output differs and the CPU time (user + sys) of both builds, exit 1 when any differs.

Usage: scripts/segmentation_identical.py ZONEMAP_A ZONEMAP_B DIR [DIR ...] [--rules]
"""
import argparse
import glob
import os
import resource
import subprocess
import sys
import tempfile


def run(zonemap, map_png, out_dir, extra):
    """Runs one segmentation; returns its outputs' bytes and its CPU time (s)."""
    geojson = os.path.join(out_dir, "zones.geojson")
    labels = os.path.join(out_dir, "labels.png")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([zonemap, "zones", "segment", map_png, "--out", geojson, "--labels", labels]
                   + extra, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    with open(geojson, "rb") as g, open(labels, "rb") as png:
        return (g.read(), png.read()), cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("zonemap_a")
    ap.add_argument("zonemap_b")
    ap.add_argument("dirs", nargs="+", metavar="DIR")
    ap.add_argument("--rules", action="store_true",
                    help="also compare the rule merges (--param layout_merge_threshold=0)")
    a = ap.parse_args()
    variants = [[]] + ([["--param", "layout_merge_threshold=0"]] if a.rules else [])
    maps = sorted(m for d in a.dirs for m in glob.glob(os.path.join(d, "*_map.png")))
    if not maps:
        sys.exit("no *_map.png in " + " ".join(a.dirs))
    differ = 0
    cpu = [0.0, 0.0]
    with tempfile.TemporaryDirectory() as tmp:
        for m in maps:
            for extra in variants:
                out_a, cpu_a = run(a.zonemap_a, m, tmp, extra)
                out_b, cpu_b = run(a.zonemap_b, m, tmp, extra)
                cpu[0] += cpu_a
                cpu[1] += cpu_b
                if out_a != out_b:
                    differ += 1
                    print(f"DIFFERS: {m} {' '.join(extra)}")
    runs = len(maps) * len(variants)
    print(f"{runs - differ} of {runs} runs identical ({len(maps)} maps); CPU time "
          f"{cpu[0]:.2f} s (A) / {cpu[1]:.2f} s (B), B/A {cpu[1] / max(cpu[0], 1e-9):.2f}")
    sys.exit(1 if differ else 0)


if __name__ == "__main__":
    main()
