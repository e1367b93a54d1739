#!/usr/bin/python3
"""Trains the layout merge model of `zonemap zones segment` (lib/segment/layout_merge.h, issue 16).

The features are computed by zonemap itself (`--merge-trace`), never here, so training and the
product share one definition of each. Training data, in two passes over every training map:
  1. oracle traces: pieces merged in the ground truth's order (`--merge-oracle`), every pair at
     every step written with its label (one GT room or not);
  2. the model fitted on those is run (`--merge-model`), and every pair at every step of its own
     merges is written with its label (one round of DAgger: the model learns from the states its
     own decisions lead to, not only the ones a perfect merge passes through); --dagger-passes N
     repeats it N times, each pass running the model fitted on every row so far (issue 28,
     ninth round: the merges are greedy, so a model meets states, such as two large chunks of
     one hall, that only a model's own earlier merges produce).
The model is scikit-learn's GradientBoostingClassifier (200 trees of depth 4, fixed seed) on
both, as the shipped model was trained; --learner hist fits HistGradientBoostingClassifier with
the same trees (learning rate 0.1, one thread: OMP_NUM_THREADS=1 is set here), which took a
minute per fit where the exact learner took half an hour on issue 28's 403 training maps on a
shared machine (issue 28's models and leave-one-out); it is written as JSON (--json) and as lib/segment/layout_merge_model.inc (--inc), which is
compiled in. --bag K makes the final fit K times on the same rows, each with the maps resampled
with replacement within their DIR (a stratified bootstrap, seeds 1..K, or S..S+K-1 with
--bag-seed S), and joins the K into one
model whose log-odds is the mean of theirs (the compiled-in format sums trees, so it holds a bag
as it holds one model; issue 28, seventh round: one fit's variance moved single maps' IoU by
points). The model records the options its pieces were cut with ("trained_with": the cut
and rule-merge options zonemap reports with --merge-trace), and zonemap refuses to merge pieces
cut with other options.

Usage: scripts/train_layout_merge.py ZONEMAP DIR [DIR ...] [--json OUT.json] [--inc OUT.inc]
           [--exclude NAME ...] [--threshold 0.4] [--dagger-threshold 0.6]
           [--weight DIR=W ...] [--loo DIR [--loo-models OUT_DIR]] [--param K=V ...]
           [--learner exact|hist] [--bag K] [--dagger-passes N] [--features N]
           [--drop NAME ...] [--bag-seed S] [--jobs N] [--trees N --depth D --rate R]
           [--row-weight pair|area_s|sqrt_area_s]
Each DIR holds <name>_map.png and <name>_gt.png (scripts/render_r2v.py's layout). --exclude
leaves maps out by name (leave-one-out figures). Each DIR has the same total weight, shared by
its maps, unless --weight gives it W times that. --loo DIR (DIR also among the training DIRs)
prints the leave-one-out table instead: each map of DIR scored by a model trained without it;
--loo-models keeps each of those models as OUT_DIR/<map>.json (to score them at another
threshold, or trace the left-out map with its own model, without training again).
--param K=V is passed to every `zones segment` run (SegmentOptions; the model records the
cutting options they give, and is refused with any other). The DAgger pass merges at --dagger-threshold (0.6, as
when the threshold was chosen); --loo scores at --threshold (the default's 0.4).
--features N trains on the first N features only, in FEATURES' order (all by default): 35 is
the shipped model's set, which predates the map-level features (issue 28's fifth and eighth
rounds), so the shipped recipe and its leave-one-out (the floor of issue 28's rounds) are
trained with --features 35.
--drop NAME (repeatable) trains without that feature, which need not be at the end: its column
is set to 0 in every row, so no tree splits on it, and the model still lists the first N names
(issue 28's twentieth round: the end extents without the eighteenth round's channel widths).
--trees N, --depth D, --rate R size the ensemble (200, 4, 0.1 by default, as every shipped
model; issue 28's twenty-eighth round probed 400 trees of depth 6 at 0.05).
--row-weight shares each map's weight among its rows equally ("pair", the default), by the
smaller piece's area ("area_s": the cells a wrong decision on the pair costs the area-weighted
precision and recall) or by its square root (twenty-eighth round's probes).
--jobs N runs N zonemap traces at once (the maps are independent), and N of --bag's K fits: the
same model, byte for byte, in less time on a machine with N cores to spare.
Needs python3-sklearn, python3-numpy (Debian); development only, not a build dependency.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before scikit-learn loads OpenMP: one core
import numpy as np  # noqa: E402
from sklearn.ensemble import GradientBoostingClassifier, HistGradientBoostingClassifier  # noqa

FEATURES = ["open_m", "wall_m", "open_fraction", "area_s", "area_l", "peak_s", "peak_l",
            "contact_clearance", "contact_over_peak_s", "contact_over_peak_l",
            "open_over_perimeter_s", "wall_over_perimeter_s", "open_perimeter_share_s",
            "open_over_extent_max_s", "open_over_extent_min_s", "rectangularity_s",
            "rectangularity_l", "rectangularity_union", "rectangularity_gain",
            "end_support_min", "end_support_max", "border_straightness_m",
            "elongation_s", "elongation_l", "elongation_union", "rule_same_segment",
            "rule_open_share", "map_free_m2", "map_rule_segment_m2", "doorway_share",
            "free_end_share", "corner_share", "mouth_share", "facade_share",
            "cap_share", "map_specks_per_100m2", "map_blobs_per_100m2",
            "map_loose_occupied_share", "map_rough_face_share", "map_unknown_border_share",
            "map_rough_cut", "channel_width_near", "channel_width_far",
            "end_extent_min_m", "end_extent_max_m", "visibility", "visibility_s"]


def maps(dirs, exclude):
    for d in dirs:
        for f in sorted(os.listdir(d)):
            if f.endswith("_map.png") and f[: -len("_map.png")] not in exclude:
                name = f[: -len("_map.png")]
                yield os.path.join(d, f), os.path.join(d, name + "_gt.png"), d


_TRACES = {}  # (map, options) -> rows: leave-one-out's folds share every oracle trace


def trace(zonemap, map_png, gt_png, csv, extra):
    """The map's pair rows and labels, and the options its pieces were cut with. Oracle traces
    (no model in extra) do not depend on the fold, so they are computed once per map."""
    key = (map_png, tuple(extra))
    if key in _TRACES:
        return _TRACES[key]
    result = _trace(zonemap, map_png, gt_png, csv, extra)
    if "--merge-model" not in extra:
        _TRACES[key] = result
    return result


def _trace(zonemap, map_png, gt_png, csv, extra):
    cmd = [zonemap, "zones", "segment", map_png, "--out", os.devnull, "--score", gt_png,
           "--merge-trace", csv, "--json"] + extra
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    trained_with = json.loads(out)["trained_with"]
    if os.path.getsize(csv) == 0:  # a map of one piece: no pair
        return np.zeros((0, len(FEATURES)), np.float32), np.zeros(0), trained_with
    rows = np.loadtxt(csv, delimiter=",", ndmin=2)
    os.remove(csv)  # one per map under --jobs: large maps' traces are megabytes
    x = rows[:, 2:2 + len(FEATURES)].astype(np.float32)
    x[:, DROPPED] = 0.0  # a constant column: no tree splits on it
    return x, rows[:, 1], trained_with


def collect(zonemap, pairs, tmp, extra, dir_weight):
    """Rows of every map, and weights that give each DIR the same total weight, shared equally
    by its maps (a large office map has a hundred times the pair rows of an apartment and would
    decide alone; a set of many apartments would drown a set of a few offices)."""
    per_dir = {}
    for _, _, d in pairs:
        per_dir[d] = per_dir.get(d, 0) + 1
    xs, ys, ws, owners, options = [], [], [], [], []

    def one(i):
        m, g, _ = pairs[i]
        return trace(zonemap, m, g, os.path.join(tmp, f"trace_{i}.csv"), extra)

    traces = run_all(one, range(len(pairs)))
    for i, (_, _, d) in enumerate(pairs):
        x, y, trained_with = traces[i]
        xs.append(x)
        ys.append(y)
        share = np.full(len(y), 1.0 / max(1, len(y)))  # the map's weight over its rows
        if ROW_WEIGHT != "pair" and len(y):
            # Each row by the area a wrong decision on it costs: the smaller piece's cells are
            # the recall a missed merge loses, and the precision a wrong one does.
            stake = x[:, FEATURES.index("area_s")].astype(np.float64)
            if ROW_WEIGHT == "sqrt_area_s":
                stake = np.sqrt(stake)
            if stake.sum() > 0:
                share = stake / stake.sum()
        ws.append(share * dir_weight.get(d, 1.0) / per_dir[d])
        owners.append(np.full(len(y), i))
        options.append(trained_with)
    assert all(o == options[0] for o in options), "maps cut with different options"
    return (np.concatenate(xs), np.concatenate(ys), np.concatenate(ws), options[0],
            np.concatenate(owners))


def bootstrap_counts(map_dirs, seed):
    """How often each map is drawn when the maps are resampled with replacement within their
    DIR (every DIR keeps its number of maps, so its share of the weight). The DIRs draw in the
    order of their absolute paths, so a seed gives the same sample however a path is spelled."""
    rng = np.random.default_rng(seed)
    counts = np.zeros(len(map_dirs))
    by_dir = {}
    for i, d in enumerate(map_dirs):
        by_dir.setdefault(os.path.abspath(d), []).append(i)
    for d in sorted(by_dir):
        for j in rng.integers(0, len(by_dir[d]), len(by_dir[d])):
            counts[by_dir[d][j]] += 1
    return counts


def bag_models(models):
    """One model whose log-odds is the mean of the models' (zonemap sums the trees)."""
    k = len(models)
    trees = [dict(t, value=[v * m["learning_rate"] / k for v in t["value"]])
             for m in models for t in m["trees"]]
    return {"features": models[0]["features"], "init": float(np.mean([m["init"] for m in models])),
            "learning_rate": 1.0, "trees": trees, "trained_with": models[0]["trained_with"]}


def check_bag(model, clfs, x_check):
    # The joined model must give the mean of the learners' own log-odds.
    want = np.mean([c.decision_function(x_check) for c in clfs], axis=0)
    assert np.allclose(log_odds(model, x_check), want, atol=1e-6), "bag mismatch"


LEARNER = "exact"  # --learner
JOBS = 1  # --jobs
DROPPED = []  # --drop: column indices set to 0
BAG_SEED = 1  # --bag-seed: the first bootstrap seed of --bag
TREES, DEPTH, RATE = 200, 4, 0.1  # --trees, --depth, --rate
ROW_WEIGHT = "pair"  # --row-weight


def run_all(fn, items):
    """[fn(i) for i in items], JOBS at a time: the items are independent (zonemap runs, or fits
    that build their trees without the GIL) and the results come back in the items' order, so
    what is made of them does not depend on JOBS."""
    if JOBS == 1:
        return [fn(i) for i in items]
    with ThreadPoolExecutor(max_workers=JOBS) as pool:
        return list(pool.map(fn, items))


def fit(x, y, w):
    w = w * len(w) / w.sum()
    if LEARNER == "hist":
        return HistGradientBoostingClassifier(max_iter=TREES, max_depth=DEPTH, learning_rate=RATE,
                                              early_stopping=False, random_state=0).fit(
            x, y, sample_weight=w)
    return GradientBoostingClassifier(n_estimators=TREES, max_depth=DEPTH, learning_rate=RATE,
                                      random_state=0).fit(
        x, y, sample_weight=w)


def export(clf, x_check, trained_with):
    if isinstance(clf, HistGradientBoostingClassifier):
        return export_hist(clf, x_check, trained_with)
    prior = clf.init_.class_prior_[1]
    model = {"features": FEATURES, "init": float(np.log(prior / (1.0 - prior))),
             "learning_rate": float(clf.learning_rate), "trees": []}
    for est in clf.estimators_[:, 0]:
        t = est.tree_
        leaf = t.children_left < 0
        model["trees"].append({
            "feature": [int(-1 if leaf[i] else t.feature[i]) for i in range(t.node_count)],
            "threshold": [float(v) for v in t.threshold],
            "left": [int(v) for v in t.children_left],
            "right": [int(v) for v in t.children_right],
            "value": [float(v) for v in t.value[:, 0, 0]]})
    return check_export(model, clf, x_check, trained_with)


def export_hist(clf, x_check, trained_with):
    # The trees' leaf values already hold the learning rate: the model's rate is 1.
    model = {"features": FEATURES, "init": float(np.ravel(clf._baseline_prediction)[0]),
             "learning_rate": 1.0, "trees": []}
    for (predictor,) in clf._predictors:
        nodes = predictor.nodes
        leaf = nodes["is_leaf"].astype(bool)
        model["trees"].append({
            "feature": [int(-1 if leaf[i] else nodes["feature_idx"][i]) for i in range(len(nodes))],
            "threshold": [float(0.0 if leaf[i] else nodes["num_threshold"][i])
                          for i in range(len(nodes))],
            "left": [int(-1 if leaf[i] else nodes["left"][i]) for i in range(len(nodes))],
            "right": [int(-1 if leaf[i] else nodes["right"][i]) for i in range(len(nodes))],
            "value": [float(v) for v in nodes["value"]]})
    return check_export(model, clf, x_check, trained_with)


def log_odds(model, x):
    """The exported model's log-odds for each row of x, evaluated as zonemap evaluates it."""
    raw = np.full(len(x), model["init"])
    for tree in model["trees"]:
        for i, row in enumerate(x):
            n = 0
            while tree["feature"][n] >= 0:
                n = tree["left"][n] if float(row[tree["feature"][n]]) <= tree["threshold"][n] \
                    else tree["right"][n]
            raw[i] += model["learning_rate"] * tree["value"][n]
    return raw


def check_export(model, clf, x_check, trained_with):
    # The exported form must give scikit-learn's own answer (zonemap evaluates it the same way).
    assert np.allclose(log_odds(model, x_check), clf.decision_function(x_check), atol=1e-6), \
        "export mismatch"
    model["trained_with"] = trained_with  # last, so a record alone changes only the last line
    return model


def train(zonemap, pairs, dir_weight, dagger_threshold, params, bag=0, passes=1):
    with tempfile.TemporaryDirectory() as tmp:
        x1, y1, w1, trained_with, o1 = collect(zonemap, pairs, tmp, ["--merge-oracle"] + params,
                                           dir_weight)
        x, y, w, owner = x1, y1, w1, o1
        # DAgger: each pass runs the model fitted on every row so far and adds the rows of the
        # states its own merges lead to (each pass with the same weight per DIR as the oracle's).
        for _ in range(passes):
            model_json = os.path.join(tmp, "dagger.json")
            with open(model_json, "w") as f:
                json.dump(export(fit(x, y, w), x[:200], trained_with), f)
            x2, y2, w2, _, o2 = collect(zonemap, pairs, tmp, [
                "--merge-model", model_json, "--param",
                f"layout_merge_threshold={dagger_threshold}"] + params, dir_weight)
            x, y = np.concatenate([x, x2]), np.concatenate([y, y2])
            w, owner = np.concatenate([w, w2]), np.concatenate([owner, o2])
        if not bag:
            return export(fit(x, y, w), x[:200], trained_with), len(y1), len(y) - len(y1), y.mean()
        seeds = range(BAG_SEED, BAG_SEED + bag)
        clfs = run_all(lambda s: fit(x, y, w * bootstrap_counts([d for _, _, d in pairs],
                                                                s)[owner]), seeds)
        model = bag_models([export(c, x[:200], trained_with) for c in clfs])
        check_bag(model, clfs, x[:50])
        return model, len(y1), len(y) - len(y1), y.mean()


def leave_one_out(zonemap, dirs, loo_dir, dir_weight, threshold, dagger_threshold, params,
                  keep=None, bag=0, passes=1):
    """For each map of loo_dir (which is also a training DIR): train without it, score it."""
    print("| map | precision % | recall % | mean IoU % | segments |")
    print("|---|---:|---:|---:|---:|")
    scores = []
    for m, g, _ in maps([loo_dir], set()):
        name = os.path.basename(m)[: -len("_map.png")]
        model, _, _, _ = train(zonemap, list(maps(dirs, {name})), dir_weight, dagger_threshold,
                               params, bag, passes)
        with tempfile.TemporaryDirectory() as tmp:
            # The fold's model is written once: where --loo-models keeps it, else a scratch file.
            if keep:
                os.makedirs(keep, exist_ok=True)
            path = os.path.join(keep or tmp, (name if keep else "model") + ".json")
            with open(path, "w") as f:
                f.write(json.dumps(model, separators=(",", ":")) + "\n")
            out = subprocess.run([zonemap, "zones", "segment", m, "--out", os.devnull, "--score",
                                  g, "--json", "--merge-model", path, "--param",
                                  f"layout_merge_threshold={threshold}"] + params,
                                 check=True, capture_output=True, text=True).stdout
        s = json.loads(out)["score"]
        scores.append([s["precision"], s["recall"], s["mean_iou"]])
        print(f"| {name} | {100 * s['precision']:.1f} | {100 * s['recall']:.1f} | "
              f"{100 * s['mean_iou']:.1f} | {s['segments']} |", flush=True)
    mean = 100 * np.mean(scores, axis=0)
    print(f"| **mean** | **{mean[0]:.1f}** | **{mean[1]:.1f}** | **{mean[2]:.1f}** | |")


def write_inc(path, text):
    """The model's JSON text as lib/segment/layout_merge_model.inc (compiled in)."""
    with open(path, "w") as f:
        f.write("// Generated by scripts/" + os.path.basename(sys.argv[0]) + ": do not edit.\n")
        # Raw string pieces stay under compilers' literal length limits.
        for k in range(0, len(text), 4000):
            f.write('R"json(' + text[k:k + 4000] + ')json"\n')


def main(argv):
    global LEARNER, FEATURES, JOBS, DROPPED, BAG_SEED, TREES, DEPTH, RATE, ROW_WEIGHT
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__)
    ap.add_argument("zonemap")
    ap.add_argument("dirs", nargs="+", metavar="DIR")
    ap.add_argument("--exclude", action="append", default=[], metavar="NAME")
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--inc", metavar="OUT.inc")
    ap.add_argument("--threshold", type=float, default=0.4)
    ap.add_argument("--dagger-threshold", type=float, default=0.6)
    ap.add_argument("--weight", action="append", default=[], metavar="DIR=W")
    ap.add_argument("--loo", metavar="DIR")
    ap.add_argument("--loo-models", metavar="OUT_DIR")
    ap.add_argument("--param", action="append", default=[], metavar="K=V")
    ap.add_argument("--learner", choices=["exact", "hist"], default="exact")
    ap.add_argument("--bag", type=int, default=0, metavar="K")
    ap.add_argument("--bag-seed", type=int, default=1, metavar="S")
    ap.add_argument("--dagger-passes", type=int, default=1, metavar="N")
    ap.add_argument("--features", type=int, default=len(FEATURES), metavar="N")
    ap.add_argument("--drop", action="append", default=[], metavar="NAME")
    ap.add_argument("--jobs", type=int, default=1, metavar="N")
    ap.add_argument("--trees", type=int, default=200, metavar="N")
    ap.add_argument("--depth", type=int, default=4, metavar="D")
    ap.add_argument("--rate", type=float, default=0.1, metavar="R")
    ap.add_argument("--row-weight", choices=["pair", "area_s", "sqrt_area_s"], default="pair")
    a = ap.parse_args(argv)
    if a.jobs < 1:
        ap.error(f"--jobs {a.jobs}: at least 1")
    if a.dagger_passes < 1:
        ap.error(f"--dagger-passes {a.dagger_passes}: at least 1")
    if not 1 <= a.features <= len(FEATURES):
        ap.error(f"--features {a.features}: from 1 to {len(FEATURES)}, the features zonemap "
                 "writes")
    if a.bag_seed < 1:
        ap.error(f"--bag-seed {a.bag_seed}: at least 1")
    if a.trees < 1 or a.depth < 1 or not 0.0 < a.rate <= 1.0:
        ap.error(f"--trees {a.trees} --depth {a.depth} --rate {a.rate}: at least 1 tree of "
                 "depth 1, a rate in (0, 1]")
    LEARNER, JOBS, BAG_SEED = a.learner, a.jobs, a.bag_seed
    TREES, DEPTH, RATE, ROW_WEIGHT = a.trees, a.depth, a.rate, a.row_weight
    FEATURES = FEATURES[:a.features]
    for name in a.drop:
        if name not in FEATURES:
            ap.error(f"--drop {name}: not one of the {len(FEATURES)} features trained on")
    DROPPED = [FEATURES.index(name) for name in a.drop]
    params = [x for p in a.param for x in ("--param", p)]
    exclude, out_json, out_inc, threshold, loo_dir = set(a.exclude), a.json, a.inc, a.threshold, a.loo
    dir_weight = {d: float(w) for d, w in (x.rsplit("=", 1) for x in a.weight)}
    zonemap, dirs = a.zonemap, a.dirs
    if loo_dir:
        return leave_one_out(zonemap, dirs, loo_dir, dir_weight, threshold, a.dagger_threshold,
                             params, a.loo_models, a.bag, a.dagger_passes)
    pairs = list(maps(dirs, exclude))
    model, n1, n2, share = train(zonemap, pairs, dir_weight, a.dagger_threshold, params, a.bag,
                                 a.dagger_passes)
    print(f"{len(pairs)} maps, {n1} oracle + {n2} model-driven pair rows, "
          f"{100 * share:.0f} % one room", file=sys.stderr)
    text = json.dumps(model, separators=(",", ":"))
    if out_json:
        with open(out_json, "w") as f:
            f.write(text + "\n")
    if out_inc:
        write_inc(out_inc, text)


if __name__ == "__main__":
    main(sys.argv[1:])
