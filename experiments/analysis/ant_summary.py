#!/usr/bin/env python3
"""Ant imitation results (paper Fig. 5) of a sweep's results tree, per demonstration count: for behaviour
cloning and hybrid imitation the mean +- std over seeds of the mean return of the count's test episodes
(imitation/eval_return_mean), of the one logged test episode and of the policy alone; the expert's return
from the same start states; each method as a fraction of the expert; the hybrid minus behaviour cloning
seed by seed; the eval.variants evaluations of the same networks (imitation/variant<i>_return_mean) where
the runs made any; then every seed's mean test return per count.

  experiments/analysis/ant_summary.py experiments/results/ant_imitation_eb11271
"""
import csv
import glob
import os
import re
import statistics
import sys

if len(sys.argv) != 2:
    sys.exit(__doc__)
root = sys.argv[1]
METHODS = ("bc", "hybrid-imitation")
TAGS = {"eval": "imitation/eval_return_mean", "test": "imitation/test_return",
        "policy": "imitation/policy_return", "expert": "imitation/expert_return"}


def seed_of(path):
    return int(re.sub(r"\D", "", os.path.basename(os.path.dirname(path))))


def read(path):
    """{name: {count: value}} of one run, counts from imitation/demonstrations."""
    rows = list(csv.DictReader(open(path)))
    count = {int(r["step"]): int(float(r["value"])) for r in rows if r["tag"] == "imitation/demonstrations"}
    out = {name: {} for name in TAGS}
    for r in rows:
        if int(r["step"]) not in count:
            continue
        for name, tag in TAGS.items():
            if r["tag"] == tag:
                out[name][count[int(r["step"])]] = float(r["value"])
        match = re.fullmatch(r"imitation/(variant\d+)_return_mean", r["tag"])
        if match:
            out.setdefault(match.group(1), {})[count[int(r["step"])]] = float(r["value"])
    return out


runs = {m: {seed_of(p): read(p) for p in glob.glob(os.path.join(root, "ant", m, "seed*", "scalars.csv"))}
        for m in METHODS}
variants = {m: sorted({k for run in runs[m].values() for k in run if k.startswith("variant")}) for m in METHODS}
counts = sorted({c for m in METHODS for run in runs[m].values() for c in run["eval"]})
if not counts:
    sys.exit(f"no imitation/eval_return_mean under {root}/ant")


def stats(values):
    return (statistics.mean(values), statistics.stdev(values) if len(values) > 1 else 0.0) if values else None


def cell(s, fmt="{:.0f} +- {:.0f}"):
    return fmt.format(*s) if s else ""


# The expert runs from each seed's test start state, which both methods share: one value per seed.
expert_seed = {}
for m in METHODS:
    for seed, run in runs[m].items():
        for c, v in run["expert"].items():
            expert_seed.setdefault((seed, c), v)
expert = {c: stats([v for (s, k), v in expert_seed.items() if k == c]) for c in counts}
print(f"{root}: seeds {sorted(set(s for m in METHODS for s in runs[m]))}, counts {counts[0]}-{counts[-1]}")
print("\nmean +- std over seeds, per demonstration count")
print("| | " + " | ".join(str(c) for c in counts) + " |")
print("|---|" + "---|" * len(counts))
print("| expert (same start states) | " + " | ".join(cell(expert[c]) for c in counts) + " |")
for m in METHODS:
    if not runs[m]:
        continue
    for name, label in (("eval", "mean of the test episodes"), ("test", "the logged test episode"),
                        ("policy", "policy alone, one episode")):
        if m == "bc" and name == "policy":
            continue  # behaviour cloning's test episode is its policy
        row = [stats([run[name][c] for run in runs[m].values() if c in run[name]]) for c in counts]
        print(f"| {m}, {label} ({len(runs[m])} seeds) | " + " | ".join(cell(s) for s in row) + " |")
    for v in variants[m]:
        row = [stats([run[v][c] for run in runs[m].values() if c in run.get(v, {})]) for c in counts]
        print(f"| {m}, {v} (eval.variants, same networks) | " + " | ".join(cell(s) for s in row) + " |")
    frac = [[run["eval"][c] / expert_seed[(s, c)] for s, run in runs[m].items()
             if c in run["eval"] and (s, c) in expert_seed] for c in counts]
    print(f"| {m}, mean test return / expert | " +
          " | ".join(f"{100 * statistics.mean(f):.0f} %" if f else "" for f in frac) + " |")
if all(runs[m] for m in METHODS):
    both = sorted(set(runs["bc"]) & set(runs["hybrid-imitation"]))
    diff = [[runs["hybrid-imitation"][s]["eval"][c] - runs["bc"][s]["eval"][c] for s in both
             if c in runs["hybrid-imitation"][s]["eval"] and c in runs["bc"][s]["eval"]] for c in counts]
    print("| hybrid - bc, mean (seeds above) | " +
          " | ".join(f"{statistics.mean(d):+.0f} ({sum(x > 0 for x in d)}/{len(d)})" if d else "" for d in diff) +
          " |")
    print("\nover all counts: " + ", ".join(
        f"{m} {statistics.mean(v for run in runs[m].values() for v in run['eval'].values()):.1f}" for m in METHODS) +
          f", expert {statistics.mean(expert_seed.values()):.1f}" + "".join(
              f", hybrid-imitation {v} {statistics.mean(x for run in runs['hybrid-imitation'].values() for x in run[v].values()):.1f}"
              for v in variants["hybrid-imitation"]))
for m in METHODS:
    print(f"\n{m}: every seed's mean test return (imitation/eval_return_mean) per count")
    print("| seed | " + " | ".join(str(c) for c in counts) + " | mean |")
    print("|---|" + "---|" * (len(counts) + 1))
    for seed in sorted(runs[m]):
        values = [runs[m][seed]["eval"].get(c) for c in counts]
        shown = [f"{v:.0f}" if v is not None else "" for v in values]
        print(f"| {seed} | " + " | ".join(shown) + f" | {statistics.mean(v for v in values if v is not None):.0f} |")
