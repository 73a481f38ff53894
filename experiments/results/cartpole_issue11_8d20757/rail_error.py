#!/usr/bin/python3
"""The learned dynamics model's one-step error along episodes, at the end of the cart-pole's rail and away
from it: rail_error.py EPISODES.csv PREDICTIONS.csv (hlt_rollout --csv and --predictions of one run)."""
import csv
import sys

import numpy as np

ep = list(csv.DictReader(open(sys.argv[1])))
pr = list(csv.DictReader(open(sys.argv[2])))
rows = []
for i in range(len(ep) - 1):
    if ep[i]["episode"] != ep[i + 1]["episode"]:
        continue
    s = np.array([float(ep[i]["obs_%d" % j]) for j in range(5)])
    s1 = np.array([float(ep[i + 1]["obs_%d" % j]) for j in range(5)])
    p = np.array([float(pr[i]["pred_obs_%d" % j]) for j in range(5)])
    rows.append((s, s1, p))


def summary(sel, name):
    if not sel:
        print(name, "none")
        return
    e = np.array([r[1] - r[2] for r in sel])
    d = np.array([r[1] - r[0] for r in sel])
    print("%-30s n=%4d  RMS error [x, xd, cos, sin, thetad] %s  RMS true change %s"
          % (name, len(sel), np.sqrt((e ** 2).mean(0)).round(3), np.sqrt((d ** 2).mean(0)).round(3)))


at_rail = lambda r: abs(r[0][0]) >= 0.99 or abs(r[1][0]) >= 0.99
summary(rows, "all steps")
summary([r for r in rows if abs(r[0][0]) < 0.9 and abs(r[1][0]) < 0.9], "|x| < 0.9")
summary([r for r in rows if at_rail(r)], "at the rail (|x| >= 0.99)")
summary([r for r in rows if at_rail(r) and r[0][2] > 0.9], "at the rail, pole up")
