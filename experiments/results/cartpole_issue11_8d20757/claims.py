#!/usr/bin/python3
"""Issue 11 part 1's per-seed conditions for a sweep folder: claims.py FOLDER prints, per seed, the evaluations
(agent step, return) below 850 after the seed first reached 880, and those more than 10 below the better of
its policy alone and planner alone (agent step, return, better component). Step 0 is skipped."""
import csv
import glob
import os
import sys

TAGS = ("eval/return_mean", "eval/policy_return_mean", "eval/planner_return_mean")
runs = glob.glob(os.path.join(sys.argv[1], "cartpole_swingup/hybrid-stochastic/seed*"))
for run in sorted((r for r in runs if os.path.isdir(r)), key=lambda p: int(p.split("seed")[-1])):
    v = {}
    for r in csv.DictReader(open(os.path.join(run, "scalars.csv"))):
        if r["tag"] in TAGS:
            v.setdefault(int(r["step"]), {})[r["tag"].split("/")[1]] = float(r["value"])
    reached, drops, below = False, [], []
    for st in sorted(v):
        h = v[st].get("return_mean")
        if h is None or st == 0:
            continue
        if reached and h < 850:
            drops.append((st // 4, round(h, 1)))
        reached = reached or h >= 880
        best = max(v[st].get("policy_return_mean", -1e9), v[st].get("planner_return_mean", -1e9))
        if h < best - 10:
            below.append((st // 4, round(h, 1), round(best, 1)))
    print(os.path.basename(run), "drops", drops, "below", below)
