#!/usr/bin/python3
"""Raster floor maps with room ground truth, mapped again as a robot's laser would (issue 28).

  render_raster.py MAP_DIR OUT_DIR [--seeds K] [--laser]

MAP_DIR holds pairs NAME_map.png / NAME_gt.png in the layout of ../shared/data/floorplans (grey
map, >= 250 free, 0 occupied, anything else unknown; ground truth one flat colour per room,
black elsewhere), as scripts/ipa_to_grid.py writes them. R2V plans are vectors and the
simulator's buildings come with their robot's route; these are rasters without either, so this
script gives such a map what render_sim.py gives a simulated building, with the same functions:

  - the world: the map's free and occupied cells, with render_r2v.py's clutter in every ground
    truth room (room_clutter: a piece per 6 m2, 0.3-1.2 m a side, a third chairs);
  - the route: a robot that drove everywhere, i.e. a viewpoint on every free cell of a 1 m
    lattice (its offset drawn per render) at least 0.4 m from anything not free, visited in
    no particular order (only the set matters to a scan);
  - robot/: render_r2v.py's robot_scan of that world from those viewpoints (a quarter dropped,
    the rest moved up to 0.3 m, range 4-8 m, wall-face noise, specks);
  - laser/ (--laser): the same world and route with a laser of 360, 720 or 1440 rays and
    real_grid's band of unknown cells and dotted faces, from a second generator.

No glass and no door leaves: a raster map has no wall segments or door leaves to draw them from
(render_sim.py's grids have neither). Each map is rendered K times (--seeds, default 1), render
k of NAME written as NAME_sK (k = 1..K), each from generators seeded by (crc32(NAME), k) and
(crc32(NAME), k, 1), so a render is reproducible and one map's renders differ. The ground truth
is the map's rooms restricted to its free cells, relabelled 1..n (a colour on fewer than 200
cells, the scorer's smallest room, is none), unchanged by the render.

Only numpy, PIL, render_r2v.py's functions and ipa_to_grid.py's two thresholds.
"""
import argparse
import os
import sys
import zlib

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ipa_to_grid import FREE_MIN, MIN_ROOM_CELLS  # noqa: E402  (zonemap's thresholds, once)
from render_r2v import (LASER_RAYS, RES, near, real_grid, robot_scan,  # noqa: E402
                        room_clutter, write)

LATTICE_M = 1.0       # the route's viewpoint spacing
CLEARANCE_M = 0.4     # a viewpoint's least distance to anything not free


def read_pair(map_dir, name):
    """(free, occupied, rooms, n) of NAME_map.png / NAME_gt.png; rooms 1..n on free cells."""
    grid = np.array(Image.open(os.path.join(map_dir, name + "_map.png")).convert("L"))
    gt = np.array(Image.open(os.path.join(map_dir, name + "_gt.png")).convert("RGB"))
    if gt.shape[:2] != grid.shape:
        raise SystemExit(f"render_raster.py: {name}_gt.png is {gt.shape[1]}x{gt.shape[0]}, "
                         f"its map {grid.shape[1]}x{grid.shape[0]}: they must be the same size")
    free, occupied = grid >= FREE_MIN, grid == 0
    key = (gt[..., 0].astype(np.int64) << 16) | (gt[..., 1].astype(np.int64) << 8) | gt[..., 2]
    key[~free] = 0
    _, rooms = np.unique(key, return_inverse=True)  # 0 stays 0: black is the smallest key
    rooms = rooms.reshape(grid.shape)
    if not (key == 0).any():
        rooms += 1  # no black cell at all: every label is a room
    # Colours on fewer cells than the scorer's smallest room are no room (anti-aliased edges).
    area = np.bincount(rooms.ravel())
    small = area < MIN_ROOM_CELLS
    small[0] = True
    _, rooms = np.unique(np.where(small[rooms], 0, rooms), return_inverse=True)
    rooms = rooms.reshape(grid.shape)
    return free, occupied, rooms, int(rooms.max())


def route(free, rng):
    """Viewpoints (x, y) in cells: a 1 m lattice with a random offset, on free cells at least
    CLEARANCE_M from anything not free."""
    clear = ~near(~free, int(round(CLEARANCE_M / RES)))
    step = int(round(LATTICE_M / RES))
    r0, c0 = (int(v) for v in rng.integers(0, step, 2))
    rr, cc = np.nonzero(clear[r0::step, c0::step])
    return [(c0 + c * step, r0 + r * step) for r, c in zip(rr, cc)]


def render(free, occupied, rooms, n, seed, laser):
    rng = np.random.default_rng(seed)
    lrng = np.random.default_rng(list(seed) + [1])
    clutter = room_clutter(free, rooms, n, rng)
    world_free, world_occ = free & ~clutter, occupied | clutter
    views = route(world_free, rng)
    if not views:
        raise SystemExit("render_raster.py: no free cell is 0.4 m from a wall: nothing to scan from")
    if laser:
        seen = robot_scan(world_free, world_occ, views, rng, rays=int(lrng.choice(LASER_RAYS)))
        return (*real_grid(*seen, lrng), len(views))
    return (*robot_scan(world_free, world_occ, views, rng), len(views))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("map_dir", metavar="MAP_DIR")
    ap.add_argument("out", metavar="OUT_DIR")
    ap.add_argument("--seeds", type=int, default=1, metavar="K")
    ap.add_argument("--laser", action="store_true")
    a = ap.parse_args()
    if a.seeds < 1:
        ap.error(f"--seeds must be at least 1, got {a.seeds}")
    names = sorted(f[:-8] for f in os.listdir(a.map_dir) if f.endswith("_map.png"))
    if not names:
        raise SystemExit(f"render_raster.py: no NAME_map.png in {a.map_dir}")
    kind = "laser" if a.laser else "robot"
    for name in names:
        free, occupied, rooms, n = read_pair(a.map_dir, name)
        for k in range(1, a.seeds + 1):
            seen_free, seen_occ, views = render(free, occupied, rooms, n,
                                                (zlib.crc32(name.encode()), k), a.laser)
            write(os.path.join(a.out, kind), f"{name}_s{k}", seen_free, seen_occ, rooms, n)
            print(f"{name}_s{k}: {kind}/, {n} rooms, {views} viewpoints")


if __name__ == "__main__":
    main()
