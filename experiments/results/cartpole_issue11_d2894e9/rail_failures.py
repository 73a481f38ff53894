"""What the episodes of an hlt_rollout --csv/--predictions pair did at the end of the cart's rail.
Per episode: the return, the agent step from which the pole stays within 0.6 rad of upright (the catch), and
the steps at which the cart was at the rail (|x| >= 0.97) with the pole's angle there. Over all steps: the
share of the models' squared one-step error that falls on transitions at the rail.
Usage: rail_failures.py EP.csv PRED.csv"""
import csv
import math
import sys
from collections import defaultdict

ep = list(csv.DictReader(open(sys.argv[1])))
pr = list(csv.DictReader(open(sys.argv[2])))
episodes = defaultdict(list)
for i, row in enumerate(ep):
    episodes[row["episode"]].append(i)
tot, rail, n, nr = [0.0] * 5, [0.0] * 5, 0, 0
for e, idx in episodes.items():
    rows = [ep[i] for i in idx]
    ret = sum(float(r["reward"]) for r in rows)
    th = [math.atan2(float(r["obs_3"]), float(r["obs_2"])) for r in rows]
    catch = next((t for t in range(len(rows)) if all(abs(a) < 0.6 for a in th[t:])), None)
    hits = [f"{t}:{th[t]:+.1f}" for t, r in enumerate(rows) if abs(float(r["obs_0"])) >= 0.97]
    print(f"episode {e}: return {ret:.1f}, caught at step {catch}, at the rail (step:angle) {' '.join(hits)}")
    for i in idx[:-1]:
        nx = [float(ep[i + 1][f"obs_{k}"]) for k in range(5)]
        p = [float(pr[i][f"pred_obs_{k}"]) for k in range(5)]
        err = [(a - b) ** 2 for a, b in zip(nx, p)]
        n += 1
        tot = [t + v for t, v in zip(tot, err)]
        if abs(float(ep[i]["obs_0"])) >= 0.97 or abs(nx[0]) >= 0.97:
            nr += 1
            rail = [t + v for t, v in zip(rail, err)]
print(f"transitions at the rail: {nr} of {n} ({100 * nr / max(n, 1):.1f} %); their share of the squared one-step "
      f"error per component (x, x', cos, sin, theta'): {' '.join(f'{r / t:.2f}' for r, t in zip(rail, tot))}")
