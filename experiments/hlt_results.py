"""hlt_results: reading hlt_train run directories, shared by hlt_plot.py and hlt_figures.py.

A run directory holds config.yaml (the resolved config; top-level keys env, method, seed) and scalars.csv
(header wall_time,step,tag,value; step counts environment steps). This module finds runs below given paths,
parses both files, puts curves of several seeds on a common step grid, and asks hlt_train for the registry
(its --help lists every environment and method), whose order fixes the order and colour of methods in every
figure and table. Errors are raised as ResultsError, which the scripts report in one line with exit code 2.
"""
import csv
import os
import re
import subprocess

import numpy as np

from hlt_sweep import is_executable, train_path  # one lookup of hlt_train for both tools

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

LABELS = {
    "eval/return_mean": "evaluation return",
    "eval/policy_return_mean": "policy alone (evaluation)",
    "eval/planner_return_mean": "model-based planner alone (evaluation)",
    "train/episode_return": "training episode return",
    "train/mode_insertion_gradient": "mode insertion gradient",
}


class ResultsError(Exception):
    """A missing or malformed input: reported as '<prog>: error: <message>', exit code 2."""


# ------------------------------------------------------------------------------------------------ registry


def train_binary(train=None):
    """hlt_train: the given path, else $HLT_BUILD_DIR/experiments/hlt_train, else build/experiments/hlt_train."""
    path = train_path(train)
    if not is_executable(path):
        raise ResultsError(f"{path} is not an executable hlt_train (build it with ./scripts/build.sh hlt_train, "
                           "or give --train or HLT_BUILD_DIR): its --help names the environments and methods")
    return path


class Registry:
    """The environments and methods hlt_train knows, in the order its --help lists them."""

    def __init__(self, envs, methods, source):
        self.envs, self.methods, self.source = list(envs), list(methods), source

    def method_key(self, method):
        """Sort key: registry order, then methods the registry does not know, alphabetically."""
        return (0, self.methods.index(method), "") if method in self.methods else (1, 0, method)

    def env_key(self, env):
        return (0, self.envs.index(env), "") if env in self.envs else (1, 0, env)

    def colour(self, method, known_extra=()):
        """A fixed colour per method (its registry index), so figures of different runs read alike."""
        palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]
        if method in self.methods:
            index = self.methods.index(method)
        else:
            extra = sorted(set(known_extra) - set(self.methods))
            index = len(self.methods) + (extra.index(method) if method in extra else 0)
        return palette[index % len(palette)]


def _help_names(text, option):
    for line in text.splitlines():
        m = re.match(r"\s*%s\s+TEXT\s+(.*)$" % re.escape(option), line)
        if m:
            names = re.sub(r"\(default [^)]*\)", "", m.group(1))
            return [n.strip() for n in names.split("|") if n.strip()]
    return []


def start_registry(train=None):
    """Starts `hlt_train --help` (LibTorch takes about a second to load), to be read by finish_registry."""
    path = train_binary(train)
    try:
        proc = subprocess.Popen([path, "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    except OSError as e:
        raise ResultsError(f"cannot run {path} --help: {e}")
    return path, proc


def finish_registry(started):
    """The Registry from a started `hlt_train --help`: its --env and --method lines, names split at ' | '."""
    path, proc = started
    try:
        out, _ = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise ResultsError(f"{path} --help did not end within 60 s")
    envs, methods = _help_names(out, "--env"), _help_names(out, "--method")
    if proc.returncode != 0 or not envs or not methods:
        raise ResultsError(f"{path} --help did not list environments and methods (exit {proc.returncode})")
    return Registry(envs, methods, path)


def registry(train=None):
    """The Registry read from `hlt_train --help`."""
    return finish_registry(start_registry(train))


def alphabetical_registry(names_envs, names_methods):
    """A stand-in when hlt_train is not built: alphabetical order (colours then differ from the registry's)."""
    return Registry(sorted(names_envs), sorted(names_methods), None)


# -------------------------------------------------------------------------------------------------- runs


def find_runs(paths):
    """Every directory at or below the given paths that holds scalars.csv and config.yaml, sorted."""
    runs = []
    for path in paths:
        if not os.path.isdir(path):
            raise ResultsError(f"{path} is not a directory")
        for root, dirs, files in os.walk(path):
            dirs.sort()
            if "scalars.csv" in files and "config.yaml" in files:
                runs.append(root)
    if not runs:
        raise ResultsError("no run directories (holding scalars.csv and config.yaml) under " + ", ".join(paths))
    return sorted(runs)


def top_level_value(config_path, key):
    """A top-level scalar of config.yaml, read without a YAML parser."""
    with open(config_path) as f:
        for line in f:
            if line.startswith(key + ":"):
                return line.split(":", 1)[1].strip().strip('"')
    return None


def read_yaml(path):
    """A YAML file's document (needs PyYAML); an unreadable or invalid file is a ResultsError naming it."""
    try:
        import yaml
    except ImportError:
        raise ResultsError("needs PyYAML: run with Debian's /usr/bin/python3 (apt-get install python3-yaml)")
    try:
        with open(path) as f:
            return yaml.safe_load(f)
    except OSError as e:
        raise ResultsError(f"cannot read {path}: {e.strerror}")
    except yaml.YAMLError as e:
        raise ResultsError(f"{path} is not valid YAML: {str(e).splitlines()[0]}")


def read_config(run):
    """config.yaml as a flat dict {'section.key': value} (needs PyYAML); the '# blas:' comment is skipped."""
    path = os.path.join(run, "config.yaml")
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise ResultsError(f"{path} is not an hlt_train config (not a mapping)")
    flat = {}

    def walk(prefix, node):
        for key, value in node.items():
            name = f"{prefix}{key}"
            if isinstance(value, dict):
                walk(name + ".", value)
            else:
                flat[name] = value

    walk("", doc)
    for key in ("env", "method", "seed"):
        if key not in flat:
            raise ResultsError(f"{path} has no top-level '{key}:' (not an hlt_train config)")
    return flat


def read_scalars(run):
    """{tag: (steps, values)} from the run's scalars.csv, in file order.

    A row with fewer or more than four fields (a line cut off by a killed run) is skipped; a wrong header or
    a row whose step or value is not a number is an error naming the file and line.
    """
    path = os.path.join(run, "scalars.csv")
    series = {}
    try:
        f = open(path, newline="")
    except OSError as e:
        raise ResultsError(f"cannot read {path}: {e.strerror}")
    with f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header != ["wall_time", "step", "tag", "value"]:
            raise ResultsError(f"{path} is not an hlt scalar log (header {header!r}, expected "
                               "wall_time,step,tag,value)")
        for row in reader:
            if len(row) != 4:
                continue
            try:
                step, tag, value = int(row[1]), row[2], float(row[3])
            except ValueError:
                raise ResultsError(f"{path}:{reader.line_num}: malformed row {','.join(row)!r} "
                                   "(step must be an integer, value a number)")
            entry = series.setdefault(tag, ([], []))
            entry[0].append(step)
            entry[1].append(value)
    return series


def sorted_curve(series, tag):
    """(steps, values) of a tag as arrays sorted by step, or None when the run did not log it."""
    if tag not in series or not series[tag][0]:
        return None
    xs, ys = np.asarray(series[tag][0]), np.asarray(series[tag][1], dtype=float)
    order = np.argsort(xs, kind="stable")
    return xs[order], ys[order]


def mean_band(curves, max_step=0):
    """Mean and std over runs on a common step grid (the union of steps, clipped to the shortest run)."""
    end = min(xs[-1] for xs, _ in curves)
    if max_step:
        end = min(end, max_step)
    grid = np.unique(np.concatenate([np.asarray(xs) for xs, _ in curves]))
    grid = grid[grid <= end]
    values = np.array([np.interp(grid, xs, ys) for xs, ys in curves])
    return grid, values.mean(axis=0), values.std(axis=0)


def last_common_step(curves, max_step=0):
    """The last step every curve reached (at most max_step when given)."""
    end = min(xs[-1] for xs, _ in curves)
    if max_step:
        end = min(end, max_step)
        # the last step at or before max_step that the curves logged, not max_step itself
        logged = np.unique(np.concatenate([xs[xs <= end] for xs, _ in curves]))
        end = int(logged[-1]) if len(logged) else end
    return int(end)


def values_at(curves, step):
    """Each curve's value at the step (linear interpolation between logged steps)."""
    return [float(np.interp(step, xs, ys)) for xs, ys in curves]
