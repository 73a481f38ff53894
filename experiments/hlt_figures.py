#!/usr/bin/python3
"""hlt_figures: the paper's figures and its table of final returns, made from a results tree in one command.

    experiments/hlt_figures.py RESULTS [...] --out docs/figures
        [--markdown FILE] [--update docs/RESULTS.md] [--sweep SWEEP.yaml ...] [--max-step N] [--pool-key KEY ...]
        [--train build/experiments/hlt_train] [--reference experiments/reference_results.yaml]

Reads every hlt_train run directory below RESULTS (config.yaml and scalars.csv, parsed by hlt_results.py),
groups them by environment and method as their config.yaml says, and writes to --out:

  fig1_deterministic.png     paper Fig. 1: evaluation return of hybrid-deterministic, sac and
                             mpc-deterministic, one column per environment, and a row with
                             hybrid-deterministic's mode insertion gradient (train/mode_insertion_gradient)
  fig2_stochastic.png        paper Fig. 2: evaluation return of hybrid-stochastic, sac and mppi
  fig4_components_<env>.png  paper Fig. 4: each hybrid's evaluation return, its policy alone
                             (eval/policy_return_mean) and its planner alone (eval/planner_return_mean), with
                             the same figure's baselines, for every environment whose runs logged them
  fig5_imitation.png         paper Fig. 5: test return against the number of expert demonstrations, for runs
                             that log imitation/demonstrations (the count so far): each imitation method's
                             imitation/test_return (imitation/eval_return_mean, the mean over
                             imitation.eval_episodes test episodes, where a run logged it), a hybrid's
                             policy alone (imitation/policy_return, where it differs from the test
                             return) and the expert from the same start states (imitation/expert_return,
                             pooled over all runs of the environment); the
                             markdown adds a table of the values per count; where runs log
                             imitation/eval_success_rate (the robot tasks), a second row of success rates
  robot_<env>.png            the robot tasks' online learning: per training episode, the fraction of seeds
                             whose episode succeeded (train/success) and the episode return, per method;
                             the markdown adds each seed's first success and successes per 10 episodes

Curves are the mean over seeds with a band of one standard deviation against environment steps; the legend
gives every curve's seed count. The markdown (--markdown, default OUT/results.md) holds sections, each
between '<!-- hlt_figures:BEGIN name -->' and '<!-- hlt_figures:END name -->': provenance (the command, the
runs, the exact sweep files), table (final evaluation return, mean +- std over seeds, in the layout of the
authors' published table: a row per method, a column per environment, their numbers beside ours), seeds
(every seed's value), fig1, fig2, fig4, fig5, robot (image and caption) and notes (what was skipped and
why).
--update FILE rewrites, in place, the sections of FILE that carry those markers and nothing else, so
docs/RESULTS.md includes the regenerated tables verbatim.

Order and colours of methods and environments are the registry's (hlt_train --help); the figures' methods
are checked against it. Runs of one environment and method whose configs differ in more than the seed (and
threads, checkpoint.every, train.agent_steps, and the keys given with --pool-key) are variants, labelled by
the differing keys; the variant with most seeds carries the method's name. The final return of a group is
each seed's eval/return_mean at the last evaluation step all its seeds reached (at most --max-step); std is
over seeds with ddof 0. With --sweep only the runs the sweep files list are used, and runs they list but
the tree lacks are reported. Missing environments, methods and tags are skipped with a note; bad input
(malformed scalars.csv, no runs, a seed twice) is an error 'hlt_figures: error: ...' with exit code 2.
"""
import argparse
import os
import re
import shlex
import sys
import textwrap

try:
    import numpy as np
except ImportError:  # pragma: no cover
    sys.stderr.write("hlt_figures: error: needs numpy: run with Debian's /usr/bin/python3\n")
    sys.exit(2)

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from hlt_results import (LABELS, REPO, ResultsError, find_runs, last_common_step, mean_band,  # noqa: E402
                         finish_registry, read_config, read_scalars, read_yaml, sorted_curve, start_registry,
                         values_at)

PROG = "hlt_figures"
EVAL_TAG = "eval/return_mean"
MIG_TAG = "train/mode_insertion_gradient"
COMPONENT_TAGS = [(EVAL_TAG, "hybrid", "-"), ("eval/policy_return_mean", "policy alone", "--"),
                  ("eval/planner_return_mean", "planner alone", ":")]
IMITATION_X = "imitation/demonstrations"
IMITATION_TEST = "imitation/test_return"
IMITATION_EVAL = "imitation/eval_return_mean"
IMITATION_POLICY = "imitation/policy_return"
IMITATION_EXPERT = "imitation/expert_return"
IMITATION_SUCCESS = "imitation/eval_success_rate"
SUCCESS_TAG = "train/success"
EPISODE_RETURN_TAG = "train/episode_return"
# Config keys that say how a run was run, not what was run: runs differing only in these are one variant.
NOT_VARIANT = {"seed", "threads", "train.threads", "checkpoint.every", "train.agent_steps"}
SECTIONS = ["provenance", "table", "seeds", "fig1", "fig2", "fig4", "fig5", "robot", "notes"]
MARKER = re.compile(r"<!-- hlt_figures:(BEGIN|END) ([A-Za-z0-9_-]+) -->")
LINESTYLES = ["-", "--", ":", "-."]


class Figure:
    """One of the paper's benchmark figures: a hybrid against its baselines, and extra rows of its own tags."""

    def __init__(self, name, number, title, hybrid, baselines, extra_rows=()):
        self.name, self.number, self.title = name, number, title
        self.hybrid, self.baselines, self.extra_rows = hybrid, list(baselines), list(extra_rows)
        self.methods = [hybrid] + self.baselines


FIGURES = [
    Figure("fig1", "Fig. 1", "deterministic hybrid learning", "hybrid-deterministic", ["sac", "mpc-deterministic"],
           [MIG_TAG]),
    Figure("fig2", "Fig. 2", "stochastic hybrid learning", "hybrid-stochastic", ["sac", "mppi"]),
]


def fail(message):
    print(f"{PROG}: error: {message}", file=sys.stderr)
    sys.exit(2)


# --------------------------------------------------------------------------------------------------- data


class Run:
    def __init__(self, path):
        self.dir = path
        self.config = read_config(path)
        self.env, self.method = str(self.config["env"]), str(self.config["method"])
        try:
            self.seed = int(self.config["seed"])
        except (TypeError, ValueError):
            raise ResultsError(f"{path}/config.yaml: seed {self.config['seed']!r} is not an integer")
        self.scalars = read_scalars(path)


def reached_budget(run, budget):
    """Whether the run's log shows it reached `budget`, in the budget's unit: agent steps, or iterations for
    an imitation run. An online run's last episode, cut off by the budget, logs no train/agent_steps row, so
    on a task whose episodes end early (the hopper) the last logged count falls short of the budget by less
    than one episode; such a run did finish if an evaluation was logged after that last episode."""
    tag = IMITATION_X if IMITATION_X in run.scalars else "train/agent_steps"
    steps, logged = run.scalars.get(tag, ([], []))
    if not logged:
        return False
    if logged[-1] >= budget:
        return True
    if tag == IMITATION_X:
        return False
    lengths = run.scalars.get("train/episode_length", ([], []))[1]  # environment steps
    skip = run.config.get("train.frame_skip", 1)
    if not lengths or not isinstance(skip, int) or skip < 1:
        return False
    longest = -(-int(max(lengths)) // skip)  # agent steps
    evals = run.scalars.get("eval/return_mean", ([], []))[0]
    return budget - logged[-1] < longest and bool(evals) and max(evals) > max(steps)


class Group:
    """The seeds of one variant of one method on one environment."""

    def __init__(self, env, method, runs, diff, index):
        self.env, self.method, self.runs, self.diff, self.index = env, method, runs, diff, index
        self.label = method if not diff else "%s [%s]" % (
            method, ", ".join(f"{k}={show(v)}" for k, v in sorted(diff.items())))
        self.seeds = [r.seed for r in runs]

    def curves(self, tag):
        return [c for c in (sorted_curve(r.scalars, tag) for r in self.runs) if c is not None]


def show(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ",".join(show(v) for v in value) + "]"
    return "missing" if value is None else str(value)


def make_groups(runs, pooled=()):
    """{(env, method): [Group, ...]} with the variant of most seeds first; keys in pooled make no variant."""
    by_pair = {}
    for run in runs:
        by_pair.setdefault((run.env, run.method), []).append(run)
    groups = {}
    for (env, method), members in by_pair.items():
        keys = set.intersection(*(set(r.config) for r in members)) - NOT_VARIANT - set(pooled)
        variants = {}
        for run in members:
            signature = tuple(sorted((k, repr(run.config[k])) for k in keys))
            variants.setdefault(signature, []).append(run)
        ordered = sorted(variants.values(), key=lambda rs: (-len(rs), rs[0].dir))
        main = ordered[0][0].config
        result = []
        for index, variant in enumerate(ordered):
            variant.sort(key=lambda r: r.seed)
            for a, b in zip(variant, variant[1:]):
                if a.seed == b.seed:
                    raise ResultsError(f"two runs of {env}/{method} with the same config and seed {a.seed}: "
                                       f"{a.dir} and {b.dir} (give one tree, or --sweep to choose)")
            cfg = variant[0].config
            diff = {} if index == 0 else {k: cfg[k] for k in keys if repr(cfg[k]) != repr(main[k])}
            result.append(Group(env, method, variant, diff, index))
        groups[(env, method)] = result
    return groups


def final_stats(group, max_step):
    """(step, per-seed values, mean, std, seeds) of the group's final evaluation, or None without one."""
    pairs = [(r.seed, sorted_curve(r.scalars, EVAL_TAG)) for r in group.runs]
    pairs = [(s, c) for s, c in pairs if c is not None]
    if not pairs:
        return None
    curves = [c for _, c in pairs]
    if max_step and min(xs[0] for xs, _ in curves) > max_step:
        return None
    step = last_common_step(curves, max_step)
    values = values_at(curves, step)
    return step, values, float(np.mean(values)), float(np.std(values)), [s for s, _ in pairs]


def frame_skip(group):
    skips = {r.config.get("train.frame_skip") for r in group.runs}
    return skips.pop() if len(skips) == 1 else None


def suptitle(fig, text):
    """The figure's title, wrapped to its width (a one-column figure would cut it off)."""
    width = max(30, int(fig.get_figwidth() * 11))
    fig.suptitle("\n".join(textwrap.wrap(text, width)), fontsize=10)


def load_reference(path, reg):
    doc = read_yaml(path)
    results = (doc or {}).get("results") or {}
    for env, methods in results.items():
        if env not in reg.envs:
            raise ResultsError(f"{path}: environment {env!r} is not in the registry ({', '.join(reg.envs)})")
        for method, pair in (methods or {}).items():
            if method not in reg.methods:
                raise ResultsError(f"{path}: {env}.{method}: not a registry method ({', '.join(reg.methods)})")
            if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(v, (int, float)) for v in pair)):
                raise ResultsError(f"{path}: {env}.{method} must be [mean, std]")
    return doc


def sweep_selection(sweep_paths, root, run_dirs):
    """The run directories the sweep files list, and per sweep file (path, text, expected, missing, short)."""
    import hlt_sweep
    wanted, reports = {}, []
    present = {os.path.abspath(d) for d in run_dirs}
    for path in sweep_paths:
        try:
            sweep = hlt_sweep.Sweep(path)
            runs = sweep.runs(os.path.abspath(root))
        except hlt_sweep.SweepError as e:
            raise ResultsError(str(e))
        with open(path) as f:
            text = f.read()
        missing = [r for r in runs if os.path.abspath(r.dir) not in present]
        for r in runs:
            if os.path.abspath(r.dir) in present:
                wanted[os.path.abspath(r.dir)] = r
        reports.append({"path": path, "text": text, "runs": runs, "missing": missing, "short": []})
    return wanted, reports


# ------------------------------------------------------------------------------------------------ figures


def save(fig, path):
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def draw_tag(ax, groups, tag, reg, names, max_step, style=None):
    """Mean and std band of a tag for each group; returns [(label, seeds, last step)] of what was drawn."""
    drawn = []
    for group in groups:
        curves = group.curves(tag)
        if not curves:
            continue
        grid, mean, std = mean_band(curves, max_step)
        colour = reg.colour(group.method, names)
        linestyle = style or LINESTYLES[group.index % len(LINESTYLES)]
        ax.plot(grid, mean, color=colour, linestyle=linestyle, label=f"{group.label} ({seeds_word(len(curves))})")
        ax.fill_between(grid, mean - std, mean + std, color=colour, alpha=0.15, linewidth=0)
        drawn.append((group.label, len(curves), int(grid[-1])))
    return drawn


def benchmark_figure(spec, groups, reg, names, args, plt, notes):
    """Fig. 1 or Fig. 2; returns (file or None, caption lines)."""
    envs = sorted({env for env, method in groups if method == spec.hybrid}, key=reg.env_key)
    for env in sorted({env for env, method in groups if method in spec.baselines} - set(envs), key=reg.env_key):
        notes.append(f"{spec.number}, {env}: runs of baselines but none of {spec.hybrid}: no column")
    if not envs:
        notes.append(f"{spec.number} not drawn: no runs of {spec.hybrid}")
        return None, []
    methods = sorted(spec.methods, key=reg.method_key)
    rows = [EVAL_TAG] + spec.extra_rows
    fig, axes = plt.subplots(len(rows), len(envs), figsize=(4.2 * len(envs), 3.0 * len(rows) + 0.6),
                             squeeze=False, sharex="col")
    caption = []
    for col, env in enumerate(envs):
        for row, tag in enumerate(rows):
            ax = axes[row, col]
            shown = methods if tag == EVAL_TAG else [spec.hybrid]
            selected = [g for m in shown for g in groups.get((env, m), [])]
            drawn = draw_tag(ax, selected, tag, reg, names, args.max_step)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(env)
            if col == 0:
                ax.set_ylabel(LABELS.get(tag, tag))
            if row == len(rows) - 1:
                ax.set_xlabel("environment steps")
            if drawn:
                ax.legend(fontsize=7, loc="lower right" if tag == EVAL_TAG else "upper right", framealpha=0.6)
            else:
                ax.text(0.5, 0.5, f"no run logged {tag}", transform=ax.transAxes, ha="center", fontsize=8)
            for label, seeds, last in drawn:
                caption.append(f"{env}, {LABELS.get(tag, tag)}: {label}, {seeds_word(seeds)}, steps 0-{last}")
            absent = [m for m in shown if (env, m) not in groups]
            if absent and tag == EVAL_TAG:
                notes.append(f"{spec.number}, {env}: no runs of {', '.join(absent)}")
    suptitle(fig, f"{spec.number}-style: {spec.title} (mean +- std over seeds)")
    fig.tight_layout()
    path = os.path.join(args.out, f"{spec.name}_{'deterministic' if spec.name == 'fig1' else 'stochastic'}.png")
    save(fig, path)
    plt.close(fig)
    return path, caption


def component_figures(groups, reg, names, args, plt, notes):
    """Fig. 4, one file per environment whose hybrid runs logged their components; [(env, file, caption)]."""
    out = []
    hybrids = sorted({spec.hybrid for spec in FIGURES}, key=reg.method_key)
    envs = sorted({env for env, _ in groups}, key=reg.env_key)
    for env in envs:
        panels = []
        for spec in sorted(FIGURES, key=lambda s: reg.method_key(s.hybrid)):
            variants = groups.get((env, spec.hybrid), [])
            if variants and any(variants[0].curves(tag) for tag, _, _ in COMPONENT_TAGS[1:]):
                panels.append((spec, variants[0]))
                if len(variants) > 1:
                    notes.append(f"Fig. 4, {env}: {spec.hybrid}'s main variant only (its other variants are in "
                                 f"{spec.number} and the table)")
        if not panels:
            if any((env, h) in groups for h in hybrids):
                notes.append(f"Fig. 4, {env}: the hybrid runs logged no eval/policy_return_mean or "
                             "eval/planner_return_mean (eval.components)")
            continue
        fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), squeeze=False)
        caption = []
        for ax, (spec, group) in zip(axes[0], panels):
            colour = reg.colour(group.method, names)
            for tag, role, linestyle in COMPONENT_TAGS:
                curves = group.curves(tag)
                if not curves:
                    notes.append(f"Fig. 4, {env}, {group.label}: no {tag}")
                    continue
                grid, mean, std = mean_band(curves, args.max_step)
                ax.plot(grid, mean, color=colour, linestyle=linestyle,
                        label=f"{group.label}: {role} ({seeds_word(len(curves))})")
                ax.fill_between(grid, mean - std, mean + std, color=colour, alpha=0.12, linewidth=0)
                caption.append(f"{group.label} {role}: {seeds_word(len(curves))}, steps 0-{int(grid[-1])}")
            baselines = [groups[(env, m)][0] for m in sorted(spec.baselines, key=reg.method_key)
                         if (env, m) in groups]
            for label, seeds, last in draw_tag(ax, baselines, EVAL_TAG, reg, names, args.max_step):
                caption.append(f"{label} (reference): {seeds_word(seeds)}, steps 0-{last}")
            ax.set_title(f"{env}: {group.label}", fontsize=9)
            ax.set_xlabel("environment steps")
            ax.set_ylabel("evaluation return")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="lower right", framealpha=0.6)
        suptitle(fig, "Fig. 4-style: the hybrid's components alone (mean +- std over seeds)")
        fig.tight_layout()
        path = os.path.join(args.out, f"fig4_components_{env}.png")
        save(fig, path)
        plt.close(fig)
        out.append((env, path, caption))
    if not out and not any(n.startswith("Fig. 4") for n in notes):
        notes.append("Fig. 4 not drawn: no hybrid runs")
    return out


def imitation_curve(run, tag):
    """(demonstrations, values) of an imitation tag: its rows matched by step to imitation/demonstrations."""
    if IMITATION_X not in run.scalars or tag not in run.scalars:
        return None
    count = dict(zip(*run.scalars[IMITATION_X]))
    points = sorted((count[s], v) for s, v in zip(*run.scalars[tag]) if s in count)
    if not points:
        return None
    return np.array([p[0] for p in points]), np.array([p[1] for p in points])


def matplotlib_ticker():
    import matplotlib.ticker
    return matplotlib.ticker


def imitation_rows(groups, reg):
    """Fig. 5's curves per environment: [(label, colour key, linestyle, [curves])], the expert first."""
    imitation = [g for gs in groups.values() for g in gs if any(IMITATION_X in r.scalars for r in g.runs)]
    envs = sorted({g.env for g in imitation}, key=reg.env_key)
    out = {}
    for env in envs:
        mine = sorted((g for g in imitation if g.env == env), key=lambda g: (reg.method_key(g.method), g.index))
        # The expert runs from each seed's test start states, which every method of that seed shares: one
        # curve per seed (the first run's), not one per run.
        by_seed = {}
        for g in mine:
            for r in g.runs:
                c = imitation_curve(r, IMITATION_EXPERT)
                if c is not None and r.seed not in by_seed:
                    by_seed[r.seed] = c
        expert = [by_seed[k] for k in sorted(by_seed)]
        rows = [("expert", None, "--", expert)] if expert else []
        for group in mine:
            # The mean of imitation.eval_episodes test episodes where a run logged it: one episode per
            # count is too noisy to rank methods by (the Ant: per-count spread over seeds up to 200).
            tests = [imitation_curve(r, IMITATION_EVAL) or imitation_curve(r, IMITATION_TEST)
                     for r in group.runs]
            policies = [imitation_curve(r, IMITATION_POLICY) for r in group.runs]
            rows.append((group.label, group.method, "-", [c for c in tests if c is not None]))
            # a hybrid's policy alone; for behaviour cloning the policy is the test, so nothing new to draw
            differs = [p for p, t in zip(policies, tests) if p is not None and t is not None and
                       (len(p[1]) != len(t[1]) or not np.array_equal(p[1], t[1]))]
            if differs:
                rows.append((f"{group.label}, policy alone", group.method, ":",
                             [p for p in policies if p is not None]))
        out[env] = rows
    return out


def imitation_success_rows(groups, reg):
    """Per environment whose imitation runs log IMITATION_SUCCESS: [(label, method, [curves])]."""
    out = {}
    for gs in groups.values():
        for g in gs:
            curves = [c for c in (imitation_curve(r, IMITATION_SUCCESS) for r in g.runs) if c is not None]
            if curves:
                out.setdefault(g.env, []).append((g.label, g.method, reg.method_key(g.method), g.index, curves))
    return {env: [(l, m, c) for l, m, _, _, c in sorted(rows, key=lambda r: (r[2], r[3]))]
            for env, rows in out.items()}


def per_count_table(title, rows, fmt_cell):
    """A markdown table: a column per demonstration count, a row per (label, n, {count: (mean, std)})."""
    cols = sorted({c for _, _, values in rows for c in values})
    lines = [title, "", "| | n | " + " | ".join(str(c) for c in cols) + " |", "|---|---|" + "---|" * len(cols)]
    for label, n, values in rows:
        cells = [fmt_cell(*values[c]) if c in values else "" for c in cols]
        lines.append(f"| {label} | {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def imitation_figure(groups, reg, names, args, plt, notes):
    rows = imitation_rows(groups, reg)
    if not rows:
        notes.append(f"Fig. 5 not drawn: no run logged {IMITATION_X}")
        return None, [], ""
    success = imitation_success_rows(groups, reg)
    nrows = 2 if success else 1
    fig, axes = plt.subplots(nrows, len(rows), figsize=(5.2 * len(rows), 3.8 * nrows), squeeze=False)
    caption, tables = [], []
    for col, (env, env_rows) in enumerate(rows.items()):
        ax = axes[0][col]
        table = []
        for label, method, linestyle, curves in env_rows:
            if not curves:
                notes.append(f"Fig. 5, {env}, {label}: no {IMITATION_TEST}")
                continue
            grid, mean, std = mean_band(curves)
            colour = "#000000" if method is None else reg.colour(method, names)
            ax.plot(grid, mean, color=colour, linestyle=linestyle, marker="o", markersize=3,
                    label=f"{label} ({seeds_word(len(curves))})")
            ax.fill_between(grid, mean - std, mean + std, color=colour, alpha=0.12, linewidth=0)
            caption.append(f"{env}, {label}: {seeds_word(len(curves))}, {int(grid[0])}-{int(grid[-1])} "
                           "demonstrations")
            table.append((label, len(curves), dict(zip(grid.astype(int), zip(mean, std)))))
        ax.set_title(env)
        ax.set_xlabel("expert demonstrations")
        ax.xaxis.set_major_locator(matplotlib_ticker().MaxNLocator(integer=True))
        ax.set_ylabel("test episode return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
        if table:
            tables.append(per_count_table(
                f"{env}: test return after each demonstration, mean +- std over seeds (n):", table,
                lambda m, sd: f"{m:.0f} +- {sd:.0f}"))
        if nrows == 2:
            ax = axes[1][col]
            srows = []
            for label, method, curves in success.get(env, []):
                grid, mean, std = mean_band(curves)
                colour = reg.colour(method, names)
                ax.plot(grid, mean, color=colour, marker="o", markersize=3,
                        label=f"{label} ({seeds_word(len(curves))})")
                ax.fill_between(grid, np.clip(mean - std, 0, 1), np.clip(mean + std, 0, 1), color=colour,
                                alpha=0.12, linewidth=0)
                caption.append(f"{env}, {label}, success rate: {seeds_word(len(curves))}, {int(grid[0])}-"
                               f"{int(grid[-1])} demonstrations")
                srows.append((label, len(curves), dict(zip(grid.astype(int), zip(mean, std)))))
            ax.set_xlabel("expert demonstrations")
            ax.xaxis.set_major_locator(matplotlib_ticker().MaxNLocator(integer=True))
            ax.set_ylabel(f"success rate ({IMITATION_SUCCESS})")
            ax.set_ylim(-0.05, 1.05)
            ax.grid(alpha=0.3)
            if srows:
                ax.legend(fontsize=7, loc="best")
                tables.append(per_count_table(
                    f"{env}: success rate of the extra test episodes after each demonstration "
                    f"(`{IMITATION_SUCCESS}`), mean +- std over seeds (n):", srows,
                    lambda m, sd: f"{m:.2f} +- {sd:.2f}"))
            else:
                ax.set_visible(False)
    suptitle(fig, "Fig. 5-style: imitation (mean +- std over seeds)")
    fig.tight_layout()
    path = os.path.join(args.out, "fig5_imitation.png")
    save(fig, path)
    plt.close(fig)
    return path, caption, "\n\n".join(tables)


def episode_series(run, tag):
    """A run's per-training-episode values of tag, in episode order (rows at the same steps as
    train/episodes), or None."""
    if tag not in run.scalars or "train/episodes" not in run.scalars:
        return None
    index = dict(zip(*run.scalars["train/episodes"]))
    points = sorted((index[s], v) for s, v in zip(*run.scalars[tag]) if s in index)
    return [v for _, v in points] if points else None


def robot_figures(groups, reg, names, args, plt, notes):
    """Online runs that log train/success: success and return per training episode, one figure per env."""
    out = []
    envs = sorted({env for (env, _), gs in groups.items() for g in gs
                   if any(SUCCESS_TAG in r.scalars for r in g.runs)}, key=reg.env_key)
    for env in envs:
        mine = sorted((g for (e, _), gs in groups.items() if e == env for g in gs
                       if any(SUCCESS_TAG in r.scalars for r in g.runs)),
                      key=lambda g: (reg.method_key(g.method), g.index))
        fig, axes = plt.subplots(1, 2, figsize=(10.4, 3.8), squeeze=False)
        lines = [f"{env}: each seed's training episodes (`{SUCCESS_TAG}`): the first that succeeded, and "
                 "successes per block of 10 episodes.", "",
                 "| method | seed | first success (episode) | 1-10 | 11-20 | 21-30 | mean return, last 10 episodes |",
                 "|---|---|---|---|---|---|---|"]
        caption = []
        for g in mine:
            colour = reg.colour(g.method, names)
            succ = [episode_series(r, SUCCESS_TAG) for r in g.runs]
            rets = [episode_series(r, EPISODE_RETURN_TAG) for r in g.runs]
            pairs = [(r, s, e) for r, s, e in zip(g.runs, succ, rets) if s and e]
            if not pairs:
                continue
            n = min(len(s) for _, s, _ in pairs)
            s_mat = np.array([s[:n] for _, s, _ in pairs])
            e_mat = np.array([e[:n] for _, _, e in pairs])
            x = np.arange(1, n + 1)
            axes[0][0].plot(x, s_mat.mean(axis=0), color=colour, marker="o", markersize=2,
                            label=f"{g.label} ({seeds_word(len(pairs))})")
            mean, std = e_mat.mean(axis=0), e_mat.std(axis=0)
            axes[0][1].plot(x, mean, color=colour, label=f"{g.label} ({seeds_word(len(pairs))})")
            axes[0][1].fill_between(x, mean - std, mean + std, color=colour, alpha=0.12, linewidth=0)
            caption.append(f"{env}, {g.label}: {seeds_word(len(pairs))}, episodes 1-{n}")
            within = 0
            for run, s, e in sorted(pairs, key=lambda p: p[0].seed):
                first = next((i + 1 for i, v in enumerate(s) if v > 0.5), None)
                within += first is not None and first <= 20
                blocks = [f"{int(sum(v > 0.5 for v in s[a:a + 10]))}/{len(s[a:a + 10])}" if len(s) > a else ""
                          for a in (0, 10, 20)]
                tail = e[-10:]
                tail_text = f"{np.mean(tail):.1f}" if tail else ""
                lines.append(f"| {g.label} | {run.seed} | {first if first else 'none'} | " + " | ".join(blocks)
                             + f" | {tail_text} |")
            lines.append(f"| {g.label} | seeds succeeding within 20 episodes | {within} of {len(pairs)} | | | | |")
        axes[0][0].set_ylabel(f"fraction of seeds succeeding ({SUCCESS_TAG})")
        axes[0][0].set_ylim(-0.05, 1.05)
        axes[0][1].set_ylabel(f"training episode return ({EPISODE_RETURN_TAG})")
        for ax in axes[0]:
            ax.set_xlabel("training episode")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
        suptitle(fig, f"{env}: online learning, per training episode (mean over seeds)")
        fig.tight_layout()
        path = os.path.join(args.out, f"robot_{env}.png")
        save(fig, path)
        plt.close(fig)
        out.append((env, path, caption, "\n".join(lines)))
    return out


# ----------------------------------------------------------------------------------------------- markdown


def seeds_word(n):
    return f"{n} seed" + ("" if n == 1 else "s")


def fmt(mean, std):
    return f"{mean:.1f} +- {std:.1f}"


def steps_text(step, skip):
    return f"{step} env steps" + (f" ({step // skip} agent steps)" if isinstance(skip, int) and skip > 0 else "")


def table_section(groups, stats, reg, reference):
    ref = reference.get("results") or {}
    # Imitation runs are measured per demonstration (Fig. 5's table), not by a final evaluation return.
    def measured_per_demonstration(g):
        return any(IMITATION_X in r.scalars for r in g.runs) and not any(EVAL_TAG in r.scalars for r in g.runs)

    online_keys = {k for k, gs in groups.items() if not all(measured_per_demonstration(g) for g in gs)}
    envs = sorted({e for e, _ in online_keys} | set(ref), key=reg.env_key)
    online = {m for _, m in online_keys}
    methods = sorted(online | {m for e in ref.values() for m in (e or {})}, key=reg.method_key)
    footnotes = reference.get("footnotes") or []
    marks = {}
    for i, note in enumerate(footnotes):
        for env in note.get("envs") or []:
            marks.setdefault(env, "*" * (i + 1))
    lines = [f"Final evaluation return (`{EVAL_TAG}`): mean +- std over seeds (ddof 0) of each seed's value at "
             "the last evaluation all seeds of the row reached; n is the number of seeds, then the environment "
             "steps (agent steps) of that evaluation. \"paper\": "
             + str(reference.get("source", "the published numbers")) + ". A method with a config variant has "
             "a row per variant, named by the keys that differ.", "",
             "| method | " + " | ".join(env + marks.get(env, "") for env in envs) + " |",
             "|---|" + "---|" * len(envs)]
    for method in methods:
        # the method's own row (its main variant on every environment), then a row per other variant: the
        # same differing keys on two environments share a row
        labels = [method] + list(dict.fromkeys(g.label for env in envs for g in groups.get((env, method), [])[1:]))
        for label in labels:
            cells = []
            for env in envs:
                group = next((g for g in groups.get((env, method), []) if g.label == label), None)
                ours = ""
                if group is not None:
                    s = stats.get(id(group))
                    ours = (f"{fmt(s[2], s[3])} (n={len(s[1])}, {steps_text(s[0], frame_skip(group))})"
                            if s else f"no {EVAL_TAG}")
                paper = (ref.get(env) or {}).get(method) if label == method else None
                paper = f"paper {fmt(*paper)}" if paper else ""
                cells.append("; ".join(c for c in (ours, paper) if c) or "-")
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    for i, note in enumerate(footnotes):
        lines += ["", "*" * (i + 1) + note.get("text", "")]
    return "\n".join(lines)


def seeds_section(groups, stats, reg):
    lines = [f"Every seed's final `{EVAL_TAG}` (the value at the row's step).", "",
             "| environment | method | seeds | at | mean +- std | per seed (seed: return) |",
             "|---|---|---|---|---|---|"]
    for key in sorted(groups, key=lambda k: (reg.env_key(k[0]), reg.method_key(k[1]))):
        for group in groups[key]:
            s = stats.get(id(group))
            if not s:
                lines.append(f"| {group.env} | {group.label} | {len(group.runs)} | - | no {EVAL_TAG} | |")
                continue
            step, values, mean, std, seeds = s
            per_seed = ", ".join(f"{seed}: {v:.1f}" for seed, v in zip(seeds, values))
            lines.append(f"| {group.env} | {group.label} | {len(values)} | {steps_text(step, frame_skip(group))} "
                         f"| {fmt(mean, std)} | {per_seed} |")
    return "\n".join(lines)


def figure_section(path, base, alt, text, caption):
    if not path:
        return f"_Not drawn: {text}_"
    rel = os.path.relpath(path, base)
    lines = [f"![{alt}]({rel})", "", text]
    if caption:
        lines += [""] + [f"- {c}" for c in caption]
    return "\n".join(lines)


def by_pair(sweep_runs):
    """'env/method seeds 0, 1; ...' for a list of hlt_sweep runs."""
    pairs = {}
    for r in sweep_runs:
        pairs.setdefault(f"{r.env}/{r.method}", []).append(r.seed)
    return "; ".join(f"{k} seed{'s' if len(v) > 1 else ''} {', '.join(map(str, v))}" for k, v in pairs.items())


def provenance_section(args, runs, groups, reg, reports, left_out):
    lines = ["Generated by `experiments/hlt_figures.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
             + f"` from {len(runs)} run{'' if len(runs) == 1 else 's'} under "
             + ", ".join(f"`{p}`" for p in args.results) + ":", ""]
    for key in sorted(groups, key=lambda k: (reg.env_key(k[0]), reg.method_key(k[1]))):
        for group in groups[key]:
            lines.append(f"- {group.env} / {group.label}: seeds {', '.join(map(str, group.seeds))}")
    lines.append("")
    if args.pool_key:
        lines += ["Pooled although their configs differ in: " + ", ".join(f"`{k}`" for k in args.pool_key)
                  + " (`--pool-key`).", ""]
    if not reports:
        lines.append("No sweep file given (`--sweep`): every run found was used.")
    for rep in reports:
        rel = os.path.relpath(os.path.abspath(rep["path"]), REPO)
        shown = rel if not rel.startswith("..") else rep["path"]
        lines += [f"Sweep file `{shown}` ({len(rep['runs'])} runs, {len(rep['runs']) - len(rep['missing'])} "
                  "found" + (f"; missing: {by_pair(rep['missing'])}" if rep["missing"] else "")
                  + (f"; short of their budget: {by_pair(rep['short'])}" if rep["short"] else "") + "):",
                  "", "```yaml", rep["text"].rstrip("\n"), "```", ""]
    if left_out:
        lines.append(f"{left_out} run(s) under the results tree that no sweep file lists were left out.")
    return "\n".join(lines).rstrip("\n")


def wrap(name, body):
    return f"<!-- hlt_figures:BEGIN {name} -->\n{body}\n<!-- hlt_figures:END {name} -->"


def marked_sections(text, path):
    """The names of the sections marked in text, checked: every BEGIN has its END, no nesting, no repeats."""
    names, open_name = [], None
    for m in MARKER.finditer(text):
        kind, name = m.group(1), m.group(2)
        if kind == "BEGIN":
            if open_name:
                raise ResultsError(f"{path}: section {name!r} begins inside section {open_name!r}")
            if name not in SECTIONS:
                raise ResultsError(f"{path}: unknown section {name!r} (known: {', '.join(SECTIONS)})")
            if name in names:
                raise ResultsError(f"{path}: section {name!r} is marked twice")
            open_name = name
            names.append(name)
        else:
            if name != open_name:
                raise ResultsError(f"{path}: END {name!r} without its BEGIN")
            open_name = None
    if open_name:
        raise ResultsError(f"{path}: section {open_name!r} has no <!-- hlt_figures:END {open_name} -->")
    if not names:
        raise ResultsError(f"{path} has no <!-- hlt_figures:BEGIN name --> ... <!-- hlt_figures:END name --> "
                           f"sections (names: {', '.join(SECTIONS)})")
    return names


def replace_sections(text, bodies):
    def repl(m):
        name = m.group(1)
        return wrap(name, bodies[name])
    pattern = re.compile(r"<!-- hlt_figures:BEGIN ([A-Za-z0-9_-]+) -->.*?<!-- hlt_figures:END \1 -->", re.S)
    return pattern.sub(repl, text)


def write_text(path, text):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


# --------------------------------------------------------------------------------------------------- main


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("results", nargs="+", help="results trees (RESULTS/<env>/<method>/seed<seed>) or runs")
    parser.add_argument("--out", required=True, help="directory for the figures (PNG)")
    parser.add_argument("--markdown", help="markdown file to write with every section (default OUT/results.md)")
    parser.add_argument("--update", help="markdown file whose marked sections are rewritten in place")
    parser.add_argument("--sweep", action="append", default=[],
                        help="sweep file the runs came from (repeatable): only its runs are used, and the file "
                             "is quoted in the provenance section")
    parser.add_argument("--max-step", type=int, default=0, help="cut curves and the table at this environment step")
    parser.add_argument("--pool-key", action="append", default=[], metavar="KEY",
                        help="a config key (e.g. planner.density_tanh_correction) whose differences make no "
                             "variant: runs differing only in it are pooled (repeatable; said in provenance)")
    parser.add_argument("--train", help="hlt_train, whose --help is the registry (default "
                        "$HLT_BUILD_DIR/experiments/hlt_train, else build/experiments/hlt_train)")
    parser.add_argument("--reference", default=os.path.join(HERE, "reference_results.yaml"),
                        help="the published numbers (default experiments/reference_results.yaml)")
    args = parser.parse_args()
    markdown = args.markdown or os.path.join(args.out, "results.md")
    try:
        update_text = None
        if args.update:
            try:
                with open(args.update) as f:
                    update_text = f.read()
            except OSError as e:
                raise ResultsError(f"cannot read {args.update}: {e.strerror}")
            marked_sections(update_text, args.update)
        if args.sweep and len(args.results) != 1:
            raise ResultsError("--sweep needs exactly one results tree (the --out the sweep was run with)")
        run_dirs = find_runs(args.results)
        reports, left_out = [], 0
        if args.sweep:
            wanted, reports = sweep_selection(args.sweep, args.results[0], run_dirs)
            left_out = len([d for d in run_dirs if os.path.abspath(d) not in wanted])
            run_dirs = [d for d in run_dirs if os.path.abspath(d) in wanted]
            if not run_dirs:
                raise ResultsError("none of the sweep files' runs is under " + args.results[0])
        runs = [Run(d) for d in run_dirs]
        for rep in reports:
            by_dir = {os.path.abspath(r.dir): r for r in runs}
            for srun in rep["runs"]:
                run = by_dir.get(os.path.abspath(srun.dir))
                if run is not None:
                    if not reached_budget(run, srun.steps):
                        rep["short"].append(srun)
        groups = make_groups(runs, args.pool_key)
        started = start_registry(args.train)  # LibTorch loads while matplotlib does
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            raise ResultsError("needs matplotlib: run with Debian's /usr/bin/python3 (apt-get install "
                               "python3-matplotlib)")
        reg = finish_registry(started)
        for spec in FIGURES:
            for method in spec.methods:
                if method not in reg.methods:
                    raise ResultsError(f"{spec.number} names {method!r}, which {reg.source} does not list "
                                       f"({', '.join(reg.methods)}): update hlt_figures.py's FIGURES")
        reference = load_reference(args.reference, reg)
    except ResultsError as e:
        fail(str(e))

    notes = []
    for rep in reports:
        if rep["missing"]:
            notes.append(f"{rep['path']}: {len(rep['missing'])} of its runs are not under {args.results[0]}: "
                         + by_pair(rep["missing"]))
        if rep["short"]:
            notes.append(f"{rep['path']}: {len(rep['short'])} of its runs stopped short of their budget: "
                         + by_pair(rep["short"]))
    names = {m for _, m in groups}
    for env, method in groups:
        if env not in reg.envs or method not in reg.methods:
            notes.append(f"{env}/{method}: not in the registry of {reg.source}; drawn after the registry's names")
    stats = {}
    for gs in groups.values():
        for group in gs:
            s = final_stats(group, args.max_step)
            if s is None and any(IMITATION_X in r.scalars for r in group.runs):
                continue  # an imitation run is measured per demonstration (Fig. 5), not by eval/return_mean
            if s is None:
                notes.append(f"{group.env}/{group.label}: no {EVAL_TAG}" +
                             (f" at or before step {args.max_step}" if args.max_step else ""))
            else:
                stats[id(group)] = s
                if len(s[1]) < len(group.runs):
                    notes.append(f"{group.env}/{group.label}: {len(group.runs) - len(s[1])} seed(s) without "
                                 f"{EVAL_TAG}")

    os.makedirs(args.out, exist_ok=True)
    drawn = {}
    for spec in FIGURES:
        drawn[spec.name] = benchmark_figure(spec, groups, reg, names, args, plt, notes)
    components = component_figures(groups, reg, names, args, plt, notes)
    drawn["fig5"] = imitation_figure(groups, reg, names, args, plt, notes)
    robots = robot_figures(groups, reg, names, args, plt, notes)

    def bodies(base):
        out = {"provenance": provenance_section(args, runs, groups, reg, reports, left_out),
               "table": table_section(groups, stats, reg, reference),
               "seeds": seeds_section(groups, stats, reg)}
        for spec in FIGURES:
            path, caption = drawn[spec.name]
            extra = (f"; bottom row: {spec.hybrid}'s mode insertion gradient (`{MIG_TAG}`)"
                     if MIG_TAG in spec.extra_rows else "")
            out[spec.name] = figure_section(
                path, base, f"{spec.number}-style", f"{spec.number}-style, {spec.title}: evaluation return "
                f"(`{EVAL_TAG}`) of {', '.join(spec.methods)} against environment steps, mean +- std over "
                f"seeds{extra}." if path else f"no runs of {spec.hybrid}.", caption)
        if components:
            out["fig4"] = "\n\n".join(figure_section(
                path, base, f"Fig. 4-style, {env}", f"Fig. 4-style, {env}: each hybrid's evaluation return, its "
                "policy alone (`eval/policy_return_mean`, dashed) and its model-based planner alone on the same "
                "learned models (`eval/planner_return_mean`, dotted), with the figure's baselines, mean +- std "
                "over seeds.", caption) for env, path, caption in components)
        else:
            out["fig4"] = "_Not drawn: no hybrid run logged eval/policy_return_mean or eval/planner_return_mean._"
        path, caption, table = drawn["fig5"]
        out["fig5"] = figure_section(
            path, base, "Fig. 5-style", "Fig. 5-style: test episode return against the number of expert "
            f"demonstrations (`{IMITATION_X}`) of each imitation method (`{IMITATION_EVAL}`, the mean of "
            f"`imitation.eval_episodes` test episodes, where logged, else `{IMITATION_TEST}`), a hybrid's "
            f"policy alone (`{IMITATION_POLICY}`, dotted) and the expert run from the same start states "
            f"(`{IMITATION_EXPERT}`, dashed), mean +- std over seeds."
            if path else f"no run logged `{IMITATION_X}`.", caption)
        if table:
            out["fig5"] += "\n\n" + table
        if robots:
            out["robot"] = "\n\n".join(figure_section(
                path, base, f"robot task {env}", f"{env}: per training episode, the fraction of seeds whose "
                f"episode succeeded (`{SUCCESS_TAG}`) and the episode return (mean +- std over seeds).",
                caption) + "\n\n" + table for env, path, caption, table in robots)
        else:
            out["robot"] = f"_Not drawn: no online run logged {SUCCESS_TAG}._"
        out["notes"] = "\n".join(f"- {n}" for n in notes) if notes else "Nothing was skipped."
        return out

    titles = {"provenance": "Provenance", "table": "Final evaluation returns", "seeds": "Every seed",
              "fig1": "Fig. 1: deterministic hybrid learning", "fig2": "Fig. 2: stochastic hybrid learning",
              "fig4": "Fig. 4: component analysis", "fig5": "Fig. 5: imitation",
              "robot": "Robot tasks: learning online", "notes": "Skipped"}
    standalone = bodies(os.path.dirname(os.path.abspath(markdown)))
    text = ("# Results (generated by experiments/hlt_figures.py)\n\n" +
            "\n\n".join(f"## {titles[name]}\n\n{wrap(name, standalone[name])}" for name in SECTIONS) + "\n")
    write_text(markdown, text)
    for spec in FIGURES:
        if drawn[spec.name][0]:
            print(f"wrote {drawn[spec.name][0]}")
    for _, path, _ in components:
        print(f"wrote {path}")
    if drawn["fig5"][0]:
        print(f"wrote {drawn['fig5'][0]}")
    for _, path, _, _ in robots:
        print(f"wrote {path}")
    print(f"wrote {markdown}")
    if args.update:
        updated = replace_sections(update_text, bodies(os.path.dirname(os.path.abspath(args.update))))
        write_text(args.update, updated)
        print(f"updated {args.update}: sections {', '.join(marked_sections(updated, args.update))}")
    print(f"{len(runs)} run{'' if len(runs) == 1 else 's'}; " + "; ".join(
        f"{g.env}/{g.label}: {seeds_word(len(g.runs))}" for k in sorted(groups, key=lambda k: (reg.env_key(k[0]),
                                                                                         reg.method_key(k[1])))
        for g in groups[k]))
    if stats:
        print(table_section(groups, stats, reg, {"results": {}}).split("\n", 2)[2])
    for note in notes:
        print(f"note: {note}")


if __name__ == "__main__":
    main()
