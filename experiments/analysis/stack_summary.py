#!/usr/bin/env python3
"""Block-stacking imitation results of a sweep's results tree, per demonstration count: successes of the
extra test episodes summed over seeds, and the mean (over seeds) of their mean return, for each method;
the policy alone and the expert's test episodes for scale. Then every seed's successes per count, the test
steps where the hybrid fell back to its policy, and the successes of each eval.variants evaluation
(imitation/variant<i>_success_rate) if the runs made any.

  experiments/analysis/stack_summary.py experiments/results/stack_imitation_984e781
"""
import csv
import glob
import os
import re
import sys

if len(sys.argv) != 2:
    sys.exit(__doc__)
root = sys.argv[1]
variant_tag = re.compile(r"imitation/(variant\d+)_success_rate$")
for method in ("bc", "hybrid-imitation"):
    rate, ret, pol, expert = {}, {}, {}, {}
    per_seed = []  # (seed name, {count: successes}, fallbacks, {variant: {count: successes}})
    paths = sorted(glob.glob(os.path.join(root, "block_stack", method, "seed*", "scalars.csv")),
                   key=lambda p: int(re.sub(r"\D", "", os.path.basename(os.path.dirname(p))) or 0))
    for path in paths:
        mine, fallbacks, variants = {}, 0.0, {}
        for row in csv.DictReader(open(path)):
            k, tag, v = int(row["step"]), row["tag"], float(row["value"])
            for name, d in (("imitation/eval_success_rate", rate), ("imitation/eval_return_mean", ret),
                            ("imitation/policy_return", pol), ("imitation/expert_return", expert)):
                if tag == name:
                    d.setdefault(k, []).append(v)
            if tag == "imitation/eval_success_rate":
                mine[k] = round(10 * v)
            elif tag == "imitation/fallbacks":
                fallbacks += v
            else:
                match = variant_tag.match(tag)
                if match:
                    variants.setdefault(match.group(1), {})[k] = round(10 * v)
        per_seed.append((os.path.basename(os.path.dirname(path)), mine, fallbacks, variants))
    if not paths:
        continue
    n = len(paths)
    print(f"{method}: demonstrations | successes of {10 * n} (10 per seed) | mean test return | policy alone | expert")
    mean = lambda xs: sum(xs) / len(xs)
    for k in sorted(rate):
        print(f"  {k:2d} | {round(10 * sum(rate[k]))} (per seed {' '.join(str(round(10 * x)) for x in rate[k])}) | "
              f"{mean(ret[k]):.1f} | {mean(pol[k]):.1f} | {mean(expert[k]):.1f}")
    row = lambda d: " ".join(f"{d[k]:2d}" for k in sorted(d)) + f" = {sum(d.values())}"
    print(f"  per seed, successes of 10 at each count = their sum:")
    totals = {}
    for seed, mine, fallbacks, variants in per_seed:
        print(f"    {seed:7s} {row(mine)} (fallback steps {int(fallbacks)})")
        for name in sorted(variants):
            print(f"      {name} {row(variants[name])}")
            totals[name] = totals.get(name, 0) + sum(variants[name].values())
    print(f"  in all: {sum(sum(m.values()) for _, m, _, _ in per_seed)} of {100 * n}" +
          "".join(f"; {name} {t}" for name, t in sorted(totals.items())))
