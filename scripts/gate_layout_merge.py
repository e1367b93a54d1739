#!/usr/bin/python3
"""Joins two layout merge models into one that chooses between them by the map (issue 28).

The compiled-in layout merge model (lib/segment/layout_merge_model.inc) is one tree ensemble;
zonemap evaluates it the same way whatever it holds. This script writes one whose every tree
starts with the split `GATE_FEATURE <= GATE` on a map-level feature (computed by zonemap, the
same for every pair of a map): at or below it, the clean-plan model's tree; above it, the
robot-grid model's. So on a clean plan the joined model gives the clean model's probability and
on a robot-made grid the robot model's, to rounding, and no user flag chooses. The two initial
values become one more tree of two leaves. --robot-threshold T shifts the robot model's initial
value so that it merges at T while zonemap's threshold stays the default's 0.4.

The gate feature:
- `map_rough_face_share` (the default; issue 28's fifth to seventh rounds): the share of
  wall-face edges whose face does not continue straight. Both models must have been trained on
  pieces cut with the same options (their "trained_with" records equal).
- `map_rough_cut` with --gate 0.5 (eighth round): 1 when zonemap cut the map's pieces with the
  rough-grid options (CutOptions::layout_rough_*: a map whose grid's rough face share is above
  layout_rough_face_share), so each half only sees pieces cut as its training maps were. The
  records must then agree on every option but the layout_rough_* ones; the robot model's record,
  which says which grids are rough and how they are cut, becomes the joined model's, and it must
  let some grid be rough (layout_rough_face_share < 1).

Usage: scripts/gate_layout_merge.py CLEAN ROBOT --gate 0.3 [--gate-feature NAME]
           [--robot-threshold 0.4] [--json OUT.json] [--inc OUT.inc]
CLEAN and ROBOT are model JSON files or .inc files (as train_layout_merge.py writes them);
each lists a prefix of the feature names (train_layout_merge.FEATURES).
"""
import argparse
import json
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from train_layout_merge import FEATURES, write_inc  # noqa: E402

GATE_FEATURE = "map_rough_face_share"
ROUGH_CUT = "map_rough_cut"
ROUGH_OPTIONS = ("layout_rough_face_share", "layout_rough_corner_max_m", "layout_rough_cap_max_m")


def _without_rough(record):
    cut = {k: v for k, v in record["cut"].items() if k not in ROUGH_OPTIONS}
    return dict(record, cut=cut)


def load(path):
    text = open(path).read()
    if path.endswith(".inc"):
        text = "".join(re.findall(r'R"json\((.*?)\)json"', text, re.S))
    return json.loads(text)


def _leaf(value):
    return {"feature": [-1], "threshold": [0.0], "left": [-1], "right": [-1], "value": [value]}


def _scaled(tree, scale):
    return dict(tree, value=[v * scale for v in tree["value"]])


def _join(feature, gate, a, b):
    """One tree: x[feature] <= gate -> tree a, else tree b (children after their parent)."""
    na = len(a["feature"])

    def moved(t, off):
        return ([c + off if c >= 0 else -1 for c in t["left"]],
                [c + off if c >= 0 else -1 for c in t["right"]])

    al, ar = moved(a, 1)
    bl, br = moved(b, 1 + na)
    return {"feature": [feature] + a["feature"] + b["feature"],
            "threshold": [gate] + a["threshold"] + b["threshold"],
            "left": [1] + al + bl, "right": [1 + na] + ar + br,
            "value": [0.0] + a["value"] + b["value"]}


def gate_models(clean, robot, gate, robot_threshold=0.4, default_threshold=0.4,
                gate_feature=GATE_FEATURE):
    for m in (clean, robot):
        if m["features"] != FEATURES[: len(m["features"])]:
            raise ValueError("a model's features are not a prefix of FEATURES")
    if gate_feature not in FEATURES:
        raise ValueError(f"no feature '{gate_feature}' to gate on")
    if gate_feature == ROUGH_CUT:
        # Each half sees only pieces cut as its own training pieces were: the clean half the
        # maps cut with the clean options, the robot half those cut with the rough-grid ones.
        if _without_rough(clean["trained_with"]) != _without_rough(robot["trained_with"]):
            raise ValueError("the two models were trained on pieces cut with different options "
                             "(other than layout_rough_*)")
        if robot["trained_with"]["cut"].get("layout_rough_face_share", 1.0) >= 1.0:
            raise ValueError("the robot model was trained with layout_rough_face_share=1: no "
                             "grid is rough under it, so no map would reach it")
        if not 0.0 < gate < 1.0:
            raise ValueError("map_rough_cut is 0 or 1: gate it at a value between, e.g. 0.5")
    elif clean["trained_with"] != robot["trained_with"]:
        raise ValueError("the two models were trained on pieces cut with different options")
    feature = FEATURES.index(gate_feature)
    logit = lambda p: math.log(p / (1.0 - p))  # noqa: E731
    shift = logit(default_threshold) - logit(robot_threshold)
    trees = [_join(feature, gate, _leaf(clean["init"]), _leaf(robot["init"] + shift))]
    for i in range(max(len(clean["trees"]), len(robot["trees"]))):
        a = (_scaled(clean["trees"][i], clean["learning_rate"]) if i < len(clean["trees"])
             else _leaf(0.0))
        b = (_scaled(robot["trees"][i], robot["learning_rate"]) if i < len(robot["trees"])
             else _leaf(0.0))
        trees.append(_join(feature, gate, a, b))
    return {"features": FEATURES, "init": 0.0, "learning_rate": 1.0, "trees": trees,
            "trained_with": robot["trained_with"]}


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__)
    ap.add_argument("clean")
    ap.add_argument("robot")
    ap.add_argument("--gate", type=float, required=True)
    ap.add_argument("--gate-feature", default=GATE_FEATURE, metavar="NAME")
    ap.add_argument("--robot-threshold", type=float, default=0.4)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--inc", metavar="OUT.inc")
    a = ap.parse_args(argv)
    try:
        model = gate_models(load(a.clean), load(a.robot), a.gate, a.robot_threshold,
                            gate_feature=a.gate_feature)
    except ValueError as e:
        sys.exit(f"gate_layout_merge.py: {e}")
    text = json.dumps(model, separators=(",", ":"))
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    if a.inc:
        write_inc(a.inc, text)
    print(f"{len(model['trees'])} trees, gate {a.gate_feature} <= {a.gate}", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1:])
