#!/usr/bin/env python3
"""Does a run's dynamics model predict the block's motion when the tool pushes it? Reads an hlt_rollout
trajectory of block_push (--csv) and the same rollout's model predictions (--models CHECKPOINT --predictions),
and compares the block's displacement per step, the environment's against the model's, on the steps where
the block moved (contact) and on the others. The block's displacement is minus the change of the
observation's block -> target (dx, dy); the last step of each episode has no next observation and is skipped.

  build/experiments/hlt_rollout --env block_push --policy random --episodes 20 --seed 0 --csv traj.csv \\
      --models RUN/final.pt --predictions pred.csv
  experiments/analysis/push_contact_model.py traj.csv pred.csv
"""
import csv
import math
import sys

if len(sys.argv) != 3:
    sys.exit(__doc__)
traj = list(csv.DictReader(open(sys.argv[1])))
pred = list(csv.DictReader(open(sys.argv[2])))
if len(traj) != len(pred):
    sys.exit(f"{sys.argv[1]} has {len(traj)} rows, {sys.argv[2]} {len(pred)}: not the same rollout")

moved, still = [], []  # (actual displacement (dx, dy), predicted displacement, tool-block distance)
for i in range(len(traj) - 1):
    now, nxt, p = traj[i], traj[i + 1], pred[i]
    if now["episode"] != nxt["episode"] or (now["episode"], now["step"]) != (p["episode"], p["step"]):
        continue
    o = [float(now[f"obs_{k}"]) for k in range(6)]
    o1 = [float(nxt[f"obs_{k}"]) for k in range(6)]
    po = [float(p[f"pred_obs_{k}"]) for k in range(6)]
    actual = (-(o1[3] - o[3]), -(o1[4] - o[4]))
    predicted = (-(po[3] - o[3]), -(po[4] - o[4]))
    row = (actual, predicted, math.hypot(o[0], o[1]))
    (moved if math.hypot(*actual) > 0.001 else still).append(row)

norm = lambda v: math.hypot(*v)
mean = lambda xs: sum(xs) / len(xs) if xs else float("nan")
for name, rows in (("block moved (> 1 mm)", moved), ("block still", still)):
    if not rows:
        print(f"{name}: no steps")
        continue
    a = [norm(r[0]) for r in rows]
    p = [norm(r[1]) for r in rows]
    err = [norm((r[0][0] - r[1][0], r[0][1] - r[1][1])) for r in rows]
    # The predicted displacement along the actual one (1: the model moves the block as the environment did).
    along = [(r[0][0] * r[1][0] + r[0][1] * r[1][1]) / norm(r[0]) ** 2 for r in rows if norm(r[0]) > 0.001]
    print(f"{name}: {len(rows)} steps, tool-block distance {mean([r[2] for r in rows]):.3f} m; displacement "
          f"per step, environment {1000 * mean(a):.1f} mm, model {1000 * mean(p):.1f} mm, error "
          f"{1000 * mean(err):.1f} mm" + (f"; model's along the environment's {mean(along):.2f}" if along else ""))
