#!/usr/bin/env python3
"""Summary of `hlt_rollout --plan-check` outputs: one row per output file (NAME.txt) with its four figures (the
mean over the checked planning calls) and the episodes' mean return, then one row per group of files whose
names differ only in their seed (`_s<seed>`), with the mean over them and each file's value.

  experiments/analysis/plan_check_summary.py experiments/results/plan_check_674cb6e
"""
import glob
import os
import re
import statistics
import sys

if len(sys.argv) != 2:
    sys.exit(__doc__)
FIGURES = ("rank", "reward rank", "choice", "best - mean")
figure = re.compile(r"mean (-?[\d.]+|nan) median (-?[\d.]+|nan) over (\d+)")
groups = {}
print("| run | " + " | ".join(FIGURES) + " | mean return | successes |")
print("|---|" + "---|" * (len(FIGURES) + 2))
for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.txt"))):
    text = open(path).read()
    found = figure.findall(text)
    if "plan check over" not in text or len(found) < len(FIGURES):
        continue
    name = os.path.basename(path)[:-4]
    values = [float(m[0]) for m in found[:len(FIGURES)]]
    ret = re.search(r"mean return (-?[\d.]+)", text)
    succ = re.search(r"success (\d+ of \d+)", text)
    print(f"| {name} | " + " | ".join(f"{v:.3f}" for v in values) +
          f" | {ret.group(1) if ret else ''} | {succ.group(1) if succ else ''} |")
    groups.setdefault(re.sub(r"_s\d+", "", name), []).append(values)
print("\nper group, mean over its runs (each run's value):")
for group, rows in groups.items():
    cols = list(zip(*rows))
    print(f"{group}: {len(rows)} runs; " + "; ".join(
        f"{label} {statistics.mean(c):.3f} ({', '.join(f'{v:.2f}' for v in c)})" for label, c in zip(FIGURES, cols)))
