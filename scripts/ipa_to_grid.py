#!/usr/bin/python3
"""Real robot maps with room ground truth from ipa320's room-segmentation dataset (issue 28).

  ipa_to_grid.py SVG_DIR OUT_DIR

Bormann et al. (ICRA 2016) drew their ground truth in Inkscape: each `NAME_gt_segmentation.svg`
embeds the occupancy map as a base64 PNG and, over it, the separators the authors drew across
doorways (filled rectangles and paths, often rotated). A room is a 4-connected component of the
map's free cells once the separators are drawn, which is how the dataset's own ground-truth
images are read. This reads every such SVG of SVG_DIR and writes, per map,
  OUT_DIR/ipa_NAME_map.png  the embedded map as 8-bit grey, unchanged (254 free, 205 unknown,
                            0 occupied in these files; zonemap reads >= 250 as free), or
                            a drawing read as such a map (below)
  OUT_DIR/ipa_NAME_gt.png   RGB, one flat colour per room, black elsewhere, as the shared maps'
Some SVGs embed a drawing instead of a map: office_a-i, and lab_a_scan, lab_b_scan and lab_f
(a white or light grey floor, walls as grey lines or outlined with a grey fill, a grey outside,
edges anti-aliased; fewer than 99 % of the cells at a map's levels 0, 205, 254 and 255). Such an
image is read as a map first (drawn_plan_grid: the floor's grey, or brighter, is free, what is
not floor within 0.3 m of it is wall, the rest unknown), and ipa_NAME_map.png is that map (254 /
0 / 205), not the drawing. (Until issue 28's twenty-seventh round the drawings were written as
they are: zonemap read their grey walls as unknown.)
Components under MIN_ROOM_CELLS (zonemap's own kDefaultMinGtRoomCells, score.h) get no colour:
the scorer would drop them anyway. The resolution is 0.05 m per cell, the dataset's.

Only the standard library, numpy, PIL and render_r2v.py's component labelling and dilation.
"""
import base64
import io
import math
import os
import re
import sys
import xml.etree.ElementTree as ET

import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from render_r2v import RES, components, near  # noqa: E402  (4-connected labels, 1..n; a dilation)

SVG = "{http://www.w3.org/2000/svg}"
XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
FREE_MIN = 250        # zonemap's PNG threshold for a free cell (grid_map.h)
MIN_ROOM_CELLS = 200  # kDefaultMinGtRoomCells (score.h)
MAP_LEVELS = (0, 205, 254, 255)  # a map's grey levels: occupied, unknown, free
MAP_MIN_LEVEL_SHARE = 0.99  # fewer of the image's cells at them: a drawing, not a map
DRAWN_FLOOR_TOLERANCE = 8  # grey levels around a drawn plan's floor colour (anti-aliasing)
DRAWN_WALL_M = 0.3    # a drawn plan's walls: non-floor cells this close to the floor
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
IDENTITY = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)


def compose(m, n):
    """The affine map m∘n, both as SVG's (a, b, c, d, e, f)."""
    a1, b1, c1, d1, e1, f1 = m
    a2, b2, c2, d2, e2, f2 = n
    return (a1 * a2 + c1 * b2, b1 * a2 + d1 * b2, a1 * c2 + c1 * d2, b1 * c2 + d1 * d2,
            a1 * e2 + c1 * f2 + e1, b1 * e2 + d1 * f2 + f1)


def apply(m, x, y):
    a, b, c, d, e, f = m
    return a * x + c * y + e, b * x + d * y + f


def parse_transform(text):
    m = IDENTITY
    for name, args in re.findall(r"(\w+)\s*\(([^)]*)\)", text or ""):
        v = [float(t) for t in re.findall(NUMBER, args)]
        if name == "matrix":
            t = tuple(v)
        elif name == "translate":
            t = (1, 0, 0, 1, v[0], v[1] if len(v) > 1 else 0)
        elif name == "scale":
            t = (v[0], 0, 0, v[1] if len(v) > 1 else v[0], 0, 0)
        elif name == "rotate":
            r = math.radians(v[0])
            t = (math.cos(r), math.sin(r), -math.sin(r), math.cos(r), 0, 0)
            if len(v) == 3:
                t = compose(compose((1, 0, 0, 1, v[1], v[2]), t), (1, 0, 0, 1, -v[1], -v[2]))
        elif name == "skewX":
            t = (1, 0, math.tan(math.radians(v[0])), 1, 0, 0)
        elif name == "skewY":
            t = (1, math.tan(math.radians(v[0])), 0, 1, 0, 0)
        else:
            raise ValueError(f"unknown SVG transform {name}")
        m = compose(m, t)
    return m


def path_polygons(d):
    """A path's subpaths as point lists; curves sampled at eight points (separators are
    straight)."""
    tokens = re.findall(r"[MmLlHhVvCcSsQqTtAaZz]|" + NUMBER, d)
    i, cmd, cur, start, subs, pts = 0, None, (0.0, 0.0), (0.0, 0.0), [], []

    def num():
        nonlocal i
        i += 1
        return float(tokens[i - 1])

    while i < len(tokens):
        if re.match(r"[A-Za-z]", tokens[i]):
            cmd = tokens[i]
            i += 1
            if cmd in "Zz":
                if pts:
                    subs.append(pts)
                pts, cur = [], start
                continue
        rel, c = cmd.islower(), cmd.upper()
        ox, oy = cur if rel else (0.0, 0.0)
        if c == "M":
            if pts:
                subs.append(pts)
            cur = (ox + num(), oy + num())
            start, pts = cur, [cur]
            cmd = "l" if rel else "L"  # coordinates after a moveto are linetos
        elif c == "L":
            cur = (ox + num(), oy + num())
            pts.append(cur)
        elif c == "H":
            cur = ((cur[0] if rel else 0.0) + num(), cur[1])
            pts.append(cur)
        elif c == "V":
            cur = (cur[0], (cur[1] if rel else 0.0) + num())
            pts.append(cur)
        elif c in "CSQT":
            ctrl = [(ox + num(), oy + num()) for _ in range({"C": 3, "S": 2, "Q": 2, "T": 1}[c])]
            p = [cur] + ctrl
            for k in range(1, 9):
                t, q = k / 8.0, p[:]
                while len(q) > 1:
                    q = [((1 - t) * q[j][0] + t * q[j + 1][0], (1 - t) * q[j][1] + t * q[j + 1][1])
                         for j in range(len(q) - 1)]
                pts.append(q[0])
            cur = ctrl[-1]
        elif c == "A":
            for _ in range(5):
                num()
            cur = (ox + num(), oy + num())
            pts.append(cur)
        else:
            raise ValueError(f"unknown path command {cmd}")
    if pts:
        subs.append(pts)
    return subs


def style(el):
    st = {k: el.get(k) for k in ("fill", "stroke", "stroke-width", "display") if el.get(k)}
    for kv in (el.get("style") or "").split(";"):
        if ":" in kv:
            k, v = kv.split(":", 1)
            st[k.strip()] = v.strip()
    return st


def separators(root):
    """(polygons, stroke width, transform) of every drawn shape; the <image> is the map."""
    out = []

    def walk(el, m):
        tag = el.tag.replace(SVG, "")
        if tag in ("defs", "metadata") or tag.endswith("namedview"):
            return
        m = compose(m, parse_transform(el.get("transform")))
        if tag in ("svg", "g"):
            for child in el:
                walk(child, m)
            return
        st = style(el)
        if st.get("display") == "none":
            return
        if tag == "rect":
            x, y, w, h = (float(el.get(k, 0)) for k in ("x", "y", "width", "height"))
            polys = [[(x, y), (x + w, y), (x + w, y + h), (x, y + h)]]
        elif tag == "path":
            polys = path_polygons(el.get("d", ""))
        elif tag in ("polygon", "polyline"):
            v = [float(t) for t in re.findall(NUMBER, el.get("points", ""))]
            polys = [list(zip(v[0::2], v[1::2]))]
        elif tag == "line":
            polys = [[(float(el.get("x1", 0)), float(el.get("y1", 0))),
                      (float(el.get("x2", 0)), float(el.get("y2", 0)))]]
        else:
            return  # the <image>, text, anything else draws no separator
        width = float(re.match(NUMBER, st.get("stroke-width", "1")).group(0))
        if st.get("stroke", "none") == "none":
            width = 0.0
        out.append((polys, width, m))

    walk(root, IDENTITY)
    return out


def colour(i):
    """Room i's colour: distinct for i < 6**3, every channel above the scorer's black (<= 20)."""
    return (40 + 40 * (i % 6), 40 + 40 * (i // 6 % 6), 40 + 40 * (i // 36 % 6))


def drawn_plan_grid(grey):
    """A drawing (a white or light grey floor, walls as grey lines or outlined with a grey fill, the
    outside a mid grey) as a map: the floor's grey (the most common level of 200 and above) less
    DRAWN_FLOOR_TOLERANCE, or brighter, is free (254); a cell that is not and lies within
    DRAWN_WALL_M of a free cell is wall (0); the rest is unknown (205)."""
    bright = grey[grey >= 200]
    if bright.size == 0:
        raise ValueError("the embedded image has no cell of grey 200 or above: no floor to read")
    floor = int(np.bincount(bright).argmax())
    free = grey.astype(int) >= floor - DRAWN_FLOOR_TOLERANCE  # white highlights are floor too
    near_free = near(free, int(round(DRAWN_WALL_M / RES)))
    out = np.full(grey.shape, 205, np.uint8)
    out[near_free] = 0
    out[free] = 254
    return out


def convert(svg_path):
    root = ET.fromstring(open(svg_path, encoding="utf-8").read().encode("utf-8"))
    images = root.findall(f".//{SVG}image")
    if len(images) != 1:
        raise ValueError(f"{svg_path}: {len(images)} embedded images, expected one")
    el = images[0]
    href = el.get(XLINK_HREF) or el.get("href") or ""
    if not href.startswith("data:image/png;base64,"):
        raise ValueError(f"{svg_path}: the map is not an embedded PNG")
    png = Image.open(io.BytesIO(base64.b64decode(re.sub(r"\s", "", href.split(",", 1)[1]))))
    grey = np.asarray(png.convert("L"))
    h, w = grey.shape
    # The image's placement: its x/y/width/height inside its own and its ancestors' transforms.
    parent = {child: p for p in root.iter() for child in p}
    m_img, e = parse_transform(el.get("transform")), el
    while e in parent:
        e = parent[e]
        m_img = compose(parse_transform(e.get("transform")), m_img)
    a, b, c, d, tx, ty = m_img
    det = a * d - b * c
    inverse = (d / det, -b / det, -c / det, a / det,
               (c * ty - d * tx) / det, (b * tx - a * ty) / det)
    ix, iy = float(el.get("x", 0)), float(el.get("y", 0))
    sx, sy = w / float(el.get("width", w)), h / float(el.get("height", h))

    def to_cell(x, y):
        u, v = apply(inverse, x, y)
        return (u - ix) * sx - 0.5, (v - iy) * sy - 0.5  # cell centres at integer coordinates

    cut = Image.new("L", (w, h), 0)
    draw = ImageDraw.Draw(cut)
    count = 0
    for polys, stroke, m in separators(root):
        # A stroke is as wide in cells as the shape's transform and the image's scale make it; a
        # separator is at least one cell wide, so that it closes the doorway it was drawn across.
        scale = math.sqrt(abs(m[0] * m[3] - m[1] * m[2]) * sx * sy / abs(det))
        width = max(1, round(stroke * scale))
        for poly in polys:
            p = [to_cell(*apply(m, x, y)) for x, y in poly]
            if len(p) >= 3:
                draw.polygon(p, fill=255)
                p = p + [p[0]]
            draw.line(p, fill=255, width=width)
        count += 1
    drawn = np.isin(grey, MAP_LEVELS).mean() < MAP_MIN_LEVEL_SHARE
    if drawn:
        grey = drawn_plan_grid(grey)
    free = (grey >= FREE_MIN) & (np.asarray(cut) == 0)
    labels, n = components(free)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)  # sizes[0]: cells in no component
    rooms = sorted((i for i in range(1, n + 1) if sizes[i] >= MIN_ROOM_CELLS),
                   key=lambda i: -sizes[i])
    if len(rooms) > 6 ** 3:
        raise ValueError(f"{svg_path}: {len(rooms)} rooms, more than the 216 colours")
    gt = np.zeros((h, w, 3), np.uint8)
    for k, i in enumerate(rooms):
        gt[labels == i] = colour(k)
    return grey, gt, count, [int(sizes[i]) for i in rooms], drawn


def main(argv):
    if len(argv) != 3:
        sys.exit(__doc__)
    src, out = argv[1], argv[2]
    os.makedirs(out, exist_ok=True)
    names = sorted(f for f in os.listdir(src) if f.endswith("_gt_segmentation.svg"))
    if not names:
        sys.exit(f"{src}: no *_gt_segmentation.svg")
    for f in names:
        name = "ipa_" + f[: -len("_gt_segmentation.svg")]
        grey, gt, count, rooms, drawn = convert(os.path.join(src, f))
        Image.fromarray(grey).save(os.path.join(out, name + "_map.png"))
        Image.fromarray(gt, "RGB").save(os.path.join(out, name + "_gt.png"))
        print(f"{name}: {grey.shape[1]}x{grey.shape[0]} cells, {count} separators, "
              f"{len(rooms)} rooms of >= {MIN_ROOM_CELLS} cells" + (", a drawing" if drawn else ""))


if __name__ == "__main__":
    main(sys.argv)
