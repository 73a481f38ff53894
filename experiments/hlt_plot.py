#!/usr/bin/python3
"""hlt_plot: learning curves from hlt_train run directories, as in the paper's figures.

    experiments/hlt_plot.py RUN_OR_PARENT [...] --out curves.png
        [--tags eval/return_mean,train/mode_insertion_gradient] [--title TEXT] [--max-step N]
        [--table] [--at 16000,40000] [--threshold 880] [--train build/experiments/hlt_train]

Every directory given (or found below one) that holds scalars.csv and config.yaml is a run. Runs are grouped by
method; each figure panel shows one tag against environment steps: the mean over seeds as a line and the
standard deviation as a shaded band. Tags logged at different steps in different seeds (episode returns) are
interpolated onto a common grid. With --table it also prints, per method and for the first tag, the mean and
standard deviation over seeds at the steps given with --at (default: the last common step), every seed's
value there, and the first step at which the mean over seeds reaches --threshold. Methods come in the
registry's order with a fixed colour each (hlt_train --help, found as --train, else
$HLT_BUILD_DIR/experiments/hlt_train, else build/experiments/hlt_train; without it, alphabetically, with a
warning). The parsing is experiments/hlt_results.py's, shared with hlt_figures.py. Uses Debian's
python3-matplotlib.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from hlt_results import (LABELS, ResultsError, alphabetical_registry, find_runs, mean_band,  # noqa: E402
                         read_scalars, registry, sorted_curve, top_level_value)


def fail(message):
    print(f"hlt_plot: error: {message}", file=sys.stderr)
    sys.exit(2)


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
    parser.add_argument("--train", help="hlt_train, whose --help gives the methods' order and colours (default "
                        "$HLT_BUILD_DIR/experiments/hlt_train, else build/experiments/hlt_train)")
    args = parser.parse_args()

    groups = {}
    env_names = set()
    try:
        for run in find_runs(args.runs):
            method = top_level_value(os.path.join(run, "config.yaml"), "method") or "?"
            env_names.add(top_level_value(os.path.join(run, "config.yaml"), "env") or "?")
            groups.setdefault(method, []).append(read_scalars(run))
    except ResultsError as e:
        fail(str(e))
    try:
        reg = registry(args.train)
    except ResultsError as e:
        print(f"hlt_plot: warning: {e}; methods in alphabetical order, colours not the registry's",
              file=sys.stderr)
        reg = alphabetical_registry(env_names, groups)
    tags = [t for t in args.tags.split(",") if t]
    methods = sorted(groups, key=reg.method_key)
    if args.table:
        print_table(groups, methods, tags[0], args)

    fig, axes = plt.subplots(len(tags), 1, figsize=(7, 3.2 * len(tags)), sharex=True, squeeze=False)
    for ax, tag in zip(axes[:, 0], tags):
        drawn = False
        for method in methods:
            curves = [c for c in (sorted_curve(s, tag) for s in groups[method]) if c is not None]
            if not curves:
                continue
            grid, mean, std = mean_band(curves, args.max_step)
            colour = reg.colour(method, groups)
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
