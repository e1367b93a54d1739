#!/usr/bin/python3
"""Which maps of a set are the same place: the free space two grids share at their best alignment
(issue 28, thirtieth round).

  grid_overlap.py DIR [DIR ...] [--against DIR [DIR ...]] [--min-iou 0.5] [--coarse K] [--gt]
                  [--layout [--min-layout 0.5]]

A mean over "maps never trained on" says what it claims only if its maps are other places than the
training maps, and it weighs places alike only if no place is in it several times (one home mapped
by five vacuums, one R2V plan stored twice). This reads every *_map.png of the DIRs (free cells:
grey >= FREE_MIN, as ipa_to_grid.py writes them and zonemap reads them) and, for each pair of
maps, finds the largest IoU of their free cells over every translation (one FFT cross-correlation)
and each of the eight rotations by 90 degrees and mirror images. Without --against every pair of
the DIRs' maps is compared; with it, every map of the DIRs against every map of --against (an
untouched set against a training set). Pairs at or above --min-iou are printed, highest first.
--coarse K compares the grids K x K cells to one (a block is free if most of it is), for large
sets; 1 compares cell by cell. --gt compares the ground truths' room cells (<name>_gt.png, any
colour but black) instead of the maps' free cells: the same layout rendered with other clutter,
rays or noise (render_r2v.py's robot/ and laser/) then still matches.

A footprint is not a layout: many flats are rectangles of about one size, and their footprints
overlap as much as two renders of one plan do. --layout compares each pair that passed, at full
resolution, by the ground truths' room borders (cells where two rooms, or a room and no room,
meet), widened by BORDER_WIDEN cells: the IoU of those at their best alignment, printed beside the
footprint's and kept only at or above --min-layout. On R2V's flats one plan in two listings scored
0.889, flats of one type with other rooms 0.6-0.72, unrelated flats about 0.3. Both grids are
taken at one cell size (zonemap's PNGs: 0.05 m). Every grid's spectra are held at one padded
shape (the largest grid's), so memory grows with the largest grid and the number of maps: 427 R2V
renders at --coarse 4 take 0.8 GB and 210 s on one core. numpy, scipy (python3-sklearn's) and
PIL.
"""
import argparse
import functools
import glob
import os
import sys

import numpy as np
from PIL import Image
from scipy import ndimage

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ipa_to_grid import FREE_MIN  # noqa: E402

BORDER_WIDEN = 2   # cells (0.1 m) each side of a room border: a render's walls move by a cell


def rooms_of(map_png):
    """The map's ground truth, each colour but black one room. Not gt_rooms's reading (the
    scorer's, which drops colours under 0.5 m2): for telling one plan from another, a closet
    is part of the layout."""
    rgb = np.asarray(Image.open(map_png[:-len("_map.png")] + "_gt.png").convert("RGB"))
    return rgb.astype(np.int64) @ np.array([1 << 16, 1 << 8, 1])


@functools.lru_cache(maxsize=None)   # a map is in many pairs; read and widen it once
def room_borders(map_png):
    """The ground truth's room borders (cells with a 4-neighbour of another room, or of no
    room), widened by BORDER_WIDEN cells, as 0/1 float64."""
    lab = rooms_of(map_png)
    cross = ndimage.generate_binary_structure(2, 1)
    edge = ndimage.grey_erosion(lab, footprint=cross) != ndimage.grey_dilation(lab, footprint=cross)
    side = 2 * BORDER_WIDEN + 1
    return ndimage.binary_dilation(edge, structure=np.ones((side, side))).astype(np.float64)


def cells(map_png, coarse, gt=False):
    """The map's free cells (or with gt its ground truth's room cells) as 0/1 float64, K x K
    blocks to one cell when coarse > 1."""
    if gt:
        on = rooms_of(map_png) > 0
    else:
        on = np.asarray(Image.open(map_png).convert("L")) >= FREE_MIN
    if coarse > 1:
        h, w = (on.shape[0] // coarse) * coarse, (on.shape[1] // coarse) * coarse
        blocks = on[:h, :w].reshape(h // coarse, coarse, w // coarse, coarse)
        on = blocks.mean(axis=(1, 3)) > 0.5
    return on.astype(np.float64)


def fast_length(n):
    """The least m >= n whose only prime factors are 2, 3 and 5: numpy's FFT is slow on a
    length with a large prime factor (a 239-cell side costs several times a 240-cell one)."""
    while True:
        m = n
        for p in (2, 3, 5):
            while m % p == 0:
                m //= p
        if m == 1:
            return n
        n += 1


def orientations(b):
    """The eight images of b under rotations by 90 degrees and a mirror."""
    for k in range(4):
        r = np.rot90(b, k)
        yield r
        yield r[:, ::-1]


class Spectra:
    """Each grid's FFT at one padded shape, so a pair costs eight products and inverse FFTs.

    The shape leaves room for every overlap of any two of the grids (no wrap-around): the
    largest height and width plus the largest side. Correlation is a convolution with the
    other grid turned by 180 degrees, so the right-hand grids are kept in their eight
    orientations, each turned."""

    def __init__(self, grids, right):
        side = max(max(g.shape) for g in grids.values())
        self.shape = (fast_length(max(g.shape[0] for g in grids.values()) + side),
                      fast_length(max(g.shape[1] for g in grids.values()) + side))
        self.count = {m: g.sum() for m, g in grids.items()}
        self.left = {m: np.fft.rfft2(g, self.shape) for m, g in grids.items()}
        self.right = {m: [np.fft.rfft2(o[::-1, ::-1], self.shape)
                          for o in orientations(grids[m])] for m in right}

    def best_iou(self, m, n):
        """Largest IoU of m's and n's cells over translations and the eight orientations of n."""
        na, nb = self.count[m], self.count[n]
        if na == 0 or nb == 0:
            return 0.0
        best = 0.0
        for fb in self.right[n]:
            # The maximum of the correlation is the largest number of cells both hold.
            shared = np.fft.irfft2(self.left[m] * fb, self.shape).max()
            shared = min(round(float(shared)), na, nb)
            best = max(best, shared / (na + nb - shared))
        return best


def best_iou(a, b):
    """Largest IoU of a's and b's cells over translations and the eight orientations of b."""
    return Spectra({0: a, 1: b}, [1]).best_iou(0, 1)


def maps_of(dirs):
    out = []
    for d in dirs:
        out += sorted(glob.glob(os.path.join(d, "*_map.png")))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__)
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--against", nargs="+", default=None)
    ap.add_argument("--min-iou", type=float, default=0.5)
    ap.add_argument("--coarse", type=int, default=1)
    ap.add_argument("--gt", action="store_true")
    ap.add_argument("--layout", action="store_true")
    ap.add_argument("--min-layout", type=float, default=0.5)
    a = ap.parse_args()
    if a.coarse < 1:
        sys.exit(f"grid_overlap.py: --coarse must be 1 or more, not {a.coarse}")
    for flag, v in (("--min-iou", a.min_iou), ("--min-layout", a.min_layout)):
        if not 0.0 <= v <= 1.0:
            sys.exit(f"grid_overlap.py: {flag} must be in [0, 1], not {v}")
    left = maps_of(a.dirs)
    right = maps_of(a.against) if a.against else left
    if not left or not right:
        sys.exit("grid_overlap.py: no *_map.png in " + " ".join(a.dirs + (a.against or [])))
    grids = {m: cells(m, a.coarse, a.gt) for m in set(left) | set(right)}
    spectra = Spectra(grids, set(right))
    name = lambda m: os.path.basename(m)[:-len("_map.png")]  # noqa: E731
    hits, pairs = [], 0
    for i, m in enumerate(left):
        for n in (right if a.against else left[i + 1:]):
            if m == n:
                continue
            pairs += 1
            iou = spectra.best_iou(m, n)
            if iou < a.min_iou:
                continue
            if not a.layout:
                hits.append((iou, name(m), name(n)))
                continue
            layout = best_iou(room_borders(m), room_borders(n))
            if layout >= a.min_layout:
                hits.append((layout, iou, name(m), name(n)))
    for hit in sorted(hits, reverse=True):
        print("  ".join(f"{v:.3f}" if isinstance(v, float) else v for v in hit))
    what = "ground truth's room cells" if a.gt else "free cells"
    print(f"{len(hits)} of {pairs} pairs share at least {a.min_iou:.2f} of their {what} "
          f"(IoU, best of translations and 8 orientations, {a.coarse}x{a.coarse} cells to one)"
          + (f" and at least {a.min_layout:.2f} of their room borders (layout IoU, first column)"
             if a.layout else ""))


if __name__ == "__main__":
    main()
