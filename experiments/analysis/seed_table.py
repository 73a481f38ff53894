#!/usr/bin/env python3
"""Per-seed table of one scalar tag at chosen steps, for the run directories under a sweep's output.

  experiments/analysis/seed_table.py DIR [--tag eval/return_mean] [--at 4000,8000,...] [--label 1k,2k,...]

DIR holds seed<N> run directories (DIR is <out>/<env>/<method>); prints a markdown table, one row per seed, the
mean +- std over seeds last. A seed that has not reached a step shows '-' there and is left out of that mean.
"""
import argparse
import csv
import math
import os
import re
import sys


def read(run, tag):
    values = {}
    with open(os.path.join(run, "scalars.csv")) as f:
        for row in csv.DictReader(f):
            if row["tag"] == tag:
                values[int(row["step"])] = float(row["value"])
    return values


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dir")
    p.add_argument("--tag", default="eval/return_mean")
    p.add_argument("--at", default="4000,8000,12000,16000,20000")
    p.add_argument("--label", default="")
    a = p.parse_args()
    steps = [int(x) for x in a.at.split(",")]
    labels = a.label.split(",") if a.label else [str(s) for s in steps]
    seeds = sorted((int(m.group(1)), d) for d in os.listdir(a.dir)
                   if (m := re.fullmatch(r"seed(\d+)", d)) and os.path.isdir(os.path.join(a.dir, d)))
    if not seeds:
        sys.exit("no seed<N> run directories in %s" % a.dir)
    print("| seed | " + " | ".join(labels) + " |")
    print("|---" * (len(steps) + 1) + "|")
    columns = [[] for _ in steps]
    for seed, d in seeds:
        v = read(os.path.join(a.dir, d), a.tag)
        cells = []
        for i, s in enumerate(steps):
            if s in v:
                columns[i].append(v[s])
                cells.append("%.1f" % v[s])
            else:
                cells.append("-")
        print("| %d | %s |" % (seed, " | ".join(cells)))

    def summary(xs):
        if not xs:
            return "-"
        m = sum(xs) / len(xs)
        sd = math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1)) if len(xs) > 1 else 0.0
        return "%.1f +- %.1f" % (m, sd)

    print("| mean +- std | " + " | ".join(summary(c) for c in columns) + " |")


if __name__ == "__main__":
    main()
