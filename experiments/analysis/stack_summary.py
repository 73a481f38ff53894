#!/usr/bin/env python3
"""Block-stacking imitation results of a sweep's results tree, per demonstration count: successes of the
extra test episodes summed over seeds, and the mean (over seeds) of their mean return, for each method;
the policy alone and the expert's test episodes for scale.

  experiments/analysis/stack_summary.py experiments/results/stack_imitation_984e781
"""
import csv
import glob
import os
import sys

if len(sys.argv) != 2:
    sys.exit(__doc__)
root = sys.argv[1]
for method in ("bc", "hybrid-imitation"):
    rate, ret, pol, expert = {}, {}, {}, {}
    paths = sorted(glob.glob(os.path.join(root, "block_stack", method, "seed*", "scalars.csv")))
    for path in paths:
        for row in csv.DictReader(open(path)):
            k, tag, v = int(row["step"]), row["tag"], float(row["value"])
            for name, d in (("imitation/eval_success_rate", rate), ("imitation/eval_return_mean", ret),
                            ("imitation/policy_return", pol), ("imitation/expert_return", expert)):
                if tag == name:
                    d.setdefault(k, []).append(v)
    if not paths:
        continue
    n = len(paths)
    print(f"{method}: demonstrations | successes of {10 * n} (10 per seed) | mean test return | policy alone | expert")
    mean = lambda xs: sum(xs) / len(xs)
    for k in sorted(rate):
        print(f"  {k:2d} | {round(10 * sum(rate[k]))} (per seed {' '.join(str(round(10 * x)) for x in rate[k])}) | "
              f"{mean(ret[k]):.1f} | {mean(pol[k]):.1f} | {mean(expert[k]):.1f}")
