#!/usr/bin/python3
"""Test of experiments/hlt_figures.py (and hlt_plot.py's registry order) on a small synthetic results tree.

  tests/sweep/test_figures.py --train build/experiments/hlt_train

The tree is written by the test: fake config.yaml and scalars.csv files with known values, for a few methods
on the cart-pole, the pendulum and the ant (an imitation run), with a config variant and methods missing.
The final-return table must hold the means and standard deviations worked out by hand, in the registry's
order (hlt_train --help), with the published numbers beside ours; the figures must be PNGs; missing methods
are notes, not failures; --update rewrites only the marked sections; --sweep uses only its runs and reports
the missing ones; a malformed scalars.csv, a seed given twice and bad markers are errors (exit 2) naming the
file. A few seconds. Ends with 'N passed, M failed'.
"""

import argparse
import functools
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
FIGURES = os.path.join(REPO, "experiments", "hlt_figures.py")
PLOT = os.path.join(REPO, "experiments", "hlt_plot.py")
TRAIN = None  # set by main()
WORK = None

CONFIG = """\
# blas: a comment line as hlt_train writes it
checkpoint:
  every: 5000
env: "{env}"
eval:
  components: true
  episodes: 5
  every: 1000
method: "{method}"
planner:
  horizon: {horizon}
  samples: 20
policy:
  hidden: [128]
seed: {seed}
threads: 1
train:
  agent_steps: {agent_steps}
  frame_skip: 4
"""


def write(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)
    return path


def make_run(root, env, method, seed, series, horizon=5, subdir=None, agent_steps=2000):
    """A run directory with config.yaml and scalars.csv; series: {tag: [(env step, value), ...]}. Without a
    train/agent_steps series one row is added at the last step, as a run of fixed-length episodes logs it."""
    run = os.path.join(root, subdir or env, method, f"seed{seed}")
    write(os.path.join(run, "config.yaml"), CONFIG.format(env=env, method=method, seed=seed, horizon=horizon,
                                                           agent_steps=agent_steps))
    rows = ["wall_time,step,tag,value"]
    for tag, points in series.items():
        for step, value in points:
            rows.append(f"1796150000.5,{step},{tag},{value!r}")
    if "train/agent_steps" not in series:
        last = max(step for points in series.values() for step, _ in points)
        rows.append(f"1796150000.5,{last},train/agent_steps,{last // 4}")
    write(os.path.join(run, "scalars.csv"), "\n".join(rows) + "\n")
    return run


def ramp(final, steps=(0, 4000, 8000), start=-1000.0):
    """An evaluation curve from start to final over the steps (the last value exactly final)."""
    n = len(steps) - 1
    return [(s, start + (final - start) * i / n) for i, s in enumerate(steps)]


def build_tree(root):
    for seed, final in enumerate([800.0, 850.0, 900.0]):
        make_run(root, "cartpole_swingup", "hybrid-stochastic", seed, {
            "eval/return_mean": ramp(final),
            "eval/policy_return_mean": ramp(final - 300),
            "eval/planner_return_mean": ramp(final - 100),
        })
    # seed 3 with another planner horizon: a variant of its own, not pooled with seeds 0-2
    make_run(root, "cartpole_swingup", "hybrid-stochastic", 3, {"eval/return_mean": ramp(100.0)}, horizon=7)
    # SAC: seed 1 ran longer; the final value is taken at the last step both reached (8000)
    make_run(root, "cartpole_swingup", "sac", 0, {"eval/return_mean": ramp(100.0)})
    make_run(root, "cartpole_swingup", "sac", 1, {"eval/return_mean": ramp(300.0) + [(12000, 700.0)]},
             agent_steps=3000)
    make_run(root, "cartpole_swingup", "hybrid-deterministic", 0, {
        "eval/return_mean": ramp(500.0),
        "train/mode_insertion_gradient": [(1000, 5.0), (2000, 3.0), (3000, 1.0), (8000, 0.5)],
    })
    for seed, final in enumerate([-200.0, -100.0]):
        make_run(root, "pendulum", "hybrid-deterministic", seed, {
            "eval/return_mean": ramp(final, start=-1500.0),
            "train/mode_insertion_gradient": [(0, 2.0), (8000, 0.1)],
        })
    # pendulum hybrid-stochastic: two variants of one seed each (the first directory's is the main one); its
    # other variant differs in another key than the cart-pole's, so it gets a row of its own
    make_run(root, "pendulum", "hybrid-stochastic", 0, {"eval/return_mean": ramp(-120.0, start=-1500.0)})
    make_run(root, "pendulum", "hybrid-stochastic", 1, {"eval/return_mean": ramp(-130.0, start=-1500.0)},
             horizon=9)
    # an imitation run: demonstrations 1, 2, 3 at steps 1000, 2000, 3000
    make_run(root, "ant", "hybrid-stochastic", 0, {
        "eval/return_mean": ramp(50.0),
        "imitation/demonstrations": [(1000, 1), (2000, 2), (3000, 3)],
        "imitation/expert_return": [(1000, 2300.0), (2000, 2300.0), (3000, 2300.0)],
        "imitation/test_return": [(1000, 300.0), (2000, 1200.0), (3000, 2100.0)],
        "imitation/policy_return": [(1000, 100.0), (2000, 400.0), (3000, 900.0)],
        "imitation/eval_success_rate": [(1000, 0.0), (2000, 0.5), (3000, 1.0)],
    })
    # an imitation run that also scored each count over several test episodes: those means are its curve
    make_run(root, "ant", "bc", 0, {
        "imitation/demonstrations": [(1000, 1), (2000, 2), (3000, 3)],
        "imitation/test_return": [(1000, 10.0), (2000, 20.0), (3000, 30.0)],
        "imitation/eval_return_mean": [(1000, 250.0), (2000, 650.0), (3000, 1050.0)],
        "imitation/policy_return": [(1000, 10.0), (2000, 20.0), (3000, 30.0)],
    })
    # a robot task learnt online: seed 0 succeeds from its 3rd episode on, seed 1 never (episodes of 100
    # steps at steps 100, 200, ...; 12 episodes)
    for seed, first in ((0, 3), (1, None)):
        make_run(root, "block_push", "hybrid-stochastic", seed, {
            "eval/return_mean": [(0, -50.0), (1200, -20.0)],
            "train/episodes": [(100 * e, e) for e in range(1, 13)],
            "train/success": [(100 * e, 1.0 if first and e >= first else 0.0) for e in range(1, 13)],
            "train/episode_return": [(100 * e, -10.0 * seed - e) for e in range(1, 13)],
        })


def run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def figures(*args):
    return run(["/usr/bin/python3", FIGURES] + list(args) + ["--train", TRAIN])


@functools.lru_cache(maxsize=None)
def registry_methods():
    out = run([TRAIN, "--help"]).stdout
    line = next(l for l in out.splitlines() if l.strip().startswith("--method"))
    return [m.strip() for m in line.split("TEXT", 1)[1].split("|")]


def section(text, name):
    m = re.search(r"<!-- hlt_figures:BEGIN %s -->\n(.*?)\n<!-- hlt_figures:END %s -->" % (name, name), text, re.S)
    assert m, f"section {name} missing"
    return m.group(1)


def table_cells(text):
    """{row label: {column: cell}} of the markdown table in the 'table' section."""
    lines = [l for l in section(text, "table").splitlines() if l.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    rows = {}
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = dict(zip(header[1:], cells[1:]))
    return header, rows


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    assert head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


class Figures(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tree = os.path.join(WORK, "results")
        build_tree(cls.tree)
        cls.out = os.path.join(WORK, "figures")
        cls.doc = write(os.path.join(WORK, "docs", "RESULTS.md"),
                        "# Results\n\nHand-written text stays.\n\n"
                        "<!-- hlt_figures:BEGIN table -->\nold table\n<!-- hlt_figures:END table -->\n\n"
                        "More text.\n\n<!-- hlt_figures:BEGIN fig1 -->\n<!-- hlt_figures:END fig1 -->\n")
        cls.result = figures(cls.tree, "--out", cls.out, "--update", cls.doc)
        with open(os.path.join(cls.out, "results.md")) as f:
            cls.markdown = f.read()

    def test_exits_0_and_writes_every_figure_as_png(self):
        self.assertEqual(self.result.returncode, 0, self.result.stderr)
        for name in ("fig1_deterministic.png", "fig2_stochastic.png", "fig4_components_cartpole_swingup.png",
                     "fig5_imitation.png"):
            width, height = png_size(os.path.join(self.out, name))
            self.assertGreater(width, 300, name)
            self.assertGreater(height, 200, name)
        # the pendulum's hybrid-deterministic logged no components: no Fig. 4 for it
        self.assertFalse(os.path.exists(os.path.join(self.out, "fig4_components_pendulum.png")))

    def test_table_holds_the_hand_computed_means_and_stds_with_the_papers_numbers(self):
        header, rows = table_cells(self.markdown)
        # cart-pole hybrid-stochastic seeds 0-2: 800, 850, 900 -> mean 850, std sqrt(5000/3) = 40.82
        self.assertEqual(rows["hybrid-stochastic"]["cartpole_swingup"],
                         "850.0 +- 40.8 (n=3, 8000 env steps (2000 agent steps)); paper 972.6 +- 2.2")
        # SAC seeds 0, 1 at their last common step 8000: 100, 300 -> 200 +- 100
        self.assertEqual(rows["sac"]["cartpole_swingup"],
                         "200.0 +- 100.0 (n=2, 8000 env steps (2000 agent steps)); paper 740.4 +- 197.5")
        self.assertEqual(rows["hybrid-deterministic"]["pendulum"],
                         "-150.0 +- 50.0 (n=2, 8000 env steps (2000 agent steps))")
        # the variant is a row of its own, without the paper's number
        self.assertEqual(rows["hybrid-stochastic [planner.horizon=7]"]["cartpole_swingup"],
                         "100.0 +- 0.0 (n=1, 8000 env steps (2000 agent steps))")
        self.assertEqual(rows["hybrid-stochastic [planner.horizon=7]"]["pendulum"], "-")
        self.assertEqual(rows["hybrid-stochastic"]["pendulum"],
                         "-120.0 +- 0.0 (n=1, 8000 env steps (2000 agent steps))")
        self.assertEqual(rows["hybrid-stochastic [planner.horizon=9]"]["pendulum"],
                         "-130.0 +- 0.0 (n=1, 8000 env steps (2000 agent steps))")
        self.assertEqual(rows["hybrid-stochastic [planner.horizon=9]"]["cartpole_swingup"], "-")
        # the published layout: acrobot is a column (paper numbers only), methods without runs are rows
        self.assertIn("acrobot", header)
        self.assertEqual(rows["mppi"]["acrobot"], "paper -55.2 +- 13.9")
        self.assertEqual(rows["mppi"]["cartpole_swingup"], "paper 947.7 +- 39.1")
        self.assertEqual(rows["hybrid-deterministic"]["ant"], "-")

    def test_rows_and_columns_follow_the_registry(self):
        _, rows = table_cells(self.markdown)
        methods = [r.split(" [")[0] for r in rows]
        order = registry_methods()
        self.assertEqual(sorted(set(methods), key=order.index), list(dict.fromkeys(methods)))
        seeds = section(self.markdown, "seeds")
        self.assertIn("| 0: 800.0, 1: 850.0, 2: 900.0 |", seeds)
        self.assertIn("| 0: 100.0, 1: 300.0 |", seeds)

    def test_missing_methods_are_notes_not_failures(self):
        notes = section(self.markdown, "notes")
        self.assertIn("Fig. 1, cartpole_swingup: no runs of mpc-deterministic", notes)
        self.assertIn("Fig. 2, cartpole_swingup: no runs of mppi", notes)
        self.assertIn("note: Fig. 2, cartpole_swingup: no runs of mppi", self.result.stdout)

    def test_every_figure_says_its_seeds_and_steps(self):
        fig1 = section(self.markdown, "fig1")
        self.assertIn("](fig1_deterministic.png)", fig1)
        self.assertIn("pendulum, evaluation return: hybrid-deterministic, 2 seeds, steps 0-8000", fig1)
        self.assertIn("cartpole_swingup, mode insertion gradient: hybrid-deterministic, 1 seed, steps 0-8000", fig1)
        fig5 = section(self.markdown, "fig5")
        self.assertIn("ant, hybrid-stochastic: 1 seed, 1-3 demonstrations", fig5)
        self.assertIn("ant, hybrid-stochastic, policy alone: 1 seed, 1-3 demonstrations", fig5)
        self.assertIn("ant, expert: 1 seed, 1-3 demonstrations", fig5)
        # the values per count, computed by hand from the run above
        self.assertIn("| expert | 1 | 2300 +- 0 | 2300 +- 0 | 2300 +- 0 |", fig5)
        self.assertIn("| hybrid-stochastic | 1 | 300 +- 0 | 1200 +- 0 | 2100 +- 0 |", fig5)
        self.assertIn("| hybrid-stochastic, policy alone | 1 | 100 +- 0 | 400 +- 0 | 900 +- 0 |", fig5)
        self.assertIn("| bc | 1 | 250 +- 0 | 650 +- 0 | 1050 +- 0 |", fig5)  # the means, not the one episode

    def test_robot_tasks_get_success_per_episode_and_per_count(self):
        robot = section(self.markdown, "robot")
        self.assertIn("](robot_block_push.png)", robot)
        # seed 0: first success at episode 3, 8 of 10 then 2 of 2; seed 1: none; the mean return of episodes
        # 3-12: seed 0 -(3 + ... + 12) / 10, seed 1 that minus 10
        self.assertIn("| hybrid-stochastic | 0 | 3 | 8/10 | 2/2 |  | -7.5 |", robot)
        self.assertIn("| hybrid-stochastic | 1 | none | 0/10 | 0/2 |  | -17.5 |", robot)
        self.assertIn("| hybrid-stochastic | seeds succeeding within 20 episodes | 1 of 2 |", robot)
        self.assertTrue(os.path.exists(os.path.join(self.out, "robot_block_push.png")))
        fig5 = section(self.markdown, "fig5")
        self.assertIn("| hybrid-stochastic | 1 | 0.00 +- 0.00 | 0.50 +- 0.00 | 1.00 +- 0.00 |", fig5)

    def test_update_rewrites_only_the_marked_sections(self):
        with open(self.doc) as f:
            text = f.read()
        self.assertTrue(text.startswith("# Results\n\nHand-written text stays.\n\n<!-- hlt_figures:BEGIN table -->"))
        self.assertIn("<!-- hlt_figures:END table -->\n\nMore text.\n\n<!-- hlt_figures:BEGIN fig1 -->", text)
        self.assertNotIn("old table", text)
        self.assertEqual(section(text, "table"), section(self.markdown, "table"))
        self.assertIn("](../figures/fig1_deterministic.png)", section(text, "fig1"))  # relative to the file
        self.assertNotIn("hlt_figures:BEGIN seeds", text)

    def test_sweep_selects_its_runs_and_reports_missing_ones(self):
        sweep = write(os.path.join(WORK, "pendulum.yaml"),
                      "envs: [pendulum]\nmethods: [hybrid-deterministic, hybrid-stochastic]\nseeds: 0-2\n"
                      "steps: 2000\n")
        r = figures(self.tree, "--out", os.path.join(WORK, "sweep_figs"), "--sweep", sweep,
                    "--pool-key", "planner.horizon")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(WORK, "sweep_figs", "results.md")) as f:
            text = f.read()
        provenance = section(text, "provenance")
        self.assertIn("(6 runs, 4 found; missing: pendulum/hybrid-deterministic seed 2; "
                      "pendulum/hybrid-stochastic seed 2)", provenance)
        self.assertIn("seeds: 0-2", provenance)  # the sweep file itself, verbatim
        self.assertIn("from 4 runs", provenance)
        self.assertIn("`planner.horizon` (`--pool-key`)", provenance)
        _, rows = table_cells(text)
        # --pool-key: the two horizons pooled, -120 and -130
        self.assertEqual(rows["hybrid-stochastic"]["pendulum"],
                         "-125.0 +- 5.0 (n=2, 8000 env steps (2000 agent steps))")
        self.assertEqual(rows["sac"]["cartpole_swingup"], "paper 740.4 +- 197.5")  # not in the sweep: left out

    def test_a_run_whose_last_episode_was_cut_by_the_budget_is_not_short(self):
        # Hopper-like logs: episodes end early, so the last logged train/agent_steps (1925) is below the
        # budget (2000) by less than one episode (800 env steps = 200 agent steps). Seed 0 then logged its
        # final evaluation and finished; seed 1 was killed in that last episode.
        root = os.path.join(WORK, "cut_tree")
        for seed, evals in ((0, [(0, -10.0), (4000, 5.0), (7950, 9.0)]), (1, [(0, -10.0), (4000, 5.0)])):
            make_run(root, "hopper", "sac", seed, {"eval/return_mean": evals, "train/episode_length": [(7700, 800)],
                                                   "train/agent_steps": [(7700, 1925)]})
        sweep = write(os.path.join(WORK, "cut.yaml"), "envs: [hopper]\nmethods: [sac]\nseeds: 0-1\nsteps: 2000\n")
        r = figures(root, "--out", os.path.join(WORK, "cut_figs"), "--sweep", sweep)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(WORK, "cut_figs", "results.md")) as f:
            provenance = section(f.read(), "provenance")
        self.assertIn("short of their budget: hopper/sac seed 1)", provenance)
        self.assertNotIn("short of their budget: hopper/sac seeds", provenance)

    def test_hlt_plot_orders_methods_by_the_registry(self):
        r = run(["/usr/bin/python3", PLOT, os.path.join(self.tree, "cartpole_swingup"), "--out",
                 os.path.join(WORK, "plot.png"), "--table", "--train", TRAIN])
        self.assertEqual(r.returncode, 0, r.stderr)
        methods = [l.split("|")[1].strip() for l in r.stdout.splitlines() if l.startswith("| ")][1:]
        order = registry_methods()
        self.assertEqual(methods, sorted(methods, key=order.index))
        png_size(os.path.join(WORK, "plot.png"))


class Errors(unittest.TestCase):
    def copy_tree(self, name):
        root = os.path.join(WORK, name)
        make_run(root, "pendulum", "sac", 0, {"eval/return_mean": ramp(-300.0)})
        make_run(root, "pendulum", "sac", 1, {"eval/return_mean": ramp(-200.0)})
        return root

    def assert_error(self, r, *needles):
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertTrue(r.stderr.startswith("hlt_figures: error: "), r.stderr)
        self.assertNotIn("Traceback", r.stderr)
        for needle in needles:
            self.assertIn(needle, r.stderr)

    def test_malformed_scalars_csv_is_an_error_naming_the_file_and_line(self):
        root = self.copy_tree("bad_row")
        path = os.path.join(root, "pendulum", "sac", "seed1", "scalars.csv")
        with open(path, "a") as f:
            f.write("1796150000.5,four thousand,eval/return_mean,1.0\n")
        self.assert_error(figures(root, "--out", os.path.join(WORK, "x")), path + ":", "malformed row")

    def test_a_wrong_header_is_an_error_naming_the_file(self):
        root = self.copy_tree("bad_header")
        path = os.path.join(root, "pendulum", "sac", "seed0", "scalars.csv")
        write(path, "step;tag;value\n0;eval/return_mean;1\n")
        self.assert_error(figures(root, "--out", os.path.join(WORK, "x")), path, "not an hlt scalar log")

    def test_a_seed_twice_is_an_error(self):
        root = self.copy_tree("twice")
        make_run(root, "pendulum", "sac", 0, {"eval/return_mean": ramp(-250.0)}, subdir="rerun")
        self.assert_error(figures(root, "--out", os.path.join(WORK, "x")), "seed 0")

    def test_no_runs_and_bad_markers_are_errors(self):
        empty = os.path.join(WORK, "empty")
        os.makedirs(empty, exist_ok=True)
        self.assert_error(figures(empty, "--out", os.path.join(WORK, "x")), "no run directories")
        root = self.copy_tree("markers")
        doc = write(os.path.join(WORK, "bad.md"), "<!-- hlt_figures:BEGIN table -->\nno end\n")
        self.assert_error(figures(root, "--out", os.path.join(WORK, "x"), "--update", doc), doc, "no <!--")
        doc = write(os.path.join(WORK, "typo.md"), "<!-- hlt_figures:BEGIN tabel -->\n<!-- hlt_figures:END tabel -->\n")
        self.assert_error(figures(root, "--out", os.path.join(WORK, "x"), "--update", doc), "unknown section")
        with open(doc) as f:
            self.assertIn("tabel", f.read())  # left as it was


def main():
    global TRAIN, WORK
    parser = argparse.ArgumentParser()
    parser.add_argument("--train", default=os.environ.get("HLT_TRAIN_BIN"), help="hlt_train (default $HLT_TRAIN_BIN)")
    parser.add_argument("--keep", action="store_true", help="keep the work directory")
    args = parser.parse_args()
    if not args.train or not os.access(args.train, os.X_OK):
        print("test_figures: give --train PATH to a built hlt_train", file=sys.stderr)
        return 2
    TRAIN = os.path.abspath(args.train)
    WORK = tempfile.mkdtemp(prefix="hlt_figures_test.")
    try:
        suite = unittest.TestSuite()
        for case in (Figures, Errors):
            suite.addTests(unittest.TestLoader().loadTestsFromTestCase(case))
        result = unittest.TextTestRunner(verbosity=2).run(suite)
    finally:
        if args.keep:
            print("work directory kept: " + WORK)
        else:
            shutil.rmtree(WORK, ignore_errors=True)
    failed = len(result.failures) + len(result.errors)
    print("%d passed, %d failed" % (result.testsRun - failed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
