#!/usr/bin/python3
"""Joins two layout merge models into one that chooses between them by the map (issue 28).

The compiled-in layout merge model (lib/segment/layout_merge_model.inc) is one tree ensemble;
zonemap evaluates it the same way whatever it holds. This script writes one whose every tree
starts with the split `map_rough_face_share <= GATE` (a map-level feature, computed by zonemap
from the grid: the share of wall-face edges whose face does not continue straight): at or
below it, the clean-plan model's tree; above it, the robot-grid model's. So on a clean plan the
joined model gives the clean model's probability and on a robot-made grid the robot model's,
to rounding, and no user flag chooses. Both models must have been trained on pieces cut with
the same options (their "trained_with" records must be equal; zonemap checks the joined
model's record as any other's). The two initial values become one more tree of two leaves.
--robot-threshold T shifts the robot model's initial value so that it merges at T while
zonemap's threshold stays the default's 0.4 (not used by the shipped model: T = 0.4).

Usage: scripts/gate_layout_merge.py CLEAN ROBOT --gate 0.3 [--robot-threshold 0.4]
           [--json OUT.json] [--inc OUT.inc]
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


def gate_models(clean, robot, gate, robot_threshold=0.4, default_threshold=0.4):
    for m in (clean, robot):
        if m["features"] != FEATURES[: len(m["features"])]:
            raise ValueError("a model's features are not a prefix of FEATURES")
    if clean["trained_with"] != robot["trained_with"]:
        raise ValueError("the two models were trained on pieces cut with different options")
    feature = FEATURES.index(GATE_FEATURE)
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
    ap.add_argument("--robot-threshold", type=float, default=0.4)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--inc", metavar="OUT.inc")
    a = ap.parse_args(argv)
    model = gate_models(load(a.clean), load(a.robot), a.gate, a.robot_threshold)
    text = json.dumps(model, separators=(",", ":"))
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    if a.inc:
        write_inc(a.inc, text)
    print(f"{len(model['trees'])} trees, gate {GATE_FEATURE} <= {a.gate}", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1:])
