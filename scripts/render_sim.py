#!/usr/bin/python3
"""Simulator buildings mapped by the simulator's robot (issue 28): robot-made occupancy grids
whose rooms are exact ground truth, in the layout of ../shared/data/floorplans
(<name>_map.png, <name>_gt.png), for training and scoring `zonemap zones segment`.

For each SEED: `zonemap sim hospital --seed SEED --area A` (A from the seed, 400-1600 m2: a
clinic to a hospital wing; one patrol task, small payloads: only the building and the mapping
route matter), then the building's grid as the robot's laser maps it along its own mapping route
(every pose of mapping_gt.tum at least 0.5 m from the last one is a viewpoint) with
render_r2v.py's robot_scan: viewpoints dropped and moved, range 4-8 m, wall-face noise,
specks; plus clutter in the rooms (a piece per 6 m2, as render_r2v.py's robot/). The simulator's
output is not changed: this reads its files.

Ground truth: the simulator's zones (zones.geojson) filled into the grid, over the building's
free cells; its corridor segments (the spine cut once per branch, branches cut every 15 m,
docs/sim.md) are one room where they touch, as a building's corridor is one space.

With --laser (issue 28, sixth round) the grid is render_r2v.py's laser/ instead: the same
building, clutter and route, a laser of 360, 720 or 1440 rays, and real_grid's band of unknown
cells at the returns and dotted faces, drawn from a second generator seeded by (SEED, 1).
With --fronts (issue 28, ninth round) it is the --laser grid of a building in which a share of
the rooms open onto their front neighbour (render_r2v.py's open_fronts: mostly the corridor),
the fronts and the laser drawn from a generator seeded by (SEED, 2).

Usage: scripts/render_sim.py ZONEMAP OUT_DIR SEED [SEED ...] [--laser | --fronts]
"""
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from render_r2v import (LASER_RAYS, RES, components, open_fronts, real_grid,  # noqa: E402
                        robot_scan, write)


def read_pgm(path):
    return np.array(Image.open(path))


def render(zonemap, seed, tmp, laser=False, fronts=False):
    rng = np.random.default_rng(seed)
    area = 400 + (seed * 7919) % 1201
    out = os.path.join(tmp, f"sim{seed}")
    # Only the robot's occupancy grid and the building's rooms are used: the oracle's features
    # (named, issue 26) spare rendering and ORB on images nobody reads.
    subprocess.run([zonemap, "sim", "hospital", "--seed", str(seed), "--area", str(area),
                    "--tasks", "1", "--dense", "32x24", "--max-features", "60", "--features", "oracle",
                    "--out", out],
                   check=True, capture_output=True)
    grid = read_pgm(os.path.join(out, "map.pgm"))
    meta = {}
    with open(os.path.join(out, "map.yaml")) as f:
        for line in f:
            k, _, v = line.partition(":")
            meta[k.strip()] = v.strip()
    res = float(meta["resolution"])
    assert abs(res - RES) < 1e-9, f"sim resolution {res}, expected {RES}"
    ox, oy = (float(v) for v in meta["origin"].strip("[]").split(",")[:2])
    h, w = grid.shape
    free, occupied = grid >= 250, grid == 0

    def px(x, y):
        return ((x - ox) / res, h - (y - oy) / res)

    img = Image.new("I", (w, h), 0)
    d = ImageDraw.Draw(img)
    zones = json.load(open(os.path.join(out, "zones.geojson")))["features"]
    corridor = np.zeros((h, w), bool)
    for k, z in enumerate(zones, start=1):
        ring = [px(x, y) for x, y in z["geometry"]["coordinates"][0]]
        d.polygon(ring, fill=k)
    labels = np.array(img)
    for k, z in enumerate(zones, start=1):
        if z["properties"]["kind"] == "corridor":
            corridor |= labels == k
    joined, nc = components(corridor & free)
    rooms = np.where(corridor, 0, labels)
    rooms[joined > 0] = len(zones) + joined[joined > 0]
    rooms[~free] = 0
    _, rooms = np.unique(rooms, return_inverse=True)
    rooms = rooms.reshape(h, w)
    n = int(rooms.max())
    # laser/'s generator (the fronts' too): its own stream, so the robot's route is --laser's.
    lrng = np.random.default_rng([seed, 2 if fronts else 1])
    if fronts:
        free, occupied, _ = open_fronts(free, occupied, rooms, n, lrng)
    # Clutter, as render_r2v.py's robot/ draws it (chairs, tables, carts).
    clutter = np.zeros_like(free)
    for room in range(1, n + 1):
        cells = np.argwhere(rooms == room)
        for _ in range(rng.poisson(len(cells) * RES * RES / 6.0)):
            r, c = cells[rng.integers(len(cells))]
            bh, bw = (int(rng.uniform(0.3, 1.2) / RES) for _ in range(2))
            clutter[r:min(h, r + bh), c:min(w, c + bw)] = True
    clutter &= free
    world_free, world_occ = free & ~clutter, occupied | clutter
    views, last = [], None
    with open(os.path.join(out, "mapping_gt.tum")) as f:
        for line in f:
            if line.startswith("#"):
                continue
            x, y = (float(v) for v in line.split()[1:3])
            if last is None or np.hypot(x - last[0], y - last[1]) >= 0.5:
                views.append(px(x, y))
                last = (x, y)
    if laser or fronts:
        seen = robot_scan(world_free, world_occ, views, rng, rays=int(lrng.choice(LASER_RAYS)))
        seen_free, seen_occ = real_grid(*seen, lrng)
    else:
        seen_free, seen_occ = robot_scan(world_free, world_occ, views, rng)
    return seen_free, seen_occ, rooms, n, area, len(views)


def main():
    args = sys.argv[1:]
    laser = "--laser" in args
    if laser:
        args.remove("--laser")
    fronts = "--fronts" in args
    if fronts:
        args.remove("--fronts")
    if laser and fronts:
        sys.exit("--laser and --fronts: one at a time")
    if len(args) < 3:
        sys.exit(__doc__)
    zonemap, out = args[0], args[1]
    with tempfile.TemporaryDirectory() as tmp:
        for seed in (int(s) for s in args[2:]):
            seen_free, seen_occ, rooms, n, area, nv = render(zonemap, seed, tmp, laser, fronts)
            name = f"sim_hospital_{seed}"
            write(out, name, seen_free, seen_occ, rooms, n)
            print(f"{name}: {area} m2, {seen_free.shape[1]}x{seen_free.shape[0]} cells, "
                  f"{n} rooms, {nv} viewpoints")


if __name__ == "__main__":
    main()
