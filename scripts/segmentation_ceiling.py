#!/usr/bin/python3
"""How far better merge decisions alone could take `zonemap zones segment` (issue 16).

Runs the segmentation with merges switched off (and any other `--param K=V` given), so that
every candidate border (walls, doorways, openings) stays a border, then merges the pieces with
knowledge of the ground truth: every piece joins the GT room holding most of its cells. The mean
IoU of those unions (over the cells in some GT room and some piece, the scoring's convention)
is a ceiling for any rule that only decides which candidate borders to keep: when it is low, the
borders themselves are missing from the map's evidence, not the merge decisions.

Usage: scripts/segmentation_ceiling.py ZONEMAP DIR [DIR ...] [--param K=V ...]
Each DIR holds <name>_map.png and <name>_gt.png (scripts/render_r2v.py's layout).
Needs python3-numpy and python3-pil (Debian; PIL comes with python3-matplotlib).
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

MERGES_OFF = ["opening_merge_ratio=0", "opening_local_ratio=0", "merge_open_border_ratio=0",
              "min_room_area_m2=0"]
MIN_ROOM_CELLS = 200  # the scorer's threshold for a GT colour to be a room (0.5 m2)


def colour_keys(path):
    a = np.array(Image.open(path).convert("RGB")).astype(np.int64)
    return a, a[..., 0] * 65536 + a[..., 1] * 256 + a[..., 2]


def ceiling(zonemap, map_png, gt_png, params, labels_png):
    cmd = [zonemap, "zones", "segment", map_png, "--out", os.devnull, "--labels", labels_png]
    for p in params:
        cmd += ["--param", p]
    subprocess.run(cmd, check=True, capture_output=True)
    _, gt = colour_keys(gt_png)
    rgb, lab = colour_keys(labels_png)
    h, w = min(gt.shape[0], lab.shape[0]), min(gt.shape[1], lab.shape[1])
    gt, lab, rgb = gt[:h, :w], lab[:h, :w], rgb[:h, :w]
    # The label image draws segments in colours and everything else in greys.
    grey = (rgb[..., 0] == rgb[..., 1]) & (rgb[..., 1] == rgb[..., 2])
    piece = np.where(grey, -1, lab)
    values, counts = np.unique(gt, return_counts=True)
    rooms = [v for v, c in zip(values, counts) if v != 0 and c >= MIN_ROOM_CELLS]
    in_room = np.isin(gt, rooms)
    owner = {}
    for p in np.unique(piece[piece >= 0]):
        r, c = np.unique(gt[(piece == p) & in_room], return_counts=True)
        owner[p] = r[c.argmax()] if len(r) else 0
    scored = (piece >= 0) & in_room
    ious = []
    for v in rooms:
        room = gt == v
        mine = np.isin(piece, [p for p, o in owner.items() if o == v])
        union = ((mine | room) & scored).sum()
        ious.append((mine & room & scored).sum() / union if union else 0.0)
    return ious


def main(argv):
    params = list(MERGES_OFF)
    args = []
    i = 0
    while i < len(argv):
        if argv[i] == "--param":
            params.append(argv[i + 1])
            i += 2
        else:
            args.append(argv[i])
            i += 1
    if len(args) < 2:
        sys.exit(__doc__)
    zonemap, dirs = args[0], args[1:]
    print("| set | maps | GT rooms | ceiling mean IoU % |")
    print("|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for d in dirs:
            ious, maps = [], 0
            for f in sorted(os.listdir(d)):
                if not f.endswith("_map.png"):
                    continue
                name = f[: -len("_map.png")]
                ious += ceiling(zonemap, os.path.join(d, f), os.path.join(d, name + "_gt.png"),
                                params, os.path.join(tmp, "labels.png"))
                maps += 1
            print(f"| {d} | {maps} | {len(ious)} | {100 * np.mean(ious):.1f} |")
    print(f"\nparams: {' '.join(params)}")


if __name__ == "__main__":
    main(sys.argv[1:])
