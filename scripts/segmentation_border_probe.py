#!/usr/bin/python3
"""Where a segmentation loses recall, and what a post-merge on border evidence would do (issue 28,
third round; docs/segmentation.md). Development only: measures, changes nothing in zonemap.

For every map of each DIR (<name>_map.png and <name>_gt.png, scripts/render_r2v.py's layout) it
runs `zonemap zones segment MAP --labels` once with the defaults and reads the final segments
back from the label PNG. Then, in this script:
  1. recall lost per GT room (its cells outside its best segment), split by how each other piece
     of the room meets that best segment: an open border (4-neighbour free cells), only occupied
     cells of a small occupied component between them (< 400 cells: clutter, a leaf, a speck),
     only occupied cells of a larger one (a wall), or not at all within 3 cells;
  2. of the final pairs with an open border, how "wall-like" the border is (share of its cells
     within 2 cells of an occupied cell), its length over the smaller segment's perimeter, the
     smaller segment's area and the size ratio, for pairs of one GT room and of two;
  3. the score (P / R / mean IoU / mean IoU over the rooms the map shows, as ScoreSegmentation)
     after merging every pair a rule accepts, for a few rules: an open border that is long
     against the smaller segment's perimeter and not wall-like, or a separation by clutter alone.
Usage: scripts/segmentation_border_probe.py ZONEMAP LABEL_DIR DIR [DIR ...]
Needs python3-numpy, python3-scipy, python3-pil (Debian).
"""
import collections
import itertools
import os
import subprocess
import sys

import numpy as np
from PIL import Image
from scipy import ndimage

RES = 0.05
CLUTTER_CELLS = 400  # an occupied component smaller than this is clutter, not a wall


def label_of_colour():
    """WriteSegmentationPng's colour of label l (a fixed hash), inverted."""
    lut = {}
    for lab in range(1, 5000):
        h = (lab * 2654435761) & 0xFFFFFFFF
        b, g, r = 64 + (h >> 8) % 192, 64 + (h >> 16) % 192, 64 + (h >> 24) % 192
        lut[(r << 16) | (g << 8) | b] = lab
    return lut


LUT = label_of_colour()


def labels_png(png):
    """zonemap's --labels PNG back to its label ids (0 where no segment: walls, unknown)."""
    im = np.asarray(Image.open(png).convert("RGB")).astype(np.int64)
    key = (im[..., 0] << 16) | (im[..., 1] << 8) | im[..., 2]
    lab = np.zeros(key.shape, np.int32)
    for k in np.unique(key):
        if int(k) in LUT:
            lab[key == k] = LUT[int(k)]
    return lab


def gt_rooms(gt_png):
    """The ground truth's rooms as ScoreSegmentation reads them: ids 1..n for the colours of at
    least kDefaultMinGtRoomCells cells that are not black, 0 elsewhere."""
    gi = np.asarray(Image.open(gt_png).convert("RGB")).astype(np.int64)
    gk = (gi[..., 0] << 16) | (gi[..., 1] << 8) | gi[..., 2]
    gk[(gi <= 20).all(axis=2)] = -1
    u, inv, cnt = np.unique(gk, return_inverse=True, return_counts=True)
    ids = np.zeros(len(u), np.int32)
    nxt = 0
    for i, (uu, c) in enumerate(zip(u, cnt)):
        if uu >= 0 and c >= 200:  # kDefaultMinGtRoomCells
            nxt += 1
            ids[i] = nxt
    return ids[inv.reshape(gk.shape)]


def load(zonemap, label_dir, d, name):
    m = os.path.join(d, name + "_map.png")
    lp = os.path.join(label_dir, d.strip("/").replace("/", "_") + "__" + name + ".png")
    if not os.path.exists(lp):
        subprocess.run([zonemap, "zones", "segment", m, "--out", os.devnull, "--labels", lp],
                       check=True, capture_output=True)
    lab = labels_png(lp)
    mp = np.asarray(Image.open(m).convert("L"))
    gt = gt_rooms(os.path.join(d, name + "_gt.png"))
    h, w = min(lab.shape[0], gt.shape[0]), min(lab.shape[1], gt.shape[1])  # as ScoreSegmentation
    return lab[:h, :w], gt[:h, :w], mp[:h, :w] >= 250, mp[:h, :w] <= 50


def score(pred, gt, free):
    """ScoreSegmentation's precision, recall, mean IoU and mean IoU over the rooms shown."""
    m = (pred > 0) & (gt > 0)
    if not m.any():
        return 0.0, 0.0, 0.0, 0.0
    p, g = pred[m], gt[m]
    pairs, n = np.unique(np.stack([p, g]), axis=1, return_counts=True)
    pa = dict(zip(*np.unique(p, return_counts=True)))
    ga = dict(zip(*np.unique(g, return_counts=True)))
    bp, bg, bi = {}, {}, {}
    for (pp, gg), nn in zip(pairs.T, n):
        bp[pp] = max(bp.get(pp, 0), nn)
        bg[gg] = max(bg.get(gg, 0), nn)
        bi[gg] = max(bi.get(gg, 0), nn / (pa[pp] + ga[gg] - nn))
    tot = m.sum()
    rooms = np.unique(gt[gt > 0])
    shown = [r for r in rooms if (free & (gt == r)).sum() >= 200]
    return (sum(bp.values()) / tot, sum(bg.values()) / tot,
            sum(bi.get(r, 0) for r in rooms) / len(rooms),
            sum(bi.get(r, 0) for r in shown) / max(1, len(shown)))


def open_pairs(lab, occ):
    near = ndimage.binary_dilation(occ, structure=np.ones((5, 5)))
    area = np.bincount(lab.ravel())
    inner = ndimage.grey_erosion(lab, footprint=ndimage.generate_binary_structure(2, 1))
    outer = ndimage.grey_dilation(lab, footprint=ndimage.generate_binary_structure(2, 1))
    edge = (lab > 0) & ((inner != lab) | (outer != lab))
    perim = np.bincount(lab[edge], minlength=len(area))
    acc = {}
    for a, b, na, nb in ((lab[:, :-1], lab[:, 1:], near[:, :-1], near[:, 1:]),
                         (lab[:-1, :], lab[1:, :], near[:-1, :], near[1:, :])):
        m = (a > 0) & (b > 0) & (a != b)
        for x, y, w in zip(a[m], b[m], na[m] | nb[m]):
            f = acc.setdefault((min(x, y), max(x, y)), [0, 0])
            f[0] += 1
            f[1] += int(w)
    out = {}
    for (x, y), (n, w) in acc.items():
        s, big = (x, y) if area[x] <= area[y] else (y, x)
        out[(x, y)] = dict(wall_frac=w / n, open_perim_s=n / max(1, perim[s]),
                           area_s=area[s] * RES * RES, ratio=area[s] / area[big])
    return out


def occupied_pairs(lab, occ, r=3):
    comp, _ = ndimage.label(occ, structure=np.ones((3, 3)))
    csize = np.bincount(comp.ravel())
    h, w = lab.shape
    pad = np.pad(lab, r)
    win = np.stack([pad[r + dy:r + dy + h, r + dx:r + dx + w]
                    for dy in range(-r, r + 1) for dx in range(-r, r + 1)])
    lo = np.where(win > 0, win, np.iinfo(np.int32).max).min(axis=0)
    cand = occ & (win.max(axis=0) > 0) & (lo != win.max(axis=0))
    acc = {}
    for y, x in zip(*np.nonzero(cand)):
        ls = np.unique(win[:, y, x])
        for a, b in itertools.combinations(ls[ls > 0], 2):
            f = acc.setdefault((a, b), [0, 0])
            f[0] += 1
            f[1] += int(csize[comp[y, x]] < CLUTTER_CELLS)
    return {k: dict(cells=v[0], clutter_frac=v[1] / v[0]) for k, v in acc.items()}


def majority(lab, gt, x):
    return np.bincount(gt[lab == x]).argmax()


def merged(lab, accepted):
    parent = {}

    def find(x):
        while parent.get(x, x) != x:
            x = parent[x]
        return x

    for x, y in accepted:
        parent[find(x)] = find(y)
    lut = np.arange(lab.max() + 1)
    for i in range(1, len(lut)):
        lut[i] = find(i)
    return lut[lab]


def open_rule(t):
    """An open border at least t of the smaller segment's perimeter, and not wall-like."""
    return lambda o, c: o is not None and o["open_perim_s"] >= t and o["wall_frac"] <= 0.3


RULES = {"none (the shipped defaults)": lambda o, c: False}
for t1 in (0.25, 0.35, 0.5):
    RULES[f"open border >= {t1} of S's perimeter, wall-like <= 0.3"] = open_rule(t1)
RULES["separated by clutter alone (>= 10 cells between)"] = (
    lambda o, c: o is None and c is not None and c["clutter_frac"] == 1.0 and c["cells"] >= 10)


def main():
    zonemap, label_dir, dirs = sys.argv[1], sys.argv[2], sys.argv[3:]
    os.makedirs(label_dir, exist_ok=True)
    for d in dirs:
        lost = collections.Counter()
        feats = {0: collections.defaultdict(list), 1: collections.defaultdict(list)}
        scores = collections.defaultdict(list)
        for fn in sorted(os.listdir(d)):
            if not fn.endswith("_map.png"):
                continue
            lab, gt, free, occ = load(zonemap, label_dir, d, fn[:-8])
            op, oc = open_pairs(lab, occ), occupied_pairs(lab, occ)
            m = (lab > 0) & (gt > 0)
            for g in np.unique(gt[m]):
                ps, n = np.unique(lab[m & (gt == g)], return_counts=True)
                best = ps[n.argmax()]
                for p, k in zip(ps, n):
                    key = (min(p, best), max(p, best))
                    if p == best:
                        continue
                    if key in op:
                        lost["open border"] += k
                    elif key in oc:
                        lost["clutter between" if oc[key]["clutter_frac"] > 0.5
                             else "wall between"] += k
                    else:
                        lost["not adjacent"] += k
            maj = {x: majority(lab, gt, x) for x in np.unique(lab[lab > 0])}
            for (x, y), f in op.items():
                same = int(maj[x] == maj[y] and maj[x] > 0)
                for k, v in f.items():
                    feats[same][k].append(v)
            keys = set(op) | set(oc)
            for name, rule in RULES.items():
                acc = [k for k in keys if rule(op.get(k), oc.get(k))]
                scores[name].append(score(merged(lab, acc), gt, free))
        total = sum(lost.values())
        print(f"== {d}: {len(scores['none (the shipped defaults)'])} maps")
        print("  recall lost by how a room's other pieces meet its best segment: " + ", ".join(
            f"{k} {100 * v / total:.0f} %" for k, v in lost.most_common()))
        print(f"  final open-border pairs: {len(feats[1]['area_s'])} of one GT room, "
              f"{len(feats[0]['area_s'])} of two; quartiles (one room | two rooms):")
        for k in ("wall_frac", "open_perim_s", "area_s", "ratio"):
            q = [np.percentile(feats[s][k], [25, 50, 75]).round(2).tolist() if feats[s][k]
                 else [] for s in (1, 0)]
            print(f"    {k:13s} {q[0]} | {q[1]}")
        for name, v in scores.items():
            print(f"  {name:52s} P/R/IoU/IoU shown % " +
                  " / ".join(f"{100 * x:.1f}" for x in np.mean(v, axis=0)), flush=True)


if __name__ == "__main__":
    main()
