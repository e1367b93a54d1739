#!/usr/bin/python3
"""The segmentation's data scripts (issue 28) on one R2V plan and one small simulated hospital:
render_r2v.py's three variants share one ground truth and the robot/ variant is reproducible and
holds what a robot's grid holds (clutter, fewer walls seen), --robot-off leaves augmentations out,
--laser's laser/ is reproducible and its unknown band and dotted faces only make cells unknown;
--fronts's open_fronts removes only the wall between a room and its larger front neighbour;
render_sim.py's grid and ground truth agree in size, its corridor segments are one room;
train_layout_merge.py fits a model that zonemap runs, --bag joins bootstrap fits into one model
zonemap runs, --dagger-passes adds model-driven rows, and --loo-models keeps the leave-one-out's
models; score_sets.py passes --param on, segmentation_border_probe.py scores as zonemap does;
segmentation_identical.py tells identical zones from moved ones; ipa_to_grid.py reads the ipa
dataset's SVG ground truths into a map and its rooms; render_raster.py maps such a raster again
as a robot would; valetudo_to_grid.py reads a robot vacuum's ValetudoMap JSON into a map and its
rooms; grid_overlap.py finds one place in two maps, turned and moved; image_cue_probe.py trains
and scores (skipped without python3-torch).
Behaviour, not figures.

Usage: segmentation_data_test.py PROJECT_DIR WORK_DIR   (ZONEMAP in the environment)
"""
import base64
import io
import json
import os
import shutil
import subprocess
import sys

import numpy as np
from PIL import Image

try:
    import sklearn  # noqa: F401  (train_layout_merge.py's; scripts/install-deps.sh installs it)
except ImportError:
    print("python3-sklearn missing: run scripts/install-deps.sh --host; not checked")
    sys.exit(77)

project, work = sys.argv[1], sys.argv[2]
zonemap = os.environ["ZONEMAP"]
scripts = os.path.join(project, "scripts")
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def load(path):
    return np.array(Image.open(path))


# One R2V plan, rendered twice.
src = os.path.join(work, "src")
os.makedirs(src)
plan = sorted(f for f in os.listdir(os.path.join(project, "tests/data/segmentation/r2v"))
              if f.endswith(".txt"))[0]
shutil.copy(os.path.join(project, "tests/data/segmentation/r2v", plan), src)
name = "r2v_" + plan[:-4]
for out in ("a", "b"):
    subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py"), src,
                    os.path.join(work, out)], check=True, capture_output=True)
maps = {v: load(os.path.join(work, "a", v, name + "_map.png")) for v in ("plan", "scan", "robot")}
gts = {v: load(os.path.join(work, "a", v, name + "_gt.png")) for v in ("plan", "scan", "robot")}
check(all(m.shape == maps["plan"].shape for m in maps.values()), "three variants, one size")
check(all((g == gts["plan"]).all() for g in gts.values()), "three variants, one ground truth")
check((load(os.path.join(work, "b", "robot", name + "_map.png")) == maps["robot"]).all(),
      "robot/ is reproducible (seeded by the plan's name)")
room = gts["plan"].any(axis=2)
check(((maps["robot"] == 0) & room).sum() > ((maps["scan"] == 0) & room).sum(),
      "robot/ has clutter and door leaves in the rooms")
check(set(np.unique(maps["robot"])) <= {0, 128, 255}, "robot/ is a trinary grid")

# The ablation (--robot-off): only robot/ is written; with every augmentation off it is the
# laser's map of the plan without clutter (no more occupied cells in the rooms than scan/ holds),
# and with clutter off fewer cells in the rooms are occupied than in the full robot/ render.
for off in ("clutter", "glass,leaves,clutter,unexplored,range,noise,specks"):
    subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py"), src,
                    os.path.join(work, off), "--robot-off", off], check=True,
                   capture_output=True)
check(not os.path.exists(os.path.join(work, "clutter", "plan")), "--robot-off writes robot/ only")
no_clutter = load(os.path.join(work, "clutter", "robot", name + "_map.png"))
bare = load(os.path.join(work, "glass,leaves,clutter,unexplored,range,noise,specks", "robot",
                         name + "_map.png"))
check(((no_clutter == 0) & room).sum() < ((maps["robot"] == 0) & room).sum(),
      "--robot-off clutter: fewer occupied cells in the rooms")
check(((bare == 0) & room).sum() <= ((maps["scan"] == 0) & room).sum(),
      "--robot-off with everything off: no clutter, leaves or specks in the rooms")
bad = subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py"), src,
                      os.path.join(work, "bad"), "--robot-off", "paint"], capture_output=True,
                     text=True)
check(bad.returncode != 0 and "paint" in bad.stderr, "--robot-off names an unknown augmentation")
# An unknown option is refused, not taken for the output directory; --help writes nothing.
for argv, named in (([os.path.join(work, "bogus"), "--bogus"], "arguments: --bogus"),
                    ([src, os.path.join(work, "bogus"), "extra"], "arguments: extra"),
                    ([src, os.path.join(work, "bogus"), "--robot-off"], "--robot-off: expected"),
                    (["--help"], None)):
    p = subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py")] + argv, cwd=work,
                       capture_output=True, text=True)
    check((p.returncode == 0 and "Usage" in p.stdout) if named is None else
          (p.returncode != 0 and named in p.stderr and "Traceback" not in p.stderr),
          f"render_r2v.py {' '.join(argv[-1:])}: " + ("usage" if named is None else "refused"))
check(not os.path.exists(os.path.join(work, "bogus")) and
      not os.path.exists(os.path.join(work, "--help")), "render_r2v.py: nothing written for them")


def one_variant(flag, kind, refused_with):
    """render_r2v.py FLAG twice: KIND/ written alone, with the plan's ground truth, reproducible
    and trinary; FLAG with REFUSED_WITH is refused. Returns KIND/'s grid."""
    for out in (kind + "_a", kind + "_b"):
        subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py"), src,
                        os.path.join(work, out), flag], check=True, capture_output=True)
    grid = load(os.path.join(work, kind + "_a", kind, name + "_map.png"))
    check(os.listdir(os.path.join(work, kind + "_a")) == [kind], f"{flag} writes {kind}/ only")
    check((load(os.path.join(work, kind + "_a", kind, name + "_gt.png")) == gts["plan"]).all(),
          f"{kind}/ has the plan's ground truth")
    check((load(os.path.join(work, kind + "_b", kind, name + "_map.png")) == grid).all(),
          f"{kind}/ is reproducible")
    check(set(np.unique(grid)) <= {0, 128, 255}, f"{kind}/ is a trinary grid")
    both = subprocess.run([sys.executable, os.path.join(scripts, "render_r2v.py"), src,
                           os.path.join(work, kind + "_c"), flag] + refused_with,
                          capture_output=True, text=True)
    check(both.returncode != 0, f"{flag} and {refused_with[0]} together are refused")
    return grid


# laser/ (--laser, issue 28's sixth round); real_grid only turns free cells and returns into
# unknown, and its band leaves fewer free cells touching a return (free space meets unknown, as
# on the shared robot maps). front/ (--fronts, ninth round): another grid than laser/'s.
laser = one_variant("--laser", "laser", ["--robot-off", "noise"])
front = one_variant("--fronts", "front", ["--laser"])
check(not (front == laser).all(), "front/ is not laser/'s grid")
sys.path.insert(0, scripts)
from render_r2v import open_fronts, real_grid  # noqa: E402

# open_fronts on a drawn world (3-cell walls, unknown outside): a corridor (room 1, 486 cells)
# above two offices (rooms 2 and 3, 396 and 429 cells), a closet (room 4, 198) behind office 3.
walls = np.zeros((44, 64), bool)
walls[2:42, 2:62] = True
walls[5:39, 5:59] = False
walls[14:17, 5:59] = True  # the corridor's wall towards the offices
walls[17:39, 23:26] = True  # the wall between the two offices
walls[30:33, 26:59] = True  # office 3's far wall, towards the closet
lab = np.zeros(walls.shape, int)
lab[5:14, 5:59], lab[17:39, 5:23], lab[17:30, 26:59], lab[33:39, 26:59] = 1, 2, 3, 4
kept = walls.copy(), lab.copy()
f1, o1, k1 = open_fronts(lab > 0, walls, lab, 4, np.random.default_rng(0), share=1.0)
check(k1 == 3 and (walls == kept[0]).all() and (lab == kept[1]).all(),
      "open_fronts: three fronts (the corridor has no larger neighbour); its inputs unchanged")
check(f1[14:17, 5:59].all() and not o1[14:17, 5:59].any(),
      "open_fronts: both offices' walls towards the corridor (their largest neighbour) are gone")
check(o1[18:29, 23:26].all(), "open_fronts: the wall between the offices stays (each office's "
      "front is the corridor; office 2 is smaller than office 3 but shares less wall with it)")
check(f1[30:33, 26:59].all(), "open_fronts: the closet's front towards office 3 is gone")
check(o1[2, 2:62].all() and o1[2:42, 2].all() and o1[2:42, 61].all() and o1[41, 2:62].all(),
      "open_fronts: the outer wall's outside face stays closed")
check(((f1 & ~(lab > 0)) <= walls).all(), "open_fronts: only wall cells become free")
f0, o0, k0 = open_fronts(lab > 0, walls, lab, 4, np.random.default_rng(0), share=0.0)
check(k0 == 0 and (o0 == walls).all(), "open_fronts at share 0: nothing opened")

wall = np.zeros((40, 40), bool)
wall[5, 5:35] = wall[34, 5:35] = wall[5:35, 5] = wall[5:35, 34] = True
inside = np.zeros_like(wall)
inside[6:34, 6:34] = True


def touches(free, occupied):
    o = np.zeros_like(occupied)
    o[1:] |= occupied[:-1]
    o[:-1] |= occupied[1:]
    o[:, 1:] |= occupied[:, :-1]
    o[:, :-1] |= occupied[:, 1:]
    return (free & o).sum()


results = [real_grid(inside, wall, np.random.default_rng(k)) for k in range(20)]
check(all((f <= inside).all() and (o <= wall).all() for f, o in results),
      "real_grid only makes cells unknown")
check(all(touches(f, wall) < touches(inside, wall) and f.sum() > 0 for f, _ in results),
      "real_grid: the band leaves fewer free cells touching a return, and free space remains")
check(any(o.sum() < wall.sum() for _, o in results), "real_grid: dotted faces")

# One small simulated hospital mapped by its robot.
sim = os.path.join(work, "sim")
out = subprocess.run([sys.executable, os.path.join(scripts, "render_sim.py"), zonemap, sim, "7"],
                     check=True, capture_output=True, text=True).stdout
grid = load(os.path.join(sim, "sim_hospital_7_map.png"))
gt = load(os.path.join(sim, "sim_hospital_7_gt.png"))
check(grid.shape == gt.shape[:2], "sim grid and ground truth agree in size")
colours = {tuple(c) for c in gt.reshape(-1, 3)} - {(0, 0, 0)}
check(len(colours) >= 5, f"sim ground truth has rooms ({len(colours)})")
seen = (grid == 255).sum() / max(1, gt.any(axis=2).sum())
check(0.3 < seen < 1.0, f"the robot saw part of the building's free space ({seen:.2f})")
check("rooms" in out, "render_sim.py reports its buildings")
lsim = os.path.join(work, "lsim")
subprocess.run([sys.executable, os.path.join(scripts, "render_sim.py"), zonemap, lsim, "7",
                "--laser"], check=True, capture_output=True)
check((load(os.path.join(lsim, "sim_hospital_7_gt.png")) == gt).all() and
      not (load(os.path.join(lsim, "sim_hospital_7_map.png")) == grid).all(),
      "render_sim.py --laser: the same building and rooms, another grid")
fsim = os.path.join(work, "fsim")
subprocess.run([sys.executable, os.path.join(scripts, "render_sim.py"), zonemap, fsim, "7",
                "--fronts"], check=True, capture_output=True)
check((load(os.path.join(fsim, "sim_hospital_7_gt.png")) == gt).all() and
      not (load(os.path.join(fsim, "sim_hospital_7_map.png")) ==
           load(os.path.join(lsim, "sim_hospital_7_map.png"))).all(),
      "render_sim.py --fronts: the same building and rooms, another grid than --laser")

# A model fitted on these three maps runs in zonemap. rows_of trains one on them (hist learner)
# with the arguments given, and returns the process and its (oracle, model-driven) row counts.
def rows_of(*extra):
    p = subprocess.run([sys.executable, os.path.join(scripts, "train_layout_merge.py"), zonemap,
                        os.path.join(work, "a", "plan"), os.path.join(work, "a", "robot"), sim,
                        "--learner", "hist"] + list(extra), capture_output=True, text=True)
    words = p.stderr.split()
    return p, (int(words[2]), int(words[5])) if p.returncode == 0 and len(words) > 5 else None


def runs_model(path):
    """zonemap segments set 1's robot render with the model at `path`, into at least one zone."""
    run = subprocess.run([zonemap, "zones", "segment", os.path.join(work, "a", "robot",
                                                                   name + "_map.png"),
                          "--out", os.devnull, "--merge-model", path, "--json"],
                         capture_output=True, text=True)
    return run.returncode == 0 and json.loads(run.stdout)["zones"] >= 1


model = os.path.join(work, "model.json")
first, n1 = rows_of("--json", model)
check(first.returncode == 0 and n1 is not None, "train_layout_merge.py fits the three maps")
check(runs_model(model), "zonemap runs the model")

# --bag 2: two fits on maps resampled within their DIR, joined into one model (twice the trees,
# the learners' mean log-odds, checked inside the script), reproducible, run by zonemap. The
# second run traces two maps at once (--jobs 2): the same bytes.
# A third run names --bag-seed 1, the default's first seed: the same draw.
bags = []
for out, extra in (("bag_a.json", ["--jobs", "1"]), ("bag_b.json", ["--jobs", "2"]),
                   ("bag_s1.json", ["--bag-seed", "1"])):
    subprocess.run([sys.executable, os.path.join(scripts, "train_layout_merge.py"), zonemap,
                    os.path.join(work, "a", "plan"), os.path.join(work, "a", "robot"), sim,
                    "--json", os.path.join(work, out), "--learner", "hist", "--bag", "2"] + extra,
                   check=True, capture_output=True)
    bags.append(open(os.path.join(work, out)).read())
one, two = json.load(open(model)), json.loads(bags[0])
check(bags[0] == bags[1] and len(two["trees"]) == 2 * len(one["trees"]) and
      two["trained_with"] == one["trained_with"],
      "--bag 2: two joined fits, reproducibly, and the same with --jobs 2")
# --bag-seed S draws the bootstrap from seeds S.. (another draw of the same recipe); 1 is the
# default's draw, byte for byte; below 1 is refused.
check(bags[2] == bags[0], "--bag-seed 1 is the default's draw")
bad, _ = rows_of("--bag", "2", "--bag-seed", "0")
check(bad.returncode != 0 and "--bag-seed 0" in bad.stderr, "--bag-seed 0 is refused")
bad, _ = rows_of("--jobs", "0")
check(bad.returncode != 0 and "--jobs 0" in bad.stderr, "--jobs 0 is refused")
check(runs_model(os.path.join(work, "bag_a.json")), "zonemap runs a bagged model")

# --dagger-passes 2: a second DAgger pass adds the rows of the states the second model's merges
# lead to (more model-driven rows, the same oracle rows); zonemap runs the model; 0 is refused.
_, n2 = rows_of("--json", os.path.join(work, "d2.json"), "--dagger-passes", "2")
check(n1 is not None and n2 is not None and n2[0] == n1[0] and n2[1] > n1[1],
      f"--dagger-passes 2: the same oracle rows, more model-driven rows ({n1} -> {n2})")
check(runs_model(os.path.join(work, "d2.json")), "zonemap runs a model of two DAgger passes")
bad, _ = rows_of("--dagger-passes", "0")
check(bad.returncode != 0 and "--dagger-passes 0" in bad.stderr, "--dagger-passes 0 is refused")
# --features 35: the shipped model's feature set (it predates the map-level features), as the
# floor of issue 28's rounds is trained; zonemap runs it; a count beyond the trace's is refused.
rows_of("--json", os.path.join(work, "f35.json"), "--features", "35")
f35 = json.load(open(os.path.join(work, "f35.json")))
all47 = json.load(open(model))["features"]
check(len(all47) == 47 and f35["features"] == all47[:35] and
      all(f < 35 for t in f35["trees"] for f in t["feature"]), "--features 35 trains on the first 35")
check(runs_model(os.path.join(work, "f35.json")), "zonemap runs a model of 35 features")
# --drop: a feature in the middle left out; the model lists every name, no tree splits on it.
rows_of("--json", os.path.join(work, "drop.json"), "--drop", "channel_width_near", "--drop",
        "channel_width_far")
dropped = json.load(open(os.path.join(work, "drop.json")))
check(dropped["features"] == all47 and
      not any(f in (all47.index("channel_width_near"), all47.index("channel_width_far"))
              for t in dropped["trees"] for f in t["feature"]) and
      runs_model(os.path.join(work, "drop.json")), "--drop trains without the named features")
bad, _ = rows_of("--drop", "no_such_feature")
check(bad.returncode != 0 and "--drop no_such_feature" in bad.stderr, "--drop of no feature is refused")
bad, _ = rows_of("--features", "48")
check(bad.returncode != 0 and "--features 48: from 1 to 47" in bad.stderr,
      "--features beyond the trace's is refused")
# --trees / --depth / --rate: the ensemble's size (issue 28's twenty-eighth round's probes).
rows_of("--json", os.path.join(work, "small.json"), "--trees", "20", "--depth", "2",
        "--rate", "0.3")
small = json.load(open(os.path.join(work, "small.json")))
check(len(small["trees"]) == 20 and
      all(sum(f >= 0 for f in t["feature"]) <= 3 for t in small["trees"]) and
      runs_model(os.path.join(work, "small.json")), "--trees 20 --depth 2: twenty trees of depth 2")
bad, _ = rows_of("--depth", "0")
check(bad.returncode != 0 and "--depth 0" in bad.stderr, "--depth 0 is refused")
# --row-weight area_s: the same oracle rows, each weighed by its smaller piece's area; another model.
_, na = rows_of("--json", os.path.join(work, "area.json"), "--row-weight", "area_s")
area = json.load(open(os.path.join(work, "area.json")))
check(na is not None and na[0] == n1[0] and area["trees"] != json.load(open(model))["trees"] and
      runs_model(os.path.join(work, "area.json")),
      "--row-weight area_s: the same oracle rows, weighed otherwise, another model")
sys.path.insert(0, scripts)
import train_layout_merge  # noqa: E402
counts = train_layout_merge.bootstrap_counts(["a", "a", "a", "b", "b"], 1)
check(counts[:3].sum() == 3 and counts[3:].sum() == 2 and
      (counts == train_layout_merge.bootstrap_counts(["a", "a", "a", "b", "b"], 1)).all() and
      not all((train_layout_merge.bootstrap_counts(["a"] * 8, s) == 1).all() for s in (1, 2, 3)),
      "bootstrap_counts: every DIR keeps its number of maps, the same for a seed")

# --loo with --loo-models keeps each fold's model (trained without its map) under the map's name.
kept = os.path.join(work, "loo_models")
table = subprocess.run([sys.executable, os.path.join(scripts, "train_layout_merge.py"), zonemap,
                        os.path.join(work, "a", "plan"), os.path.join(work, "a", "robot"), sim,
                        "--learner", "hist", "--loo", sim, "--loo-models", kept],
                       check=True, capture_output=True, text=True).stdout
check(sorted(os.listdir(kept)) == ["sim_hospital_7.json"] and "| sim_hospital_7 |" in table,
      "--loo-models keeps the left-out map's model")
run = subprocess.run([zonemap, "zones", "segment", os.path.join(sim, "sim_hospital_7_map.png"),
                      "--out", os.devnull, "--merge-model",
                      os.path.join(kept, "sim_hospital_7.json")], capture_output=True)
check(run.returncode == 0, "zonemap runs a kept fold model")

# gate_layout_merge.py joins the compiled-in model (clean plans) and this one (robot-made
# grids) into one: the plan's zones are the default's, the robot render's this model's.
joined = os.path.join(work, "joined.json")
subprocess.run([sys.executable, os.path.join(scripts, "gate_layout_merge.py"),
                os.path.join(project, "lib", "segment", "layout_merge_model.inc"), model,
                "--gate", "0.3", "--json", joined], check=True, capture_output=True)


def zones_of(map_png, *extra):
    out = os.path.join(work, "zones.geojson")
    subprocess.run([zonemap, "zones", "segment", map_png, "--out", out] + list(extra),
                   check=True, capture_output=True)
    return open(out).read()


plan_png = os.path.join(work, "a", "plan", name + "_map.png")
robot_png = os.path.join(work, "a", "robot", name + "_map.png")
check(zones_of(plan_png, "--merge-model", joined) == zones_of(plan_png),
      "gate_layout_merge.py: a clean plan gets the compiled-in model's zones")
check(zones_of(robot_png, "--merge-model", joined) == zones_of(robot_png, "--merge-model", model),
      "gate_layout_merge.py: a robot-made grid gets the robot model's zones")

# The eighth round's gate: a robot half trained on pieces cut with the rough-grid options
# (CutOptions::layout_rough_*), joined under map_rough_cut. zonemap then cuts a rough grid
# without caps and the robot half merges it; a clean plan is cut and merged as by default.
rough = ["--param", "layout_rough_face_share=0.3", "--param", "layout_rough_cap_max_m=0"]
rough_model = os.path.join(work, "rough_model.json")
subprocess.run([sys.executable, os.path.join(scripts, "train_layout_merge.py"), zonemap,
                os.path.join(work, "a", "plan"), os.path.join(work, "a", "robot"), sim,
                "--json", rough_model, "--learner", "hist"] + rough, check=True,
               capture_output=True)
cut = json.load(open(rough_model))["trained_with"]["cut"]
check(cut["layout_rough_face_share"] == 0.3 and cut["layout_rough_cap_max_m"] == 0.0,
      "train_layout_merge.py --param records the rough-grid options")
rough_joined = os.path.join(work, "rough_joined.json")
subprocess.run([sys.executable, os.path.join(scripts, "gate_layout_merge.py"),
                os.path.join(project, "lib", "segment", "layout_merge_model.inc"), rough_model,
                "--gate", "0.5", "--gate-feature", "map_rough_cut", "--json", rough_joined],
               check=True, capture_output=True)
check(json.load(open(rough_joined))["trained_with"] == json.load(open(rough_model))["trained_with"],
      "gate_layout_merge.py --gate-feature map_rough_cut: the robot half's record is the model's")


def report(map_png, *extra):
    return json.loads(subprocess.run([zonemap, "zones", "segment", map_png, "--out", os.devnull,
                                      "--json"] + list(extra), check=True, capture_output=True,
                                     text=True).stdout)


check(not report(plan_png, "--merge-model", rough_model, *rough)["rough_cut"] and
      report(robot_png, "--merge-model", rough_model, *rough)["rough_cut"],
      "a plan is below layout_rough_face_share 0.3 and a robot render above it")
check(zones_of(plan_png, "--merge-model", rough_joined, *rough) == zones_of(plan_png),
      "map_rough_cut gate: a clean plan gets the default's zones")
check(zones_of(robot_png, "--merge-model", rough_joined, *rough) ==
      zones_of(robot_png, "--merge-model", rough_model, *rough),
      "map_rough_cut gate: a rough grid gets the robot half's zones, cut without caps")
never_rough = json.load(open(rough_model))
never_rough["trained_with"]["cut"]["layout_rough_face_share"] = 1.0
never_rough_model = os.path.join(work, "never_rough.json")
json.dump(never_rough, open(never_rough_model, "w"))
for robot, gate, why in ((never_rough_model, "0.5", "no map would reach it"),
                         (rough_model, "1", "between")):
    bad = subprocess.run([sys.executable, os.path.join(scripts, "gate_layout_merge.py"),
                          os.path.join(project, "lib", "segment", "layout_merge_model.inc"),
                          robot, "--gate", gate, "--gate-feature", "map_rough_cut"],
                         capture_output=True, text=True)
    check(bad.returncode != 0 and why in bad.stderr and "Traceback" not in bad.stderr,
          "gate_layout_merge.py refuses, in one line: " + why)

# score_sets.py passes --param to zonemap; segmentation_border_probe.py's scorer agrees with
# ScoreSegmentation (its no-merge row is score_sets.py's row) and a rule only merges.
robot_dir = os.path.join(work, "a", "robot")
sets = subprocess.run([sys.executable, os.path.join(scripts, "score_sets.py"), zonemap, robot_dir,
                       sim], check=True, capture_output=True, text=True).stdout
rows = {r.split("|")[1].strip(): [float(x) for x in r.split("|")[3:7]]
        for r in sets.splitlines() if r.startswith("| /")}
bad = subprocess.run([sys.executable, os.path.join(scripts, "score_sets.py"), zonemap, robot_dir,
                      "--param", "no_such_option=1"], capture_output=True, text=True)
check(bad.returncode != 0 and "no_such_option" in bad.stderr,
      "score_sets.py --param reaches zonemap (an unknown option is refused by name)")
# --oracle: the pieces merged by the ground truth, the best any merge of them can do; on the
# hospital it joins what the model leaves cut (at least the model's recall, nearly all precision).
oracle = subprocess.run([sys.executable, os.path.join(scripts, "score_sets.py"), zonemap, sim,
                         "--oracle"], check=True, capture_output=True, text=True).stdout
best = [[float(x) for x in r.split("|")[3:7]] for r in oracle.splitlines() if r.startswith("| /")]
check(len(best) == 1 and best[0][1] >= rows[sim][1] and best[0][0] >= 95.0,
      f"score_sets.py --oracle: recall {best[0][1] if best else None} >= the model's "
      f"{rows[sim][1]}, precision >= 95")
bad = subprocess.run([sys.executable, os.path.join(scripts, "score_sets.py"), zonemap, sim,
                      "--oracle", "--merge-model", model], capture_output=True, text=True)
check(bad.returncode != 0 and "--oracle" in bad.stderr and "Traceback" not in bad.stderr,
      "score_sets.py --oracle with --merge-model is refused")
bad = subprocess.run([sys.executable, os.path.join(scripts, "score_sets.py"), zonemap,
                      os.path.join(work, "a")], capture_output=True, text=True)
check(bad.returncode != 0 and "no <name>_map.png" in bad.stderr and bad.stdout == "" and
      "Traceback" not in bad.stderr, "score_sets.py refuses a DIR with no maps, before any row")
probe = subprocess.run([sys.executable, os.path.join(scripts, "segmentation_border_probe.py"),
                        zonemap, os.path.join(work, "labels"), robot_dir, sim],
                       capture_output=True, text=True)
check(probe.returncode == 0 and probe.stdout.count("recall lost by how") == 2,
      "segmentation_border_probe.py reports both sets")
blocks = probe.stdout.split("== ")[1:]
for block in blocks:
    d = block.split(":")[0]
    score_rows = {line.split("P/R/IoU/IoU shown %")[0].strip():
                  [float(x) for x in line.split("%")[-1].split("/")]
                  for line in block.splitlines() if "P/R/IoU/IoU shown %" in line}
    none = score_rows.get("none (the shipped defaults)")
    check(none is not None and d in rows and
          all(abs(a - b) <= 0.11 for a, b in zip(none, rows[d])),
          f"the probe's unmerged score is ScoreSegmentation's ({os.path.basename(d)})")
    check(all(v[0] <= none[0] + 0.11 and v[1] >= none[1] - 0.11 for v in score_rows.values()),
          f"a post-merge rule never raises precision nor lowers recall ({os.path.basename(d)})")

# segmentation_identical.py: a build against itself is identical; against one whose zones move
# (the same zonemap with the rule merges, through a wrapper) it names the map and fails.
same = subprocess.run([sys.executable, os.path.join(scripts, "segmentation_identical.py"), zonemap,
                       zonemap, robot_dir], capture_output=True, text=True)
check(same.returncode == 0 and "1 of 1 runs identical" in same.stdout,
      "segmentation_identical.py: a build against itself is identical")
rules = os.path.join(work, "zonemap_rules")
with open(rules, "w") as f:
    f.write('#!/bin/sh\nexec "%s" "$@" --param layout_merge_threshold=0\n' % zonemap)
os.chmod(rules, 0o755)
moved = subprocess.run([sys.executable, os.path.join(scripts, "segmentation_identical.py"),
                        zonemap, rules, robot_dir], capture_output=True, text=True)
check(moved.returncode == 1 and "DIFFERS: " in moved.stdout,
      "segmentation_identical.py: zones that move are named and fail")

# ipa_to_grid.py: an SVG in the ipa dataset's form (the map as an embedded PNG, separators drawn
# over it, one rotated, one inside a translated group) gives the map back unchanged and one room
# per free component once the separators close their doorways; a speck gets no colour.
ipa_src = os.path.join(work, "ipa_src")
os.makedirs(ipa_src)
grid = np.full((40, 60), 254, np.uint8)  # free, 0.05 m cells: 3 m x 2 m
grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 0
grid[:, 20] = 0
grid[18:24, 20] = 254   # a doorway between the left and the middle room
grid[:, 40] = 0
grid[10:30, 40] = 254   # a wide opening between the middle and the right room
grid[2:5, 2:5] = 205    # unknown cells stay as they are
grid[4, 44:53] = 0
grid[1:5, 44] = grid[1:5, 52] = 0  # walls close off a speck of 21 cells in the right room
buffer = io.BytesIO()
Image.fromarray(grid).save(buffer, format="PNG")
payload = base64.b64encode(buffer.getvalue()).decode()
payload = "\n".join(payload[i:i + 76] for i in range(0, len(payload), 76))  # as Inkscape wraps
with open(os.path.join(ipa_src, "toy_gt_segmentation.svg"), "w") as f:
    f.write('''<?xml version="1.0" encoding="UTF-8" standalone="no"?>
<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"
     xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" width="120" height="80">
  <image width="120" height="80" x="0" y="0" xlink:href="data:image/png;base64,%s" />
  <g inkscape:groupmode="layer" id="layer1" transform="translate(4,0)">
    <rect style="fill:#000000;stroke:#000000;stroke-width:1px" width="2" height="14"
          x="36" y="33" transform="rotate(0)" />
  </g>
  <rect style="fill:#cccccc;stroke:#000000;stroke-width:1px" width="42" height="1.5"
        x="-20" y="-0.75" transform="matrix(0,1,-1,0,81,40)" />
</svg>
''' % payload)
out_ipa = os.path.join(work, "ipa_out")
conv = subprocess.run([sys.executable, os.path.join(scripts, "ipa_to_grid.py"), ipa_src, out_ipa],
                      capture_output=True, text=True)
check(conv.returncode == 0 and "ipa_toy: 60x40 cells, 2 separators, 3 rooms" in conv.stdout,
      "ipa_to_grid.py reads the embedded map and both separators: " + conv.stdout.strip())
if conv.returncode == 0:
    check(np.array_equal(load(os.path.join(out_ipa, "ipa_toy_map.png")), grid),
          "ipa_to_grid.py writes the embedded map unchanged")
    gt = load(os.path.join(out_ipa, "ipa_toy_gt.png"))
    colours = {tuple(int(v) for v in gt[r, c]) for r, c in ((10, 10), (10, 30), (10, 50))}
    check(len(colours) == 3 and all(max(c) > 20 for c in colours),
          "ipa_to_grid.py: the two separators make three rooms, each its own colour")
    check(not any(gt[r, c].any() for r, c in ((20, 20), (20, 40), (2, 48), (3, 3))),
          "ipa_to_grid.py: walls, the speck and unknown cells are in no room")
# A drawn plan (office_a-i's kind): floor a light grey, walls outlined with a grey fill, the outside
# a mid grey, hardly a white cell. It is read as a map: floor free, walls occupied, outside unknown.
drawn = np.full((40, 60), 178, np.uint8)  # the outside
drawn[8:32, 8:52] = 238                   # the floor
drawn[8:32, 29:33] = 170                  # an interior wall ...
drawn[8:32, 29] = drawn[8:32, 32] = 80    # ... outlined
drawn[17:23, 29:33] = 238                 # with a doorway
drawn[10, 10] = 255                       # one white speck (anti-aliasing)
buffer = io.BytesIO()
Image.fromarray(drawn).save(buffer, format="PNG")
payload = base64.b64encode(buffer.getvalue()).decode()
drawn_src = os.path.join(work, "ipa_drawn")
os.makedirs(drawn_src)
with open(os.path.join(drawn_src, "plan_gt_segmentation.svg"), "w") as f:
    f.write('<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"'
            ' width="60" height="40">\n'
            '  <image width="60" height="40" xlink:href="data:image/png;base64,%s" />\n'
            '  <rect style="fill:#000000;stroke:none" width="4" height="6" x="29" y="17" />\n'
            '</svg>\n' % payload)
out_drawn = os.path.join(work, "ipa_drawn_out")
conv = subprocess.run([sys.executable, os.path.join(scripts, "ipa_to_grid.py"), drawn_src,
                       out_drawn], capture_output=True, text=True)
check(conv.returncode == 0 and "ipa_plan: 60x40 cells, 1 separators, 2 rooms" in conv.stdout
      and "a drawing" in conv.stdout,
      "ipa_to_grid.py reads a drawn plan as a map: " + conv.stdout.strip() + conv.stderr)
if conv.returncode == 0:
    m = load(os.path.join(out_drawn, "ipa_plan_map.png"))
    check(m[10, 10] == 254 and m[20, 15] == 254 and m[20, 30] == 254 and m[10, 30] == 0
          and m[4, 4] == 0 and m[0, 0] == 205,
          "ipa_to_grid.py: a drawn plan's floor (its doorway too) is free, its walls and the "
          "outside within 0.3 m of the floor occupied, the outside beyond unknown")
bad = os.path.join(work, "ipa_bad")
os.makedirs(bad)
with open(os.path.join(bad, "x_gt_segmentation.svg"), "w") as f:
    f.write('<svg xmlns="http://www.w3.org/2000/svg"><rect width="1" height="1"/></svg>')
refused = subprocess.run([sys.executable, os.path.join(scripts, "ipa_to_grid.py"), bad,
                          os.path.join(work, "ipa_bad_out")], capture_output=True, text=True)
check(refused.returncode != 0 and "0 embedded images" in refused.stderr,
      "ipa_to_grid.py refuses an SVG without an embedded map, naming it")

# render_raster.py: a raster map with rooms, mapped again as a robot would. Two rooms of 4 x 5 m
# joined by a 1 m doorway; renders are reproducible, differ from seed to seed, see free only
# where the map is free, and keep the ground truth's rooms.
raster_src = os.path.join(work, "raster_src")
os.makedirs(raster_src)
grid = np.full((120, 180), 205, np.uint8)
grid[10:110, 10:170] = 254
grid[10:110, 10] = grid[10:110, 169] = grid[10, 10:170] = grid[109, 10:170] = 0
grid[10:110, 90:93] = 0
grid[50:70, 90:93] = 254  # the doorway
rooms_in = np.zeros(grid.shape, np.uint8)
rooms_in[11:109, 11:91] = 1
rooms_in[11:109, 91:169] = 2
gt_in = np.zeros(grid.shape + (3,), np.uint8)
gt_in[rooms_in == 1] = (200, 40, 40)
gt_in[rooms_in == 2] = (40, 200, 40)
gt_in[grid != 254] = 0
Image.fromarray(grid).save(os.path.join(raster_src, "two_map.png"))
Image.fromarray(gt_in).save(os.path.join(raster_src, "two_gt.png"))
renders = {}
for tag, extra in (("a", []), ("b", []), ("l", ["--laser"])):
    out = os.path.join(work, "raster_" + tag)
    run = subprocess.run([sys.executable, os.path.join(scripts, "render_raster.py"), raster_src,
                          out, "--seeds", "2"] + extra, capture_output=True, text=True)
    check(run.returncode == 0 and "two_s2: " in run.stdout,
          "render_raster.py renders each map --seeds times: " + run.stdout + run.stderr)
    kind = "laser" if extra else "robot"
    renders[tag] = {k: (load(os.path.join(out, kind, f"two_s{k}_map.png")),
                        load(os.path.join(out, kind, f"two_s{k}_gt.png"))) for k in (1, 2)
                    if os.path.exists(os.path.join(out, kind, f"two_s{k}_map.png"))}
if all(len(v) == 2 for v in renders.values()):
    check(all(np.array_equal(renders["a"][k][0], renders["b"][k][0]) for k in (1, 2)),
          "render_raster.py: a render is reproducible")
    check(not np.array_equal(renders["a"][1][0], renders["a"][2][0]),
          "render_raster.py: a map's renders differ from seed to seed")
    for tag in ("a", "l"):
        for k in (1, 2):
            seen, gt = renders[tag][k]
            check(not ((seen >= 250) & (grid != 254)).any(),
                  f"render_raster.py ({tag}, s{k}): free only where the map is free")
            check((seen == 0).sum() > 0 and (seen >= 250).sum() > 0.5 * (grid == 254).sum(),
                  f"render_raster.py ({tag}, s{k}): walls returned and most free space seen")
            colours = {tuple(int(v) for v in gt[r, c]) for r, c in ((60, 50), (60, 130))}
            check(len(colours) == 2 and (gt.reshape(-1, 3).any(axis=1).reshape(grid.shape)
                                         == (rooms_in > 0) & (grid == 254)).all(),
                  f"render_raster.py ({tag}, s{k}): the ground truth's two rooms, on free cells")
    check(not np.array_equal(renders["l"][1][0], renders["a"][1][0]),
          "render_raster.py --laser draws laser/'s look")
Image.fromarray(gt_in[:60]).save(os.path.join(raster_src, "two_gt.png"))
refused = subprocess.run([sys.executable, os.path.join(scripts, "render_raster.py"), raster_src,
                          os.path.join(work, "raster_bad")], capture_output=True, text=True)
check(refused.returncode != 0 and "two_gt.png is 180x60" in refused.stderr,
      "render_raster.py refuses a ground truth of another size than its map, naming it")

# valetudo_to_grid.py: a ValetudoMap in Valetudo's JSON (5 cm cells; runs as x, y, count, or
# plain x, y pairs). Two rooms of 40 x 20 cells either side of a wall with a doorway, a strip of
# floor no room holds, one wall cell a segment lists too (it stays a wall), and a speck of a
# segment too small to be a room.
def runs(cells):
    out = []
    for x, y, n in cells:
        out += [x, y, n]
    return out


wall = [(100, 200, 82), (100, 221, 82)] + [(100, y, 1) for y in range(201, 221)] + \
       [(181, y, 1) for y in range(201, 221)] + [(140, y, 1) for y in range(201, 221) if
                                                 not 208 <= y < 214]
left = [(101, y, 39) for y in range(201, 221)] + [(140, 205, 1)]  # (140, 205) is wall
right = [(141, y, 40) for y in range(201, 221)]
valetudo = {"__class": "ValetudoMap", "pixelSize": 5, "size": {"x": 6554, "y": 6554}, "layers": [
    {"type": "wall", "metaData": {}, "pixels": [], "compressedPixels": runs(wall)},
    {"type": "floor", "metaData": {}, "pixels": [], "compressedPixels": runs([(140, y, 1) for y in
                                                                            range(208, 214)])},
    {"type": "segment", "metaData": {"segmentId": "1", "name": "Bad"}, "pixels": [],
     "compressedPixels": runs(left)},
    {"type": "segment", "metaData": {"segmentId": "2"}, "compressedPixels": [],
     "pixels": [v for y in range(201, 221) for x in range(141, 181) for v in (x, y)]},
    {"type": "segment", "metaData": {"segmentId": "3"}, "pixels": [],
     "compressedPixels": runs([(300, 300, 5)])}]}
val_src = os.path.join(work, "valetudo_src")
os.makedirs(val_src)
json.dump(valetudo, open(os.path.join(val_src, "home.json"), "w"))
out_val = os.path.join(work, "valetudo_out")
conv = subprocess.run([sys.executable, os.path.join(scripts, "valetudo_to_grid.py"), val_src,
                       out_val], capture_output=True, text=True)
check(conv.returncode == 0 and "valetudo_home: 225x121 cells, 2 rooms" in conv.stdout,
      "valetudo_to_grid.py reads both rooms and no speck: " + conv.stdout.strip() + conv.stderr)
if conv.returncode == 0:
    m = load(os.path.join(out_val, "valetudo_home_map.png"))
    gt = load(os.path.join(out_val, "valetudo_home_gt.png"))
    at = lambda x, y: (y - 190, x - 90)  # noqa: E731  the bounding box and a 10-cell margin
    check(m[at(120, 210)] == 254 and m[at(160, 210)] == 254 and m[at(140, 210)] == 254 and
          m[at(140, 205)] == 0 and m[at(100, 210)] == 0 and m[0, 0] == 205,
          "valetudo_to_grid.py: floor and rooms free, walls occupied (a room's too), the rest "
          "unknown")
    a, b = tuple(int(v) for v in gt[at(120, 210)]), tuple(int(v) for v in gt[at(160, 210)])
    check(a != b and min(max(a), max(b)) > 20 and not gt[at(140, 210)].any() and
          not gt[at(140, 205)].any() and not gt[at(302, 300)].any(),
          "valetudo_to_grid.py: each room its colour; the doorway's floor, a wall and the speck "
          "in none")
valetudo["pixelSize"] = 2
json.dump(valetudo, open(os.path.join(val_src, "home.json"), "w"))
conv = subprocess.run([sys.executable, os.path.join(scripts, "valetudo_to_grid.py"), val_src,
                       out_val], capture_output=True, text=True)
check(conv.returncode != 0 and "cells of 2 cm, only 5 cm is read" in conv.stderr,
      "valetudo_to_grid.py refuses another cell size, naming it")

# grid_overlap.py: the same place in two maps, turned and moved, is found; another place is not.
# An L-shaped room, its copy rotated by 90 degrees, mirrored and framed in another margin with a
# speck of noise, and a plain rectangle of about the same area.
ov_dir = os.path.join(work, "overlap")
split = os.path.join(work, "overlap_split")
os.makedirs(ov_dir)
os.makedirs(split)
ROOM_COLOURS = ((200, 40, 40), (40, 200, 40), (40, 40, 200), (200, 200, 40))


def put(d, name, lab):
    """A map free wherever lab names a room (1..4), and its ground truth, one colour a room."""
    Image.fromarray(np.where(lab > 0, 254, 205).astype(np.uint8)).save(
        os.path.join(d, name + "_map.png"))
    rgb = np.zeros(lab.shape + (3,), np.uint8)
    for v, c in enumerate(ROOM_COLOURS, 1):
        rgb[lab == v] = c
    Image.fromarray(rgb).save(os.path.join(d, name + "_gt.png"))


def overlap(*args):
    return subprocess.run([sys.executable, os.path.join(scripts, "grid_overlap.py")] + list(args),
                          capture_output=True, text=True)


ell = np.zeros((90, 120), np.uint8)
ell[10:40, 10:110] = 1
ell[40:80, 10:50] = 1
turned = np.pad(np.rot90(ell, 1)[:, ::-1], ((7, 23), (31, 3)))
turned[60, 40] = 1 - turned[60, 40]
box = np.zeros((80, 110), np.uint8)
box[10:70, 10:100] = 1
put(ov_dir, "ell", ell)
put(ov_dir, "ell_turned", turned)
put(ov_dir, "box", box)
ov = overlap(ov_dir, "--min-iou", "0.9")
check(ov.returncode == 0 and "ell  ell_turned" in ov.stdout and "box" not in ov.stdout and
      "1 of 3 pairs share at least 0.90" in ov.stdout,
      "grid_overlap.py finds one place turned, mirrored and moved, and not another: " +
      ov.stdout.strip() + ov.stderr[-300:])
line = next((ln for ln in ov.stdout.splitlines() if "ell_turned" in ln), "0")
check(float(line.split()[0]) > 0.99, "grid_overlap.py: the pair's IoU is all but one cell's: "
      + line)
ov = overlap(ov_dir, "--against", ov_dir, "--min-iou", "0.9", "--gt", "--coarse", "2")
check(ov.returncode == 0 and "2 of 6 pairs share at least 0.90 of their ground truth's room "
      "cells" in ov.stdout, "grid_overlap.py --against compares every map with every other "
      "(both ways), by the ground truths, on 2 x 2 blocks: " + ov.stdout.strip())
# --layout: one footprint with its rooms drawn otherwise is another layout; the same layout turned
# is one. A flat of 60 x 120 cells as three rooms in a row, the same turned, and as two rooms above
# two.


def flat(cuts):
    lab = np.zeros((80, 140), np.uint8)
    lab[10:70, 10:130] = 1
    for (y0, y1, x0, x1), v in cuts:
        lab[y0:y1, x0:x1] = v
    return lab


row = flat([((10, 70, 50, 90), 2), ((10, 70, 90, 130), 3)])
put(split, "row", row)
put(split, "row_turned", np.rot90(row, 1))
put(split, "grid", flat([((10, 40, 70, 130), 2), ((40, 70, 10, 70), 3), ((40, 70, 70, 130), 4)]))
ov = overlap(split, "--gt", "--min-iou", "0.9", "--layout", "--min-layout", "0.8")
check(ov.returncode == 0 and "row  row_turned" in ov.stdout and "grid" not in ov.stdout and
      "1 of 3 pairs share at least 0.90" in ov.stdout,
      "grid_overlap.py --layout keeps one flat turned and not one footprint with other rooms: "
      + ov.stdout.strip() + ov.stderr[-300:])
ov = overlap(ov_dir, "--coarse", "0")
check(ov.returncode != 0 and "--coarse must be 1 or more, not 0" in ov.stderr,
      "grid_overlap.py refuses --coarse 0, naming it")

# image_cue_probe.py, a development probe (it needs python3-torch, which only
# `scripts/install-deps.sh --probes` installs; without it this part says so and is skipped):
# one epoch on set 1's robot render and the hospital, then its scores of the robot render, where
# joining nothing gives zonemap's own figures.
try:
    import torch  # noqa: F401
except ImportError:
    torch = None
if torch is None:
    print("skip image_cue_probe.py: python3-torch is not installed "
          "(scripts/install-deps.sh --probes)")
else:
    probe = os.path.join(scripts, "image_cue_probe.py")
    net_pt = os.path.join(work, "cue.pt")
    robot_dir = os.path.join(work, "a", "robot")
    tr = subprocess.run([sys.executable, probe, "train", net_pt, robot_dir, sim, "--epochs", "1"],
                        capture_output=True, text=True)
    check(tr.returncode == 0 and "epoch 0: loss" in tr.stdout and os.path.exists(net_pt),
          "image_cue_probe.py trains a network: " + tr.stdout.strip() + tr.stderr[-300:])
    sc = subprocess.run([sys.executable, probe, "score", zonemap, net_pt, robot_dir],
                        capture_output=True, text=True)
    own = json.loads(subprocess.run(
        [zonemap, "zones", "segment", os.path.join(robot_dir, name + "_map.png"), "--out",
         os.devnull, "--score", os.path.join(robot_dir, name + "_gt.png"), "--json"],
        capture_output=True, text=True, check=True).stdout)["score"]
    want = " / ".join(f"{100 * own[k]:.1f}" for k in ("precision", "recall", "mean_iou",
                                                      "mean_iou_shown"))
    check(sc.returncode == 0 and f"joined where cue < 0.0: {want}" in sc.stdout and
          "cue AUC among them" in sc.stdout,
          "image_cue_probe.py score: joining nothing gives zonemap's own figures (" + want + ")")
    bad = subprocess.run([sys.executable, probe, "train", net_pt, robot_dir, "--epochs", "0"],
                         capture_output=True, text=True)
    check(bad.returncode != 0 and "--epochs 0" in bad.stderr, "image_cue_probe.py: --epochs 0 "
          "is refused")

sys.exit(1 if failures else 0)
