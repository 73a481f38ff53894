#!/usr/bin/python3
"""End-to-end test of experiments/hlt_sweep.py with a real hlt_train and a real single-node Slurm.

  tests/sweep/test_sweep.py --train build/experiments/hlt_train

One small sweep (pendulum, SAC, 3 seeds, 400 agent steps, small networks) is run by the local engine (which
is interrupted with SIGTERM mid-run and re-run, so it resumes) and submitted to a private Slurm started by
tests/sweep/slurm_cluster.sh (one array task is requeued mid-run with `scontrol requeue` and resumes from its
checkpoint). The finished run directories of both engines must be equal: config.yaml byte for byte,
scalars.csv without its wall_time column and time/ tags. Also: status, a failing run (exit 1 from run), a
locked run left alone, bad sweep files. Where Slurm cannot start (not root, packages missing) the Slurm test
is skipped with the reason (HLT_REQUIRE_SLURM=1 turns that into a failure). Ends with 'N passed, M failed'.
"""

import argparse
import fcntl
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SWEEP = os.path.join(REPO, "experiments", "hlt_sweep.py")
CLUSTER = os.path.join(HERE, "slurm_cluster.sh")
TRAIN = None  # set by main()
WORK = None

SMALL_SWEEP = """\
# The test's sweep: 3 pendulum SAC runs of a few seconds each.
name: test
envs: [pendulum]
methods: [sac]
seeds: [0, 1, 2]
steps: 400
overrides:
  all:
    sac.q_hidden: [32, 32]
    train.update_after: 64
    train.batch_size: 32
    eval.every: 100
    eval.episodes: 2
    checkpoint.every: 100
"""


def write(path, text):
    with open(path, "w") as f:
        f.write(text)
    return path


def sweep_cmd(*args):
    return [sys.executable, SWEEP] + list(args) + ["--train", TRAIN]


def call(*args, env=None, timeout=120):
    proc = subprocess.run(sweep_cmd(*args), capture_output=True, text=True, env=env, timeout=timeout)
    return proc.returncode, proc.stdout + proc.stderr


def run_dirs(out):
    return [os.path.join(out, "pendulum", "sac", "seed%d" % s) for s in (0, 1, 2)]


def logged_steps(d):
    steps = 0
    try:
        with open(os.path.join(d, "scalars.csv")) as f:
            for line in f:
                fields = line.split(",")
                if len(fields) == 4 and fields[2] == "train/agent_steps":
                    steps = int(float(fields[3]))
    except OSError:
        pass
    return steps


def mid_run(d):
    """Past a checkpoint and at least 200 of the 400 agent steps still to go (a second or more)."""
    return (os.path.exists(os.path.join(d, "checkpoint.pt")) and not os.path.exists(os.path.join(d, "final.pt"))
            and logged_steps(d) <= 200)


def wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.02)
    raise AssertionError("timed out after %.0f s waiting for %s" % (timeout, what))


def comparable_log(path):
    """scalars.csv without the wall_time column and without time/ tags."""
    rows = []
    with open(path) as f:
        header = f.readline().strip()
        assert header == "wall_time,step,tag,value", header
        for line in f:
            _, step, tag, value = line.rstrip("\n").split(",")
            if not tag.startswith("time/"):
                rows.append((step, tag, value))
    return rows


def pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is dead too
        with open("/proc/%d/stat" % pid) as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def lock_pid(d):
    try:
        with open(os.path.join(d, ".lock")) as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


class Shared:
    """Directories the tests share: the local engine's result, compared with Slurm's."""
    local_out = None
    local_error = None


def local_engine_result():
    """Runs the small sweep with the local engine, interrupted once and resumed; cached for the tests."""
    if Shared.local_out or Shared.local_error:
        if Shared.local_error:
            raise AssertionError("the local engine's run failed earlier: " + Shared.local_error)
        return Shared.local_out
    out = os.path.join(WORK, "local")
    sweep = write(os.path.join(WORK, "small.yaml"), SMALL_SWEEP)
    try:
        # Seed 2 was killed the instant it started, before its first checkpoint (its log still empty): the
        # engine starts it over.
        d2 = run_dirs(out)[2]
        os.makedirs(d2)
        write(os.path.join(d2, "config.yaml"), "checkpoint:\n  every: 100\ntrain:\n  agent_steps: 400\n")
        write(os.path.join(d2, "scalars.csv"), "")
        write(os.path.join(d2, ".lock"), "")
        proc = subprocess.Popen(sweep_cmd("run", sweep, "--out", out, "--jobs", "2"), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        dirs = run_dirs(out)
        wait_for(lambda: any(mid_run(d) for d in dirs), 60, "a checkpoint of a local run")
        pids = [p for p in (lock_pid(d) for d in dirs) if p]
        proc.send_signal(signal.SIGTERM)
        output, _ = proc.communicate(timeout=30)
        assert proc.returncode == 143, "run after SIGTERM: exit %s\n%s" % (proc.returncode, output)
        assert "stopped (resumes on the next call)" in output, output
        for pid in pids:
            assert not pid_alive(pid), "hlt_train %d outlived the interrupted sweep" % pid
        code, output = call("status", sweep, "--out", out)
        assert code == 0 and "killed" in output, output
        code, output = call("run", sweep, "--out", out, "--jobs", "2")
        assert code == 0, output
        assert "resumed (killed at" in output, output
        assert "pendulum/sac/seed2: restarted (killed before its first checkpoint)" in output, output
        code, output = call("status", sweep, "--out", out)
        assert output.count(" done ") == 3 and "3 done" in output, output
    except Exception as e:
        Shared.local_error = str(e)
        raise
    Shared.local_out = out
    return out


class LocalEngine(unittest.TestCase):
    def test_run_interrupted_then_resumed_finishes_every_run(self):
        out = local_engine_result()
        for d in run_dirs(out):
            self.assertTrue(os.path.exists(os.path.join(d, "final.pt")), d)
        # A second call has nothing to do.
        code, output = call("run", os.path.join(WORK, "small.yaml"), "--out", out)
        self.assertEqual(code, 0, output)
        self.assertEqual(output.count("already done (400 agent steps)"), 3, output)

    def test_status_lists_every_state_and_progress(self):
        out = local_engine_result()
        sweep = write(os.path.join(WORK, "states.yaml"), SMALL_SWEEP.replace("seeds: [0, 1, 2]", "seeds: 0-4")
                      .replace("steps: 400", "steps:\n  default: 400\n  sac: 400"))
        # seed 3: a directory another process is writing (its .lock held); seed 4: never started.
        d3 = os.path.join(out, "pendulum", "sac", "seed3")
        os.makedirs(d3)
        write(os.path.join(d3, "config.yaml"), "train:\n  agent_steps: 400\n")
        with open(os.path.join(d3, ".lock"), "w") as lock:
            lock.write("%d\n" % os.getpid())
            lock.flush()
            fcntl.flock(lock, fcntl.LOCK_EX)
            code, output = call("status", sweep, "--out", out)
            self.assertEqual(code, 0, output)
            lines = {line.split()[0]: line.split() for line in output.splitlines()[1:-1]}
            self.assertEqual(lines["pendulum/sac/seed0"][1:3], ["done", "400/400"], output)
            self.assertEqual(lines["pendulum/sac/seed3"][1:3], ["running", "0/400"], output)
            self.assertIn("pid %d" % os.getpid(), output)
            self.assertEqual(lines["pendulum/sac/seed4"][1:3], ["missing", "0/400"], output)
            self.assertIn("5 run(s): 3 done, 1 running, 1 missing", output)
            # The locked run is left alone, the missing one fails with a bad override: exit 1, both reported.
            bad = write(os.path.join(WORK, "bad.yaml"),
                        SMALL_SWEEP.replace("seeds: [0, 1, 2]", "seeds: [3, 4]") + "    sac.lr: 5\n")
            code, output = call("run", bad, "--out", out)
        self.assertEqual(code, 1, output)
        self.assertIn("pendulum/sac/seed3: running elsewhere (pid %d; left alone)" % os.getpid(), output)
        self.assertIn("pendulum/sac/seed4: FAILED (exit 2: hlt_train: error: config key 'sac.lr'", output)
        self.assertIn("1 of 2 run(s) failed", output)
        code, output = call("status", bad, "--out", out)
        self.assertRegex(output, r"pendulum/sac/seed4 +failed +0/400 +exit 2: hlt_train: error")
        shutil.rmtree(d3)

    def test_bad_sweep_files_are_refused_with_exit_2(self):
        cases = {
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\n": "'steps' is missing",
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: 10\nseed: 3\n": "unknown key(s) seed",
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: -1\n": "positive integer",
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: {hopper: 5}\n": "steps.hopper names no",
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: 5\noverrides: {method: {mppi: [a=1]}}\n":
                "overrides.method.mppi",
            "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: 5\noverrides: [nokey]\n": "is not key=value",
        }
        for i, (text, message) in enumerate(cases.items()):
            path = write(os.path.join(WORK, "broken%d.yaml" % i), text)
            code, output = call("status", path, "--out", os.path.join(WORK, "nowhere"))
            self.assertEqual(code, 2, text + output)
            self.assertIn(message, output, text)


class SlurmEngine(unittest.TestCase):
    cluster = None
    env = None

    @classmethod
    def setUpClass(cls):
        cls.cluster = os.path.join(WORK, "cluster")
        proc = subprocess.run(["bash", CLUSTER, "start", cls.cluster], capture_output=True, text=True,
                              timeout=90)
        if proc.returncode != 0:
            reason = (proc.stderr.strip() or proc.stdout.strip()).splitlines()
            reason = reason[0] if reason else "exit %d" % proc.returncode
            subprocess.run(["bash", CLUSTER, "stop", cls.cluster], capture_output=True, timeout=90)
            if os.environ.get("HLT_REQUIRE_SLURM") == "1":
                raise AssertionError("Slurm did not start: " + reason)
            raise unittest.SkipTest("Slurm cannot start on this machine: " + reason)
        cls.env = dict(os.environ, SLURM_CONF=os.path.join(cls.cluster, "slurm.conf"))

    @classmethod
    def tearDownClass(cls):
        subprocess.run(["bash", CLUSTER, "stop", cls.cluster], capture_output=True, timeout=120)

    def slurm(self, *args, check=True):
        proc = subprocess.run(list(args), capture_output=True, text=True, env=self.env, timeout=30)
        if check:
            self.assertEqual(proc.returncode, 0, "%s: %s" % (" ".join(args), proc.stderr))
        return proc

    def test_requeued_task_resumes_and_the_runs_equal_the_local_engines(self):
        local = local_engine_result()
        out = os.path.join(WORK, "slurm")
        sweep = os.path.join(WORK, "small.yaml")
        proc = subprocess.Popen(sweep_cmd("submit", sweep, "--out", out, "--cpus-per-task", "1", "--mem", "1G",
                                          "--time", "10:00", "--wait", "--poll", "0.5"),
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=self.env)
        try:
            first = proc.stdout.readline()
            self.assertIn("submitted job", first)
            job = first.split("submitted job ")[1].split(":")[0]
            self.assertIn("array 0-2", first)
            # Two 1-CPU tasks fit the node at once: the third is queued, or running already.
            code, output = call("status", sweep, "--out", out, env=self.env)
            self.assertEqual(code, 0, output)
            self.assertRegex(output, r"pendulum/sac/seed2 +(queued|running|done) ")
            # Requeue task 1 once it has a checkpoint and before it finishes (what preemption does).
            target = run_dirs(out)[1]
            wait_for(lambda: mid_run(target), 60, "a checkpoint of Slurm task 1")
            killed_pid = lock_pid(target)
            self.slurm("scontrol", "requeue", "%s_1" % job)
            # The requeued task may start again once the killed one's credential expired (cred_expire=5 in
            # the test cluster's slurm.conf; 120 s by default).
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                state = self.slurm("squeue", "-h", "-j", "%s_1" % job, "-o", "%T", check=False).stdout.strip()
                if state == "RUNNING" and lock_pid(target) != killed_pid:
                    break
                time.sleep(0.2)
            if killed_pid:
                self.assertFalse(pid_alive(killed_pid), "the requeued task's hlt_train still runs")
            self.assertNotEqual(lock_pid(target), killed_pid, "the requeued task did not start again in 30 s")
            rest, _ = proc.communicate(timeout=90)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        self.assertEqual(proc.returncode, 0, first + rest)
        self.assertIn("test: 3 run(s): 3 done", rest)
        log = open(os.path.join(out, "slurm", "%s_1.out" % job)).read()
        self.assertIn("restart 1", log)
        self.assertRegex(log, r"pendulum/sac/seed1: resumed \((killed|failed) at \d+ agent steps\); done: 400")
        for index in range(3):
            self.assertTrue(os.path.exists(os.path.join(out, "slurm", "%s_%d.out" % (job, index))), index)

        for a, b in zip(run_dirs(local), run_dirs(out)):
            with open(os.path.join(a, "config.yaml")) as fa, open(os.path.join(b, "config.yaml")) as fb:
                self.assertEqual(fa.read(), fb.read(), b)
            la, lb = comparable_log(os.path.join(a, "scalars.csv")), comparable_log(os.path.join(b, "scalars.csv"))
            self.assertGreater(len(la), 20)
            self.assertEqual(la, lb, b)

        # Re-submitting a finished sweep submits nothing; status reads the same from either engine's tree.
        code, output = call("submit", sweep, "--out", out, env=self.env)
        self.assertEqual(code, 0, output)
        self.assertIn("nothing to submit", output)
        code, output = call("status", sweep, "--out", out, env=self.env)
        self.assertIn("test: 3 run(s): 3 done", output)


def main():
    global TRAIN, WORK
    parser = argparse.ArgumentParser()
    parser.add_argument("--train", default=os.environ.get("HLT_TRAIN_BIN"),
                        help="hlt_train (default $HLT_TRAIN_BIN)")
    parser.add_argument("--keep", action="store_true", help="keep the work directory")
    args = parser.parse_args()
    if not args.train or not os.access(args.train, os.X_OK):
        print("test_sweep: give --train PATH to a built hlt_train", file=sys.stderr)
        return 2
    TRAIN = os.path.abspath(args.train)
    WORK = tempfile.mkdtemp(prefix="hlt_sweep_test.")
    os.chmod(WORK, 0o755)  # munged (user munge) must reach the cluster's directory inside it
    start = time.monotonic()
    try:
        loader = unittest.TestLoader()
        suite = unittest.TestSuite()
        for case in (LocalEngine, SlurmEngine):
            suite.addTests(loader.loadTestsFromTestCase(case))
        result = unittest.TextTestRunner(verbosity=2).run(suite)
    finally:
        if args.keep:
            print("work directory kept: " + WORK)
        else:
            subprocess.run(["bash", CLUSTER, "stop", os.path.join(WORK, "cluster")], capture_output=True)
            shutil.rmtree(WORK, ignore_errors=True)
    failed = len(result.failures) + len(result.errors) + len(result.unexpectedSuccesses)
    skipped_run, skipped = 0, 0
    for test, reason in result.skipped:
        if isinstance(test, unittest.TestCase):
            skipped_run += 1
            skipped += 1
        else:  # a class skipped in setUpClass: its tests never ran
            skipped += loader.loadTestsFromTestCase(SlurmEngine).countTestCases()
        name = test.id().split(".", 1)[-1] if isinstance(test, unittest.TestCase) else "SlurmEngine (every test)"
        print("skipped: %s: %s" % (name, reason))
    passed = result.testsRun - failed - skipped_run
    print("test_sweep: %.0f s" % (time.monotonic() - start))
    print("%d passed, %d failed, %d skipped" % (passed, failed, skipped))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
