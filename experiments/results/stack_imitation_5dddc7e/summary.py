#!/usr/bin/env python3
"""Per demonstration count: successes of the 10 extra test episodes summed over seeds 0-4, and the mean
(over seeds) of their mean return, for each method of this folder; the expert's test episodes for scale."""
import csv
import glob
import os

here = os.path.dirname(os.path.abspath(__file__))
for method in ("bc", "hybrid-imitation"):
    rate, ret, pol, expert = {}, {}, {}, {}
    for path in sorted(glob.glob(os.path.join(here, "block_stack", method, "seed*", "scalars.csv"))):
        for row in csv.DictReader(open(path)):
            k, tag, v = int(row["step"]), row["tag"], float(row["value"])
            for name, d in (("imitation/eval_success_rate", rate), ("imitation/eval_return_mean", ret),
                            ("imitation/policy_return", pol), ("imitation/expert_return", expert)):
                if tag == name:
                    d.setdefault(k, []).append(v)
    print(f"{method}: demonstrations | successes of 50 (10 per seed) | mean test return | policy alone | expert")
    for k in sorted(rate):
        mean = lambda xs: sum(xs) / len(xs)
        print(f"  {k:2d} | {round(10 * sum(rate[k]))} (per seed {' '.join(str(round(10 * x)) for x in rate[k])}) | "
              f"{mean(ret[k]):.1f} | {mean(pol[k]):.1f} | {mean(expert[k]):.1f}")
