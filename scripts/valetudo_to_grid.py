#!/usr/bin/python3
"""Real robot vacuums' maps of homes, with the rooms their owners keep, from Valetudo's JSON
(issue 28, twenty-ninth round).

  valetudo_to_grid.py JSON_DIR OUT_DIR

Valetudo (github.com/Hypfer/Valetudo, Apache-2.0) serves a lidar vacuum's map as a ValetudoMap
JSON: a cell size (`pixelSize`, centimetres) and layers of cells, each a list of (x, y) pairs
(`pixels`) or of runs (`compressedPixels`: x, y and a count of cells from x to the right). A
`wall` layer holds what the lidar saw as occupied, a `floor` layer the free cells no room holds,
and one `segment` layer per room (its `metaData` gives the room's id and, when the owner named it,
its name) holds that room's free cells. The rooms are the vacuum's own segmentation as its owner
keeps it (the firmware proposes them; the app lets the owner split and join them), not a ground
truth drawn independently of any algorithm. This reads every *.json of JSON_DIR and writes, per
map,
  OUT_DIR/valetudo_NAME_map.png  8-bit grey over the layers' bounding box and a margin: 254 free
                                 (floor and segments), 0 occupied (wall), 205 unknown
  OUT_DIR/valetudo_NAME_gt.png   RGB, one flat colour per segment, black elsewhere (as the shared
                                 maps' ground truth; ipa_to_grid.py's colours)
A wall cell that a layer also lists as free stays a wall. Segments under MIN_ROOM_CELLS get no
colour: the scorer would drop them anyway. A map of another cell size than 5 cm is refused
(zonemap reads a PNG at 0.05 m per cell). Only the standard library, numpy and PIL.
"""
import json
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ipa_to_grid import MIN_ROOM_CELLS, colour  # noqa: E402

CELL_CM = 5   # zonemap's PNG resolution, 0.05 m
MARGIN = 10   # cells of unknown around the layers' bounding box


def layer_cells(layer):
    """The layer's cells as two int arrays (x, y)."""
    runs = layer.get("compressedPixels") or []
    if runs:
        if len(runs) % 3:
            raise ValueError(f"a {layer.get('type')} layer's compressedPixels is not triples")
        r = np.asarray(runs, np.int64).reshape(-1, 3)
        if (r[:, 2] < 1).any():
            raise ValueError(f"a {layer.get('type')} layer has a run of fewer than one cell")
        xs = np.concatenate([np.arange(x, x + n) for x, _, n in r])
        ys = np.repeat(r[:, 1], r[:, 2])
        return xs, ys
    pixels = layer.get("pixels") or []
    if len(pixels) % 2:
        raise ValueError(f"a {layer.get('type')} layer's pixels are not pairs")
    p = np.asarray(pixels, np.int64).reshape(-1, 2)
    return p[:, 0], p[:, 1]


def convert(path):
    """(grey map, RGB ground truth, [(segment id, name, cells)]) of one ValetudoMap file."""
    d = json.load(open(path, encoding="utf-8"))
    if d.get("__class") != "ValetudoMap":
        raise ValueError(f"{path}: not a ValetudoMap (its __class is {d.get('__class')!r})")
    if d.get("pixelSize") != CELL_CM:
        raise ValueError(f"{path}: cells of {d.get('pixelSize')} cm, only {CELL_CM} cm is read")
    layers = [(l["type"], l.get("metaData") or {}, *layer_cells(l)) for l in d["layers"]]
    for l, (t, _, x, _) in zip(d["layers"], layers):
        count = (l.get("dimensions") or {}).get("pixelCount")
        if count is not None and count != len(x):  # a copy that lost or gained digits
            raise ValueError(f"{path}: a {t} layer holds {len(x)} cells, its pixelCount says "
                             f"{count}")
    cells = [(t, m, x, y) for t, m, x, y in layers if len(x)]
    if not any(t == "segment" for t, *_ in cells):
        raise ValueError(f"{path}: no segment layer, no rooms to score against")
    x0 = min(int(x.min()) for _, _, x, _ in cells) - MARGIN
    y0 = min(int(y.min()) for _, _, _, y in cells) - MARGIN
    w = max(int(x.max()) for _, _, x, _ in cells) - x0 + MARGIN + 1
    h = max(int(y.max()) for _, _, _, y in cells) - y0 + MARGIN + 1
    grey = np.full((h, w), 205, np.uint8)
    gt = np.zeros((h, w, 3), np.uint8)
    rooms = []
    for t, m, x, y in cells:
        if t in ("floor", "segment"):
            grey[y - y0, x - x0] = 254
    for t, m, x, y in cells:
        if t == "wall":
            grey[y - y0, x - x0] = 0
    segments = sorted(((m, x, y) for t, m, x, y in cells if t == "segment"),
                      key=lambda s: -len(s[1]))
    if len(segments) > 6 ** 3:
        raise ValueError(f"{path}: {len(segments)} segments, more than the 216 colours")
    k = 0
    for m, x, y in segments:
        keep = grey[y - y0, x - x0] == 254  # not where the wall layer says occupied
        if keep.sum() < MIN_ROOM_CELLS:
            continue
        gt[(y - y0)[keep], (x - x0)[keep]] = colour(k)
        k += 1
        rooms.append((str(m.get("segmentId", "")), str(m.get("name", "")), int(keep.sum())))
    return grey, gt, rooms


def main(argv):
    if len(argv) != 3:
        sys.exit(__doc__)
    src, out = argv[1], argv[2]
    names = sorted(f for f in os.listdir(src) if f.endswith(".json"))
    if not names:
        sys.exit(f"{src}: no *.json")
    os.makedirs(out, exist_ok=True)
    for f in names:
        name = "valetudo_" + f[: -len(".json")]
        try:
            grey, gt, rooms = convert(os.path.join(src, f))
        except (ValueError, KeyError, json.JSONDecodeError) as e:
            sys.exit(f"valetudo_to_grid.py: {e}")
        Image.fromarray(grey).save(os.path.join(out, name + "_map.png"))
        Image.fromarray(gt, "RGB").save(os.path.join(out, name + "_gt.png"))
        print(f"{name}: {grey.shape[1]}x{grey.shape[0]} cells, {len(rooms)} rooms of >= "
              f"{MIN_ROOM_CELLS} cells")


if __name__ == "__main__":
    main(sys.argv)
