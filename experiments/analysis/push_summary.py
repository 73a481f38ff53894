#!/usr/bin/env python3
"""Per-run summary of a block-pushing sweep (experiments/sweeps/push*.yaml): for every RUN/scalars.csv under
the given folders, the successful training episodes (train/success), the mean training return of the first
and last five episodes, the evaluation successes and returns, and where logged the dynamics model's
one-step error against "no change" at each evaluation (eval/model_error_ratio); then per method the seeds
with a success within the first 20 training episodes (the issue's criterion) and in all 30.

  experiments/analysis/push_summary.py results/block_push [results/block_push_camera ...]
"""
import csv
import math
import os
import sys
from collections import defaultdict


def read(path):
    tags = defaultdict(list)
    with open(path) as f:
        for row in csv.DictReader(f):
            tags[row["tag"]].append(float(row["value"]))
    return tags


def mean(xs):
    return sum(xs) / len(xs) if xs else math.nan


def main(folders):
    if not folders:
        sys.exit(__doc__)
    by_method = defaultdict(list)  # (env, method) -> [(seed, successes in 20, in all, episodes)]
    for folder in folders:
        for root, _, files in sorted(os.walk(folder)):
            if "scalars.csv" not in files:
                continue
            t = read(os.path.join(root, "scalars.csv"))
            succ = [int(v) for v in t["train/success"]]
            ret = t["train/episode_return"]
            at = [i + 1 for i, s in enumerate(succ) if s]
            line = (f"{os.path.relpath(root, folder)}: train successes {sum(succ)}/{len(succ)} at episodes {at}; "
                    f"ret first5 {mean(ret[:5]):.0f} last5 {mean(ret[-5:]):.0f}; eval succ "
                    + " ".join(f"{v:g}" for v in t["eval/success_rate"])
                    + "; eval ret " + " ".join(f"{v:.0f}" for v in t["eval/return_mean"]))
            if t["eval/model_error_ratio"]:
                line += "; model error/no-change " + " ".join(f"{v:.2f}" for v in t["eval/model_error_ratio"])
            print(line)
            parts = os.path.normpath(root).split(os.sep)
            by_method[(parts[-3], parts[-2])].append(
                (parts[-1], sum(1 for e in at if e <= 20), len(at), len(succ)))
    for (env, method), runs in sorted(by_method.items()):
        within = sum(1 for _, n20, _, _ in runs if n20 > 0)
        total = sum(n for _, _, n, _ in runs)
        episodes = sum(e for _, _, _, e in runs)
        print(f"{env} {method}: {within} of {len(runs)} seeds succeed within 20 episodes; "
              f"{total} successful training episodes of {episodes}")


if __name__ == "__main__":
    main(sys.argv[1:])
