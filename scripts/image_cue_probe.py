#!/usr/bin/python3
"""A probe of a learned image cue for the layout merge (issue 28, after the twenty-ninth round).

  image_cue_probe.py train OUT.pt DIR [DIR ...] [--epochs 40]
  image_cue_probe.py score ZONEMAP NET.pt DIR [DIR ...] [--fold-models DIR] [--threshold T]

Every feature the merge model weighs is hand-made, and none of them moved recall on robot-made
grids (issue 28's rounds). This asks whether a cue learned from the grid's pixels would. `train`
fits a small fully convolutional network (seven 3x3 layers of 24 channels, dilated 1-32: it sees
about 3 m around a cell) to tell, for each free cell that lies in a room, whether another room's
cell is within 0.4 m (across a wall or through a door); inputs are the map's free, occupied and
unknown cells, trained on random 192-cell crops of every map of the DIRs (<name>_map.png and
<name>_gt.png, render_r2v.py's layout), Adam at 1e-3, batches of 8, the border cells weighed
3x. `score` cuts each map of the DIRs into the layout's pieces (zonemap with the merge threshold at
1, so nothing merges), segments it as zonemap does (or with --fold-models DIR/<name>.json at
--threshold, a leave-one-out fold's model), and gives each pair of touching pieces the network's
mean output over their shared border. It prints, per DIR, the ROC AUC of that cue among the pairs
zonemap's merge left apart (one room against two), and P / R / IoU / IoU shown after joining
zonemap's segments wherever such a pair's cue is under 0.1, 0.2, ... 0.4 (0: zonemap's own,
scored as ScoreSegmentation scores). A probe, not a product path: nothing of it is compiled in.

Needs python3-torch (Debian; `scripts/install-deps.sh --probes`), python3-sklearn, numpy, PIL.
"""
import argparse
import glob
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ipa_to_grid import FREE_MIN  # noqa: E402  (zonemap's free threshold)
from segmentation_border_probe import gt_rooms, labels_png, score  # noqa: E402  (as zonemap)

BORDER_CELLS = 8   # another room within 0.4 m of a cell: a border cell
CROP = 192
CUTS = (0.0, 0.1, 0.2, 0.3, 0.4)


def torch_or_exit():
    try:
        import torch
    except ImportError:
        sys.exit("image_cue_probe.py: needs python3-torch (scripts/install-deps.sh --probes)")
    torch.set_num_threads(2)
    return torch


def load(map_png):
    """(input channels, border target, loss mask, room ids, free) over the map and its GT."""
    grey = np.asarray(Image.open(map_png).convert("L"))
    gt_png = map_png[: -len("_map.png")] + "_gt.png"
    gsize = Image.open(gt_png).size  # map and ground truth cropped to their common size
    h, w = min(grey.shape[0], gsize[1]), min(grey.shape[1], gsize[0])
    grey = grey[:h, :w]
    x = np.stack([grey >= FREE_MIN, grey <= 50, (grey > 50) & (grey < FREE_MIN)]).astype(np.float32)
    lab = gt_rooms(gt_png)[:h, :w]
    r = BORDER_CELLS
    padded = np.pad(lab, r)
    border = np.zeros(lab.shape, bool)
    for dy in range(-r, r + 1, 2):
        for dx in range(-r, r + 1, 2):
            if dy * dy + dx * dx <= r * r:
                o = padded[r + dy:r + dy + h, r + dx:r + dx + w]
                border |= (o > 0) & (o != lab)
    free = grey >= FREE_MIN
    return x, (border & (lab > 0)).astype(np.float32), (free & (lab > 0)).astype(np.float32), lab, free


def network(torch):
    nn = torch.nn
    layers = [nn.Conv2d(3, 24, 3, padding=1), nn.ReLU()]
    for d in (2, 4, 8, 16, 32, 1):
        layers += [nn.Conv2d(24, 24, 3, padding=d, dilation=d), nn.ReLU()]
    return nn.Sequential(*layers, nn.Conv2d(24, 1, 1))


def maps_of(dirs):
    out = []
    for d in dirs:
        out += sorted(glob.glob(os.path.join(d, "*_map.png")))
    if not out:
        sys.exit(f"image_cue_probe.py: no *_map.png in {' '.join(dirs)}")
    return out


def train(a):
    torch = torch_or_exit()
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    data = [load(m)[:3] for m in maps_of(a.dirs)]
    net = network(torch)
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    loss_of = torch.nn.BCEWithLogitsLoss(reduction="none", pos_weight=torch.tensor(3.0))
    for epoch in range(a.epochs):
        total, batches = 0.0, 0
        order = rng.permutation(len(data))
        for k in range(0, len(order), 8):
            xs, ys, ms = [], [], []
            for i in order[k:k + 8]:
                x, y, m = data[i]
                ph, pw = max(0, CROP - y.shape[0]), max(0, CROP - y.shape[1])
                x = np.pad(x, ((0, 0), (0, ph), (0, pw)))
                y, m = np.pad(y, ((0, ph), (0, pw))), np.pad(m, ((0, ph), (0, pw)))
                r0 = rng.integers(0, y.shape[0] - CROP + 1)
                c0 = rng.integers(0, y.shape[1] - CROP + 1)
                xs.append(x[:, r0:r0 + CROP, c0:c0 + CROP])
                ys.append(y[r0:r0 + CROP, c0:c0 + CROP])
                ms.append(m[r0:r0 + CROP, c0:c0 + CROP])
            m = torch.tensor(np.stack(ms))[:, None]
            loss = (loss_of(net(torch.tensor(np.stack(xs))), torch.tensor(np.stack(ys))[:, None])
                    * m).sum() / m.sum().clamp(min=1)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total, batches = total + float(loss), batches + 1
        print(f"epoch {epoch}: loss {total / max(batches, 1):.4f}", flush=True)
    torch.save(net.state_dict(), a.out)


def segments(zonemap, map_png, extra, tmp):
    """zonemap's segments of the map (--labels read back as label ids, 0 for none)."""
    png = os.path.join(tmp, "labels.png")
    subprocess.run([zonemap, "zones", "segment", map_png, "--out", os.devnull, "--labels", png]
                   + extra, check=True, capture_output=True)
    return labels_png(png)


def majority(pieces, of):
    """Each piece's most common non-zero value of `of` (0 where it has none), in one pass."""
    m = (pieces > 0) & (of > 0)
    stride = int(of.max()) + 1
    n = int(pieces.max()) + 1
    counts = np.bincount(pieces[m].astype(np.int64) * stride + of[m].astype(np.int64),
                         minlength=n * stride).reshape(n, stride)
    best = counts.argmax(axis=1)  # 0 for a piece with no count: column 0 is never counted
    return {int(i): int(best[i]) for i in np.unique(pieces[pieces > 0])}


def score_cmd(a):
    torch = torch_or_exit()
    from sklearn.metrics import roc_auc_score
    net = network(torch)
    net.load_state_dict(torch.load(a.net))
    net.eval()
    with tempfile.TemporaryDirectory() as tmp:
        for d in a.dirs:
            cue_all, one_all = [], []
            figures = {c: [] for c in CUTS}
            for m in maps_of([d]):
                x, _, _, gt, free = load(m)
                extra = []
                if a.fold_models:
                    name = os.path.basename(m)[: -len("_map.png")]
                    extra = ["--merge-model", os.path.join(a.fold_models, name + ".json"),
                             "--param", f"layout_merge_threshold={a.threshold}"]
                pieces = segments(a.zonemap, m, ["--param", "layout_merge_threshold=1"], tmp)
                final = segments(a.zonemap, m, extra, tmp)
                h = min(pieces.shape[0], gt.shape[0])
                w = min(pieces.shape[1], gt.shape[1])
                pieces, final, gt, free = pieces[:h, :w], final[:h, :w], gt[:h, :w], free[:h, :w]
                with torch.no_grad():
                    p = torch.sigmoid(net(torch.tensor(x[None, :, :h, :w])))[0, 0].numpy()

                room, seg = majority(pieces, gt), majority(pieces, final)
                border = {}
                for s, t, ps, pt in ((pieces[:, :-1], pieces[:, 1:], p[:, :-1], p[:, 1:]),
                                     (pieces[:-1], pieces[1:], p[:-1], p[1:])):
                    sel = (s > 0) & (t > 0) & (s != t)
                    for i, j, u, v in zip(s[sel], t[sel], ps[sel], pt[sel]):
                        acc = border.setdefault((min(i, j), max(i, j)), [0.0, 0])
                        acc[0] += u + v
                        acc[1] += 2
                cue = {k: s / n for k, (s, n) in border.items()}
                for (i, j), c in cue.items():
                    if seg[i] and seg[j] and seg[i] != seg[j]:
                        cue_all.append(c)
                        one_all.append(int(room[i] != 0 and room[i] == room[j]))
                for cut in CUTS:
                    parent = {}

                    def root(s):
                        while parent.get(s, s) != s:
                            s = parent[s]
                        return s
                    for (i, j), c in cue.items():
                        if c < cut and seg[i] and seg[j] and root(seg[i]) != root(seg[j]):
                            parent[root(seg[j])] = root(seg[i])
                    lut = np.array([root(s) for s in range(final.max() + 1)])
                    figures[cut].append(score(lut[final], gt, free))
            auc = (roc_auc_score(one_all, -np.asarray(cue_all)) if len(set(one_all)) == 2
                   else float("nan"))
            print(f"{d}: {len(figures[0.0])} maps, {len(cue_all)} pairs left apart "
                  f"({sum(one_all)} one room), cue AUC among them {auc:.3f}")
            for cut in CUTS:
                f = np.mean(figures[cut], axis=0) * 100
                per = " ".join(f"{v[2] * 100:.1f}" for v in figures[cut]) if a.per_map else ""
                print(f"  joined where cue < {cut:.1f}: " + " / ".join(f"{v:.1f}" for v in f)
                      + (f"  (IoU per map: {per})" if per else ""))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("out")
    t.add_argument("dirs", nargs="+")
    t.add_argument("--epochs", type=int, default=40)
    s = sub.add_parser("score")
    s.add_argument("zonemap")
    s.add_argument("net")
    s.add_argument("dirs", nargs="+")
    s.add_argument("--fold-models")
    s.add_argument("--threshold", type=float, default=0.5)
    s.add_argument("--per-map", action="store_true")
    a = ap.parse_args(argv)
    if a.cmd == "train":
        if a.epochs < 1:
            ap.error(f"--epochs {a.epochs}: at least 1")
        train(a)
    else:
        score_cmd(a)


if __name__ == "__main__":
    main(sys.argv[1:])
