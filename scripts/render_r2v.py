#!/usr/bin/python3
"""Renders R2V vector floor plans (tests/data/segmentation/r2v, see its README) into occupancy
grids and room ground truths at 0.05 m/px, in the layout of ../shared/data/floorplans
(<name>_map.png, <name>_gt.png), for held-out scoring of `zonemap zones segment`.

Two variants per plan:
  plan/  the architectural plan as a map: walls occupied, doors open, furniture icons
         (bathtub, counters, toilet, basins, ...) as obstacle outlines with unknown inside,
         outside the building unknown;
  scan/  what a robot's laser would have mapped of it: 360-degree scans (range 8 m) from the
         middle of every room label and every door, so rooms have shadows (unknown cells)
         behind furniture and around corners, and walls are only where a ray hit them.
  robot/ the scan with more of what a robot's SLAM grid holds (issue 28), drawn from a random
         generator seeded by the plan's name (so a render is reproducible): clutter in the
         rooms (tables, cabinets; chairs as four legs), glass and missing wall pieces (the laser
         passes an interior one, an exterior one returns nothing), door leaves open at random
         angles, rooms left unexplored (a quarter of the viewpoints dropped, the others moved up
         to 0.3 m), a range of 4-8 m, wall faces a cell in front or behind where a ray hits, and
         specks of people in the free space. plan/ and scan/ are unchanged by it.
  laser/ (only with --laser; issue 28, sixth round) robot/'s world and scan with what the shared
         robot maps show and robot/ does not: a band of unknown cells 1-3 cells wide between a
         share (0-100 %) of the returns and the free space (a real SLAM grid's cells next to a
         wall or an obstacle are neither free nor occupied enough to pass the thresholds, so
         free space meets unknown, not occupied), a share (0-15 %) of the returns themselves
         left unknown (dotted faces), and a coarser laser (0.25, 0.5 or 1 degree between rays:
         streaks of free cells with unknown between them at range). Its own generator, seeded
         by the plan's name and "laser"; robot/ is unchanged by it.
  front/ (only with --fronts; issue 28, ninth round) laser/'s look of a world in which a share of
         the rooms open onto a neighbour along their whole front: for each room, with
         probability 0.3, the wall it shares with its front neighbour (of its neighbours larger
         than itself, the one with the longest shared wall: a corridor, a hall, a living room)
         is removed, doors and all, as in an office whose front towards the corridor is open or
         glass. The ground truth keeps the two rooms (their border is the wall's line), so these
         are borders with no wall along them that separate two rooms, which robot/ and laser/
         hardly hold (the seventh round's reading of ubremen's and g4s_y2's offices). Its own
         generator, seeded by the plan's name and "front"; the other variants are unchanged.

Ground truth: every region enclosed by walls with doors closed is one room (R2V's room labels
only mark a point in a room; enclosed regions of any label are rooms).
Scale: R2V coordinates are pixels of the source raster; a plan's scale is set so that the lower
quartile of its door openings is 0.75 m (a single interior door; the wider openings are
balcony sliders and double doors), the only physical assumption made. It was fixed before any
segmentation was scored on these plans.

Usage: scripts/render_r2v.py [SRC_DIR] OUT_DIR [--robot-off KIND[,KIND...] | --laser | --fronts]
--robot-off renders robot/ only, with the named augmentations left out (glass, leaves, clutter,
unexplored, range, noise, specks; issue 28's ablation). Every random number is still drawn, so
the other augmentations are exactly those of the full render. --laser renders laser/ only,
--fronts front/ only. (robot_world, robot_scan, real_grid and open_fronts are also
scripts/render_sim.py's.)
"""
import argparse
import collections
import os
import zlib

import numpy as np
from PIL import Image, ImageDraw

RES = 0.05  # m per cell
DOOR_M = 0.75  # lower-quartile door opening: a single interior door
WALL_M = 0.15  # wall thickness drawn
MARGIN_M = 1.0
FURNITURE = {"bathtub", "cooking_counter", "toilet", "washing_basin", "refrigerator", "sofa",
             "bed", "TV", "special"}
RANGE_M = 8.0


def parse(path):
    items = []
    with open(path) as f:
        for line in f:
            parts = line.split("\t")
            if len(parts) < 5:
                continue
            x1, y1, x2, y2 = (float(v) for v in parts[:4])
            items.append((x1, y1, x2, y2, parts[4]))
    return items


def components(mask):
    """4-connected components of a boolean mask: (labels, count)."""
    labels = np.zeros(mask.shape, np.int32)
    n = 0
    h, w = mask.shape
    for r0, c0 in zip(*np.nonzero(mask)):
        if labels[r0, c0]:
            continue
        n += 1
        labels[r0, c0] = n
        q = collections.deque([(r0, c0)])
        while q:
            r, c = q.popleft()
            for rr, cc in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
                if 0 <= rr < h and 0 <= cc < w and mask[rr, cc] and not labels[rr, cc]:
                    labels[rr, cc] = n
                    q.append((rr, cc))
    return labels, n


def render(items):
    doors = [i for i in items if i[4] == "door"]
    lengths = sorted(np.hypot(d[2] - d[0], d[3] - d[1]) for d in doors)
    # Openings include wide balcony sliders and double doors; the narrowest quarter are single
    # interior doors.
    scale = DOOR_M / lengths[len(lengths) // 4]  # metres per source pixel
    xs = [v for i in items for v in (i[0], i[2])]
    ys = [v for i in items for v in (i[1], i[3])]
    x0, y0 = min(xs), min(ys)
    w = int((max(xs) - x0) * scale / RES + 2 * MARGIN_M / RES) + 1
    h = int((max(ys) - y0) * scale / RES + 2 * MARGIN_M / RES) + 1

    def px(x, y):
        return ((x - x0) * scale / RES + MARGIN_M / RES, (y - y0) * scale / RES + MARGIN_M / RES)

    wall_w = max(2, round(WALL_M / RES))

    def layer(kinds, width):
        img = Image.new("L", (w, h), 0)
        d = ImageDraw.Draw(img)
        for x1, y1, x2, y2, kind in items:
            if kind in kinds:
                d.line([px(x1, y1), px(x2, y2)], fill=255, width=width)
        return np.array(img) > 0

    walls = layer({"wall"}, wall_w)
    door_cut = layer({"door"}, wall_w + 2)
    outside, _ = components(~walls)
    outside = outside == outside[0, 0]
    rooms, n = components(~walls & ~outside)
    inside = ~walls & ~outside
    open_walls = walls & ~door_cut
    free = (inside | (walls & door_cut)) & ~outside
    occupied = open_walls.copy()
    unknown = outside.copy()
    img = Image.new("L", (w, h), 0)
    d = ImageDraw.Draw(img)
    for x1, y1, x2, y2, kind in items:
        if kind in FURNITURE:
            a, b = px(min(x1, x2), min(y1, y2)), px(max(x1, x2), max(y1, y2))
            d.rectangle([a, b], fill=128, outline=255)
    furn = np.array(img)
    occupied |= (furn == 255) & inside
    unknown |= (furn == 128) & inside
    free &= ~occupied & ~unknown
    viewpoints = []
    for x1, y1, x2, y2, kind in items:
        # Room labels and doors; not walls, furniture, entrances, stairs, nor "point" rows (a few
        # R2V files mark wall junctions with them: a viewpoint there would stand in a wall).
        if kind == "door" or kind not in FURNITURE | {"wall", "entrance", "stairs", "point"}:
            viewpoints.append(px((x1 + x2) / 2, (y1 + y2) / 2))
    return free, occupied, rooms, n, viewpoints


def line_mask(shape, segments, width):
    img = Image.new("L", (shape[1], shape[0]), 0)
    d = ImageDraw.Draw(img)
    for a, b in segments:
        d.line([a, b], fill=255, width=width)
    return np.array(img) > 0


AUGMENTATIONS = ("glass", "leaves", "clutter", "unexplored", "range", "noise", "specks")


def robot_world(items, free, occupied, rooms, n, rng, off=()):
    """The plan as a robot's laser meets it (robot/): (free, occupied) with glass and missing
    wall pieces, door leaves at random angles and clutter. The ground truth is not changed."""
    free, occupied = free.copy(), occupied.copy()
    doors = [i for i in items if i[4] == "door"]
    lengths = sorted(np.hypot(d[2] - d[0], d[3] - d[1]) for d in doors)
    scale = DOOR_M / lengths[len(lengths) // 4]
    xs = [v for i in items for v in (i[0], i[2])]
    ys = [v for i in items for v in (i[1], i[3])]
    x0, y0 = min(xs), min(ys)

    def px(x, y):
        return ((x - x0) * scale / RES + MARGIN_M / RES, (y - y0) * scale / RES + MARGIN_M / RES)

    wall_w = max(2, round(WALL_M / RES))
    building = free | occupied | (rooms > 0)
    # Glass and missing wall pieces: a fifth of the walls lose a 0.4-2 m piece.
    pieces = []
    for x1, y1, x2, y2, kind in items:
        if kind != "wall" or rng.random() > 0.2:
            continue
        a, b = np.array(px(x1, y1)), np.array(px(x2, y2))
        length = np.hypot(*(b - a))
        if length * RES < 0.5:
            continue
        cut = min(length, rng.uniform(0.4, 2.0) / RES)
        t0 = rng.uniform(0, length - cut) / length
        pieces.append((tuple(a + t0 * (b - a)), tuple(a + (t0 + cut / length) * (b - a))))
    glass = line_mask(free.shape, pieces, wall_w + 2) & occupied
    outside = ~building
    near_outside = np.zeros_like(outside)
    for dr in range(-3, 4):
        for dc in range(-3, 4):
            near_outside |= np.roll(np.roll(outside, dr, 0), dc, 1)
    if "glass" in off:
        glass &= False
    occupied &= ~glass
    free |= glass & ~near_outside  # the laser passes an interior pane; an exterior one: nothing
    # Door leaves: most doors stand open at 10-100 degrees from their frame.
    leaves = []
    for x1, y1, x2, y2, _ in doors:
        if rng.random() > 0.8:
            continue
        a, b = np.array(px(x1, y1)), np.array(px(x2, y2))
        if rng.random() < 0.5:
            a, b = b, a
        v = b - a
        v = v * min(1.0, 0.9 / RES / max(1e-9, np.hypot(*v)))  # one leaf, at most 0.9 m
        ang = np.radians(rng.uniform(10, 100)) * rng.choice([-1, 1])
        rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        leaves.append((tuple(a), tuple(a + rot @ v)))
    leaf = line_mask(free.shape, leaves, 1) & free
    clutter = room_clutter(free, rooms, n, rng)
    if "leaves" in off:
        leaf &= False
    if "clutter" in off:
        clutter &= False
    occupied |= leaf | clutter
    free &= ~(leaf | clutter)
    return free, occupied


def room_clutter(free, rooms, n, rng):
    """Clutter in the rooms (robot/'s, and render_raster.py's): about one piece per 6 m2 of room,
    0.3-1.2 m a side; a third are chairs (four legs). rooms labels the ground truth 1..n.
    Returns the clutter's cells (free ones only)."""
    clutter = np.zeros_like(free)
    h, w = free.shape
    for room in range(1, n + 1):
        cells = np.argwhere(rooms == room)
        if len(cells) == 0:
            continue
        for _ in range(rng.poisson(len(cells) * RES * RES / 6.0)):
            r, c = cells[rng.integers(len(cells))]
            bh, bw = (int(rng.uniform(0.3, 1.2) / RES) for _ in range(2))
            r1, c1 = min(h, r + bh), min(w, c + bw)
            if rng.random() < 0.33:
                for rr in (r, r1 - 1):
                    for cc in (c, c1 - 1):
                        clutter[rr:rr + 1, cc:cc + 1] = True
            else:
                clutter[r:r1, c:c1] = True
    return clutter & free & (rooms > 0)


def laser_rays(free, viewpoints, range_m, rays=1440):
    """For each viewpoint, the `rays` rays (1440 unless said) of a 360-degree laser sampled every half cell out to
    range_m: (r, c, first), the cells along each ray (clipped to the grid) and each ray's first
    sample that is not free or leaves the grid (the sample count where none). A viewpoint that
    is not free itself (inside furniture) sees nothing and yields nothing."""
    h, w = free.shape
    angles = np.linspace(0, 2 * np.pi, rays, endpoint=False)
    steps = np.arange(0, range_m / RES, 0.5)
    for vx, vy in viewpoints:
        c = (vx + np.outer(np.cos(angles), steps)).astype(int)
        r = (vy + np.outer(np.sin(angles), steps)).astype(int)
        valid = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        r, c = np.clip(r, 0, h - 1), np.clip(c, 0, w - 1)
        if not free[r[0, 0], c[0, 0]]:
            continue
        blocked = (~free[r, c]) | ~valid
        yield r, c, np.where(blocked.any(axis=1), blocked.argmax(axis=1), steps.size)


def robot_scan(free, occupied, viewpoints, rng, off=(), rays=1440):
    """A robot's laser map (robot/): a quarter of the viewpoints dropped (rooms left
    unexplored), the rest moved up to 0.3 m, range 4-8 m, each wall hit a cell in front of or
    behind its face, specks of people in the free space."""
    h, w = free.shape
    keep = [v for v in viewpoints if rng.random() >= 0.25 or "unexplored" in off] or \
        viewpoints[:1]
    moved = []
    for vx, vy in keep:
        dx, dy = rng.uniform(-0.3, 0.3, 2) / RES
        mx, my = vx + dx, vy + dy
        if 0 <= int(my) < h and 0 <= int(mx) < w and free[int(my), int(mx)]:
            moved.append((mx, my))
        else:
            moved.append((vx, vy))
    range_m = rng.uniform(4.0, 8.0)
    if "range" in off:
        range_m = RANGE_M
    seen_free = np.zeros_like(free)
    seen_occ = np.zeros_like(free)
    for r, c, first in laser_rays(free, moved, range_m, rays):
        samples = r.shape[1]
        hit = np.nonzero(first < samples)[0]
        keep_hit = occupied[r[hit, first[hit]], c[hit, first[hit]]]
        hit = hit[keep_hit]
        # Wall-face noise: the return a cell (two half-cell steps) short, on, or past the face.
        jitter = rng.choice([-2, 0, 2], size=hit.size, p=[0.25, 0.5, 0.25])
        if "noise" in off:
            jitter[:] = 0
        end = first.copy()
        end[hit] = np.maximum(1, first[hit] + jitter)
        before = np.arange(samples)[None, :] < np.minimum(end, first)[:, None]
        seen_free[r[before], c[before]] = True
        j = np.minimum(end[hit], samples - 1)
        seen_occ[r[hit, j], c[hit, j]] = True
    seen_free &= ~seen_occ
    specks = seen_free & (rng.random(free.shape) < 0.001)
    if "specks" in off:
        specks &= False
    return seen_free & ~specks, seen_occ | specks


LASER_RAYS = (360, 720, 1440)  # laser/: 1, 0.5 or 0.25 degrees between rays


def near(mask, cells):
    """Cells within `cells` (Chebyshev distance) of a True cell of mask, without wrapping."""
    out = mask.copy()
    h, w = mask.shape
    for dr in range(-cells, cells + 1):
        for dc in range(-cells, cells + 1):
            src = mask[max(0, -dr):h - max(0, dr), max(0, -dc):w - max(0, dc)]
            out[max(0, dr):h - max(0, -dr), max(0, dc):w - max(0, -dc)] |= src
    return out


def real_grid(seen_free, seen_occ, rng):
    """laser/'s look of a real SLAM grid on a robot_scan result: free cells within 1-3 cells of
    a return become unknown (the band) for a share (0-100 %) of the returns, then 0-15 % of the
    returns become unknown (dotted faces); the amounts drawn once per map. Returns (free,
    occupied)."""
    band = int(rng.integers(1, 4))
    banded = rng.uniform(0.0, 1.0)
    dotted = rng.uniform(0.0, 0.15)
    halo = near(seen_occ & (rng.random(seen_occ.shape) < banded), band)
    free = seen_free & ~halo
    occupied = seen_occ & (rng.random(seen_occ.shape) >= dotted)
    return free, occupied


FRONT_SHARE = 0.3  # front/: the share of rooms whose front is opened
FRONT_REACH = 4  # cells: a wall cell within this of both rooms lies between them (walls 3-4 wide)


def open_fronts(free, occupied, rooms, n, rng, share=FRONT_SHARE, reach=FRONT_REACH):
    """front/'s world: for each room, with probability `share`, the wall between it and its front
    neighbour (of the rooms larger than it that it shares a wall with, the one with the longest
    shared wall) becomes free, door cells and all. rooms labels the ground truth (0: no room);
    it is not changed. Returns (free, occupied, opened), opened the number of fronts opened."""
    free, occupied = free.copy(), occupied.copy()
    area = np.bincount(rooms.ravel(), minlength=n + 1)
    walls = occupied & (rooms == 0)  # walls (door openings are free already); not furniture
    # Where a wall between two rooms meets an outer wall, the outer wall's cells are near both
    # rooms too: the cells next to the outside (unknown, or the grid's edge) stay, so the
    # building stays closed.
    outside = np.pad(~free & ~occupied, 1, constant_values=True)
    walls &= ~near(outside, 1)[1:-1, 1:-1]
    near_room = [None] + [near(rooms == k, reach) if area[k] else None for k in range(1, n + 1)]
    opened = 0
    for k in range(1, n + 1):
        # One draw per room, taken whether or not it has a larger neighbour, so one room's
        # neighbours do not shift the others' draws.
        if rng.random() >= share or near_room[k] is None:
            continue
        cut = None  # the longest wall shared with a larger room, if any
        for j in range(1, n + 1):
            if j == k or near_room[j] is None or area[j] <= area[k]:
                continue
            shared = walls & near_room[k] & near_room[j]
            if shared.sum() > (0 if cut is None else cut.sum()):
                cut = shared
        if cut is None:
            continue
        occupied &= ~cut
        free |= cut
        opened += 1
    return free, occupied, opened


def scan(free, occupied, viewpoints):
    """Cells a 360-degree laser sees from each viewpoint: (seen_free, seen_occupied)."""
    seen_free = np.zeros_like(free)
    seen_occ = np.zeros_like(free)
    for r, c, first in laser_rays(free, viewpoints, RANGE_M):
        samples = r.shape[1]
        before = np.arange(samples)[None, :] < first[:, None]
        seen_free[r[before], c[before]] = True
        hit = np.nonzero(first < samples)[0]
        hr, hc = r[hit, first[hit]], c[hit, first[hit]]
        keep = occupied[hr, hc]
        seen_occ[hr[keep], hc[keep]] = True
    return seen_free & free, seen_occ


def write(out_dir, name, free, occupied, rooms, n):
    os.makedirs(out_dir, exist_ok=True)
    grid = np.full(free.shape, 128, np.uint8)
    grid[free] = 255
    grid[occupied] = 0
    Image.fromarray(grid).save(os.path.join(out_dir, name + "_map.png"))
    rng = np.random.default_rng(7)
    colours = rng.integers(60, 255, size=(n + 1, 3), dtype=np.uint8)
    colours[0] = 0
    Image.fromarray(colours[rooms]).save(os.path.join(out_dir, name + "_gt.png"))


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(
        usage="%(prog)s [SRC_DIR] OUT_DIR [--robot-off KIND[,KIND...] | --laser | --fronts]",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    # argparse matches the two positionals together: one argument is OUT_DIR, a third is refused.
    ap.add_argument("src", nargs="?", metavar="SRC_DIR",
                    default=os.path.join(here, "..", "tests", "data", "segmentation", "r2v"))
    ap.add_argument("out", metavar="OUT_DIR")
    kind = ap.add_mutually_exclusive_group()
    kind.add_argument("--robot-off", metavar="KIND[,KIND...]")
    kind.add_argument("--laser", action="store_true")
    kind.add_argument("--fronts", action="store_true")
    a = ap.parse_args()
    laser, fronts = a.laser, a.fronts
    off = None
    if a.robot_off is not None:
        off = tuple(k for k in a.robot_off.split(",") if k)
        bad = [k for k in off if k not in AUGMENTATIONS]
        if bad:
            ap.error(f"--robot-off: unknown {bad}; known: {', '.join(AUGMENTATIONS)}")
    src, out = a.src, a.out
    for fname in sorted(os.listdir(src)):
        if not fname.endswith(".txt"):
            continue
        name = "r2v_" + fname[:-4]
        items = parse(os.path.join(src, fname))
        free, occupied, rooms, n, views = render(items)
        if laser or fronts:
            kind = "front" if fronts else "laser"
            rng = np.random.default_rng(zlib.crc32((name + "/" + kind).encode()))
            opened = 0
            if fronts:
                free, occupied, opened = open_fronts(free, occupied, rooms, n, rng)
            world_free, world_occ = robot_world(items, free, occupied, rooms, n, rng)
            rays = int(rng.choice(LASER_RAYS))
            seen = robot_scan(world_free, world_occ, views, rng, rays=rays)
            write(os.path.join(out, kind), name, *real_grid(*seen, rng), rooms, n)
            print(f"{name}: {kind}/, {rays} rays" + (f", {opened} fronts open" if fronts else ""))
            continue
        if off is None:
            write(os.path.join(out, "plan"), name, free, occupied, rooms, n)
            seen_free, seen_occ = scan(free, occupied, views)
            write(os.path.join(out, "scan"), name, seen_free, seen_occ, rooms, n)
        rng = np.random.default_rng(zlib.crc32(name.encode()))
        world_free, world_occ = robot_world(items, free, occupied, rooms, n, rng,
                                            off or ())
        robot_free, robot_occ = robot_scan(world_free, world_occ, views, rng, off or ())
        write(os.path.join(out, "robot"), name, robot_free, robot_occ, rooms, n)
        print(f"{name}: {free.shape[1]}x{free.shape[0]} cells, {n} enclosed regions, "
              f"{len(views)} scan viewpoints")


if __name__ == "__main__":
    main()
