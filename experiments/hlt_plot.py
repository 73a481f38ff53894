#!/usr/bin/python3
"""hlt_plot: learning curves from hlt_train run directories, as in the paper's figures.

    experiments/hlt_plot.py RUN_OR_PARENT [...] --out curves.png
        [--tags eval/return_mean,train/mode_insertion_gradient] [--title TEXT] [--max-step N]
        [--table] [--at 16000,40000] [--threshold 880]

Every directory given (or found below one) that holds scalars.csv and config.yaml is a run. Runs are grouped by
method; each figure panel shows one tag against environment steps: the mean over seeds as a line and the
standard deviation as a shaded band. Tags logged at different steps in different seeds (episode returns) are
interpolated onto a common grid. With --table it also prints, per method and for the first tag, the mean and
standard deviation over seeds at the steps given with --at (default: the last common step), every seed's
value there, and the first step at which the mean over seeds reaches --threshold. Uses Debian's
python3-matplotlib.
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LABELS = {
    "eval/return_mean": "evaluation return",
    "eval/policy_return_mean": "policy alone (evaluation)",
    "eval/planner_return_mean": "model-based planner alone (evaluation)",
    "train/episode_return": "training episode return",
    "train/mode_insertion_gradient": "mode insertion gradient",
}
# The paper's order and a fixed colour per method, so figures of different environments read alike.
METHOD_ORDER = ["hybrid-stochastic", "hybrid-deterministic", "sac", "mppi", "mpc-deterministic"]


def fail(message):
    print(f"hlt_plot: error: {message}", file=sys.stderr)
    sys.exit(2)


def top_level_value(config_path, key):
    with open(config_path) as f:
        for line in f:
            if line.startswith(key + ":"):
                return line.split(":", 1)[1].strip().strip('"')
    return None


def find_runs(paths):
    runs = []
    for path in paths:
        if not os.path.isdir(path):
            fail(f"{path} is not a directory")
        for root, _dirs, files in os.walk(path):
            if "scalars.csv" in files and "config.yaml" in files:
                runs.append(root)
    if not runs:
        fail("no run directories (holding scalars.csv and config.yaml) under " + ", ".join(paths))
    return sorted(runs)


def read_scalars(run):
    series = {}
    with open(os.path.join(run, "scalars.csv")) as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header != ["wall_time", "step", "tag", "value"]:
            fail(f"{run}/scalars.csv is not an hlt scalar log")
        for row in reader:
            if len(row) != 4:
                continue  # a line cut off by a killed run
            step, tag, value = int(row[1]), row[2], float(row[3])
            series.setdefault(tag, ([], []))
            series[tag][0].append(step)
            series[tag][1].append(value)
    return series


def mean_band(curves, max_step):
    """Mean and std over runs on a common step grid (the union of steps, clipped to the shortest run)."""
    end = min(xs[-1] for xs, _ in curves)
    if max_step:
        end = min(end, max_step)
    grid = np.unique(np.concatenate([np.asarray(xs) for xs, _ in curves]))
    grid = grid[grid <= end]
    values = np.array([np.interp(grid, xs, ys) for xs, ys in curves])
    return grid, values.mean(axis=0), values.std(axis=0)


def print_table(groups, methods, tag, args):
    steps = [int(x) for x in args.at.split(",") if x]
    print(f"| method | seeds | step | {tag} mean +- std | per seed |"
          + (f" first step mean >= {args.threshold:g} |" if args.threshold is not None else ""))
    print("|---|---|---|---|---|" + ("---|" if args.threshold is not None else ""))
    for method in methods:
        curves = [(np.asarray(s[tag][0]), np.asarray(s[tag][1])) for s in groups[method] if tag in s]
        if not curves:
            continue
        first = ""
        if args.threshold is not None:
            grid, mean, _ = mean_band(curves, 0)
            hits = grid[mean >= args.threshold]
            first = f" {int(hits[0])} |" if len(hits) else " not reached |"
        last = min(xs[-1] for xs, _ in curves)
        for step in [s for s in steps if s <= last] or [last]:
            values = [float(np.interp(step, xs, ys)) for xs, ys in curves]
            per_seed = ", ".join(f"{v:.1f}" for v in values)
            print(f"| {method} | {len(values)} | {step} | {np.mean(values):.1f} +- {np.std(values):.1f} | {per_seed} |"
                  + first)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", help="run directories or parents holding several")
    parser.add_argument("--out", required=True, help="PNG file to write")
    parser.add_argument("--tags", default="eval/return_mean", help="comma-separated tags, one panel each")
    parser.add_argument("--title", default=None)
    parser.add_argument("--max-step", type=int, default=0, help="cut the x axis at this environment step")
    parser.add_argument("--table", action="store_true", help="print a summary table of the first tag")
    parser.add_argument("--at", default="", help="comma-separated environment steps for the table")
    parser.add_argument("--threshold", type=float, default=None, help="report when the mean first reaches this")
    args = parser.parse_args()

    groups = {}
    env_names = set()
    for run in find_runs(args.runs):
        method = top_level_value(os.path.join(run, "config.yaml"), "method") or "?"
        env_names.add(top_level_value(os.path.join(run, "config.yaml"), "env") or "?")
        groups.setdefault(method, []).append(read_scalars(run))
    tags = [t for t in args.tags.split(",") if t]
    methods = sorted(groups, key=lambda m: (METHOD_ORDER.index(m) if m in METHOD_ORDER else 99, m))
    if args.table:
        print_table(groups, methods, tags[0], args)

    fig, axes = plt.subplots(len(tags), 1, figsize=(7, 3.2 * len(tags)), sharex=True, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, tag in zip(axes[:, 0], tags):
        drawn = False
        for method in methods:
            curves = []
            for s in groups[method]:
                if tag in s and s[tag][0]:
                    xs, ys = s[tag]
                    order = np.argsort(xs, kind="stable")
                    curves.append((np.asarray(xs)[order], np.asarray(ys)[order]))
            if not curves:
                continue
            grid, mean, std = mean_band(curves, args.max_step)
            colour = colours[(METHOD_ORDER.index(method) if method in METHOD_ORDER else len(METHOD_ORDER))
                             % len(colours)]
            ax.plot(grid, mean, color=colour, label=f"{method} ({len(curves)} seeds)")
            ax.fill_between(grid, mean - std, mean + std, color=colour, alpha=0.2, linewidth=0)
            drawn = True
        ax.set_ylabel(LABELS.get(tag, tag))
        ax.grid(alpha=0.3)
        if drawn:
            ax.legend(fontsize=8, loc="best")
        else:
            ax.text(0.5, 0.5, f"no run logged {tag}", transform=ax.transAxes, ha="center")
    axes[-1, 0].set_xlabel("environment steps")
    axes[0, 0].set_title(args.title or ", ".join(sorted(env_names)))
    fig.tight_layout()
    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    tmp = args.out + ".tmp.png"
    fig.savefig(tmp, dpi=120)
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
