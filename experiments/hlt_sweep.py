#!/usr/bin/python3
"""Runs a sweep (environments x methods x seeds, described in a YAML file) with hlt_train, on a local
process pool or as a Slurm job array, and reports its state.

  experiments/hlt_sweep.py run    SWEEP.yaml --out DIR [--jobs N]
  experiments/hlt_sweep.py submit SWEEP.yaml --out DIR [--partition P] [--time T] [--cpus-per-task C]
                                  [--mem M] [--wait] [--all]
  experiments/hlt_sweep.py status SWEEP.yaml --out DIR

Every run lives in DIR/<env>/<method>/seed<seed>; beside it seed<seed>.out keeps hlt_train's output and
seed<seed>.failed the last failure. Both engines call the same per-run logic (`run_one`): a finished run
is skipped, a killed one resumed with `hlt_train --resume`, a run another process is writing (its .lock is
held) left alone, a run killed before its first checkpoint started afresh. A Slurm array task is
`hlt_sweep.py task SWEEP.yaml --out DIR --index I`, so a requeued task resumes from its last checkpoint.
Exit codes: 0 every run done (or left alone while running elsewhere), 1 some run failed or is unfinished,
2 bad sweep file or arguments, 130/143 interrupted (the runs stop and resume on the next call).
"""

import argparse
import errno
import fcntl
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

try:
    import yaml
except ImportError:  # pragma: no cover (main() says so; hlt_results imports this module without needing it)
    yaml = None

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROG = "hlt_sweep"


class SweepError(Exception):
    """A bad sweep file or argument: reported in one line, exit code 2."""


# ----------------------------------------------------------------------------------------------- sweep file


def override_value(value):
    """A YAML value as hlt_train's key=value syntax: lists as [a,b], booleans as true/false."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(override_value(v) for v in value) + "]"
    if value is None:
        raise SweepError("an override has no value")
    return str(value)


def override_list(spec, where):
    """Overrides given as a list of 'key=value' strings or as a mapping key: value."""
    if spec is None:
        return []
    if isinstance(spec, dict):
        return ["%s=%s" % (k, override_value(v)) for k, v in spec.items()]
    if isinstance(spec, str):
        spec = [spec]
    if isinstance(spec, list):
        out = []
        for item in spec:
            if not isinstance(item, str) or "=" not in item:
                raise SweepError("%s: override %r is not key=value" % (where, item))
            out.append(item)
        return out
    raise SweepError("%s: overrides must be a list of key=value or a mapping" % where)


def name_list(spec, field):
    if isinstance(spec, str):
        spec = spec.split()
    if not isinstance(spec, list) or not spec or not all(isinstance(s, str) and s for s in spec):
        raise SweepError("'%s' must be a non-empty list of names" % field)
    if len(set(spec)) != len(spec):
        raise SweepError("'%s' names something twice" % field)
    return spec


def seed_list(spec):
    """Seeds: a list of integers, one integer, or a range 'A-B' (both included)."""
    if isinstance(spec, int) and not isinstance(spec, bool):
        spec = [spec]
    if isinstance(spec, str):
        m = re.fullmatch(r"\s*(\d+)\s*-\s*(\d+)\s*", spec)
        if not m or int(m.group(1)) > int(m.group(2)):
            raise SweepError("'seeds': %r is not a list or a range like 0-4" % spec)
        spec = list(range(int(m.group(1)), int(m.group(2)) + 1))
    if not isinstance(spec, list) or not spec or not all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in spec):
        raise SweepError("'seeds' must be a non-empty list of non-negative integers")
    if len(set(spec)) != len(spec):
        raise SweepError("'seeds' names a seed twice")
    return spec


def positive_steps(value, where):
    if not isinstance(value, int) or isinstance(value, bool) or value <= 0:
        raise SweepError("%s: agent steps must be a positive integer, got %r" % (where, value))
    return value


class Run:
    def __init__(self, index, env, method, seed, steps, overrides, out):
        self.index, self.env, self.method, self.seed = index, env, method, seed
        self.steps, self.overrides = steps, overrides
        self.name = "%s/%s/seed%d" % (env, method, seed)
        self.dir = os.path.join(out, env, method, "seed%d" % seed)
        self.log = self.dir + ".out"
        self.failed_file = self.dir + ".failed"


class Sweep:
    TOP_KEYS = {"name", "envs", "methods", "seeds", "steps", "overrides"}

    def __init__(self, path):
        self.path = os.path.abspath(path)
        try:
            with open(path) as f:
                doc = yaml.safe_load(f)
        except OSError as e:
            raise SweepError("cannot read %s: %s" % (path, e.strerror))
        except yaml.YAMLError as e:
            raise SweepError("%s is not valid YAML: %s" % (path, str(e).replace("\n", " ")))
        if not isinstance(doc, dict):
            raise SweepError("%s: a sweep is a mapping (envs, methods, seeds, steps, overrides)" % path)
        unknown = sorted(set(doc) - self.TOP_KEYS)
        if unknown:
            raise SweepError("%s: unknown key(s) %s (allowed: %s)" % (
                path, ", ".join(map(str, unknown)), ", ".join(sorted(self.TOP_KEYS))))
        for key in ("envs", "methods", "seeds", "steps"):
            if key not in doc:
                raise SweepError("%s: '%s' is missing" % (path, key))
        self.name = str(doc.get("name") or os.path.splitext(os.path.basename(path))[0])
        self.envs = name_list(doc["envs"], "envs")
        self.methods = name_list(doc["methods"], "methods")
        self.seeds = seed_list(doc["seeds"])
        self.steps = doc["steps"]
        if isinstance(self.steps, dict):
            for key, value in self.steps.items():
                positive_steps(value, "steps.%s" % key)
                if key != "default" and not self._budget_key_known(str(key)):
                    raise SweepError("%s: steps.%s names no environment, method or environment/method of "
                                     "this sweep" % (path, key))
        else:
            positive_steps(self.steps, "steps")
        ov = doc.get("overrides") or {}
        if isinstance(ov, list):
            ov = {"all": ov}
        if not isinstance(ov, dict):
            raise SweepError("%s: 'overrides' must be a list or a mapping (all, env, method)" % path)
        unknown = sorted(set(ov) - {"all", "env", "method"})
        if unknown:
            raise SweepError("%s: unknown overrides section(s) %s (allowed: all, env, method)" % (
                path, ", ".join(map(str, unknown))))
        self.global_overrides = override_list(ov.get("all"), "overrides.all")
        self.env_overrides, self.method_overrides = {}, {}
        for section, names, target in (("env", self.envs, self.env_overrides),
                                       ("method", self.methods, self.method_overrides)):
            spec = ov.get(section) or {}
            if not isinstance(spec, dict):
                raise SweepError("%s: overrides.%s maps a name to its overrides" % (path, section))
            for name, items in spec.items():
                if name not in names:
                    raise SweepError("%s: overrides.%s.%s: not one of this sweep's %ss" % (
                        path, section, name, section))
                target[name] = override_list(items, "overrides.%s.%s" % (section, name))

    def _budget_key_known(self, key):
        if "/" in key:
            env, _, method = key.partition("/")
            return env in self.envs and method in self.methods
        return key in self.envs or key in self.methods

    def budget(self, env, method):
        """Agent steps for a run: steps.<env>/<method>, steps.<env>, steps.<method>, steps.default."""
        if not isinstance(self.steps, dict):
            return self.steps
        for key in ("%s/%s" % (env, method), env, method, "default"):
            if key in self.steps:
                return self.steps[key]
        raise SweepError("%s: no budget for %s/%s (give steps.default)" % (self.path, env, method))

    def runs(self, out):
        """Every run, in array-index order: environments, then methods, then seeds."""
        result = []
        for env in self.envs:
            for method in self.methods:
                overrides = (self.global_overrides + self.env_overrides.get(env, []) +
                             self.method_overrides.get(method, []))
                for seed in self.seeds:
                    result.append(Run(len(result), env, method, seed, self.budget(env, method), overrides, out))
        return result


# ------------------------------------------------------------------------------------------------ run state


def lock_holder(run):
    """The pid writing the run if its .lock is held by another process, else None."""
    path = os.path.join(run.dir, ".lock")
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            if e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise
            try:
                return int(os.pread(fd, 64, 0).split()[0])
            except (ValueError, IndexError, OSError):
                return 0
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


# The tags that count a run's progress in the unit of its budget (--steps): agent steps for the online
# methods, iterations (one demonstration each) for the imitation methods.
PROGRESS_TAGS = (b"train/agent_steps", b"imitation/demonstrations")


def logged_progress(run):
    """(tag, value): the last progress row of the run's scalars.csv, read from the file's end ((None, 0) if
    none)."""
    path = os.path.join(run.dir, "scalars.csv")
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            chunk = 1 << 16
            while True:
                start = max(0, size - chunk)
                f.seek(start)
                lines = f.read(size - start).split(b"\n")
                if start > 0:
                    lines = lines[1:]  # maybe a partial line
                for line in reversed(lines):
                    fields = line.split(b",")
                    if len(fields) == 4 and fields[2] in PROGRESS_TAGS:
                        try:
                            return fields[2].decode(), int(float(fields[3]))
                        except ValueError:
                            pass
                if start == 0:
                    return None, 0
                chunk *= 4
    except OSError:
        return None, 0


def logged_agent_steps(run):
    """The run's progress in its budget's unit (agent steps, or iterations for imitation methods)."""
    return logged_progress(run)[1]


def unit_of(run):
    """The unit of the run's budget as its log counts it ('agent steps' until it has logged anything)."""
    return "iterations" if logged_progress(run)[0] == "imitation/demonstrations" else "agent steps"


def configured_budget(run, config):
    """The budget in the run's config.yaml, in the unit its log counts progress in."""
    tag, _ = logged_progress(run)
    if tag == "imitation/demonstrations":
        return (config.get("imitation") or {}).get("iterations")
    return (config.get("train") or {}).get("agent_steps")


def run_config(run):
    """The run's config.yaml as a dict, or None."""
    try:
        with open(os.path.join(run.dir, "config.yaml")) as f:
            doc = yaml.safe_load(f)
        return doc if isinstance(doc, dict) else None
    except (OSError, yaml.YAMLError):
        return None


def failure_of(run):
    try:
        with open(run.failed_file) as f:
            return f.read().strip() or "failed"
    except OSError:
        return None


def finished(run):
    """Whether the run reached the budget in its config.yaml. final.pt alone does not tell: a finished run
    that is resumed with a larger budget keeps its old final.pt until it finishes again, while its
    config.yaml is rewritten when it resumes."""
    try:
        final = os.stat(os.path.join(run.dir, "final.pt")).st_mtime_ns
        config_time = os.stat(os.path.join(run.dir, "config.yaml")).st_mtime_ns
    except OSError:
        return False
    if final >= config_time:
        return True
    budget = configured_budget(run, run_config(run) or {})
    return isinstance(budget, int) and logged_agent_steps(run) >= budget


def run_state(run):
    """(state, detail): running, done, partial (finished below this sweep's budget), failed, killed,
    missing. A run that is running or done wins over an old failure record."""
    if not os.path.exists(os.path.join(run.dir, "config.yaml")):
        failure = failure_of(run)
        return ("failed", failure) if failure else ("missing", "")
    pid = lock_holder(run)
    if pid is not None:
        return "running", "pid %d" % pid if pid else ""
    if finished(run):
        config = run_config(run) or {}
        trained = configured_budget(run, config)
        if isinstance(trained, int) and trained < run.steps:
            return "partial", "finished at %d %s; run resumes it to %d" % (trained, unit_of(run), run.steps)
        return "done", ""
    failure = failure_of(run)
    if failure:
        return "failed", failure
    return "killed", ""


def checkpoint_every(run):
    config = run_config(run) or {}
    every = (config.get("checkpoint") or {}).get("every")
    return every if isinstance(every, int) else None


# ---------------------------------------------------------------------------------------- one run, one call


class Stopper:
    """The children of this process, stopped together on SIGINT/SIGTERM."""

    def __init__(self):
        self.stopping = threading.Event()
        self.signal = None
        self.lock = threading.RLock()  # re-entrant: the signal handler runs in the main thread, which may hold it
        self.children = set()

    def add(self, proc):
        with self.lock:
            if self.stopping.is_set():
                proc.terminate()
            self.children.add(proc)

    def remove(self, proc):
        with self.lock:
            self.children.discard(proc)

    def stop(self, signum=None):
        if signum is not None and self.signal is None:
            self.signal = signum
        self.stopping.set()
        with self.lock:
            for proc in self.children:
                try:
                    proc.terminate()
                except OSError:
                    pass

    def kill_survivors(self, grace):
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline:
            with self.lock:
                if not self.children:
                    return
            time.sleep(0.05)
        with self.lock:
            for proc in self.children:
                try:
                    proc.kill()
                except OSError:
                    pass

    def install(self):
        def handler(signum, _frame):
            if not self.stopping.is_set():
                print("%s: interrupted; stopping its runs (they resume on the next call)" % PROG,
                      file=sys.stderr, flush=True)
            self.stop(signum)

        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)

    def exit_code(self):
        return 128 + (self.signal or signal.SIGINT)


def first_error(log_path, start):
    """The first 'error:' line hlt_train printed in this attempt, or its last line."""
    try:
        with open(log_path, errors="replace") as f:
            f.seek(start)
            lines = [line.rstrip("\n") for line in f if line.strip()]
    except OSError:
        return ""
    for line in lines:
        if "error:" in line:
            return line.strip()
    return lines[-1].strip() if lines else ""


def last_done_line(log_path, start):
    try:
        with open(log_path, errors="replace") as f:
            f.seek(start)
            done = [line.strip() for line in f if line.startswith("done:")]
    except OSError:
        return ""
    return done[-1] if done else ""


def run_one(run, train, stopper, lock_wait=0.0):
    """Brings one run to its budget: new, resumed, restarted or left alone. Returns (ok, message)."""
    deadline = time.monotonic() + lock_wait
    while True:
        state, detail = run_state(run)
        if state != "running" or time.monotonic() >= deadline or stopper.stopping.is_set():
            break
        time.sleep(0.5)
    if state == "running":
        if lock_wait > 0:
            return False, "still being written by another process (%s) after %.0f s" % (detail, lock_wait)
        return True, "running elsewhere (%s; left alone)" % detail
    if state == "done":
        return True, "already done (%d %s)" % (max(logged_agent_steps(run), run.steps), unit_of(run))
    if stopper.stopping.is_set():
        return True, "not started (interrupted)"

    os.makedirs(os.path.dirname(run.dir), exist_ok=True)
    action = "started"
    if state in ("killed", "failed", "partial") and os.path.exists(os.path.join(run.dir, "config.yaml")):
        has_checkpoint = os.path.exists(os.path.join(run.dir, "checkpoint.pt"))
        has_final = os.path.exists(os.path.join(run.dir, "final.pt"))
        if not has_checkpoint and not has_final:
            # Killed before its first checkpoint: nothing to resume from. Start afresh only when no more than
            # one checkpoint interval is lost (the same rows will be written again); anything else is a run
            # whose checkpoint was removed, which stays for a person to look at.
            every = checkpoint_every(run)
            progress = logged_agent_steps(run)
            if every is None or progress > every:
                return False, ("has no checkpoint.pt but logged %d %s: not resumable, not restarted "
                               "(move %s away to start it afresh)" % (progress, unit_of(run), run.dir))
            shutil.rmtree(run.dir)
            action = "restarted (killed before its first checkpoint)"
        else:
            action = "resumed (%s at %d %s)" % (state, logged_agent_steps(run), unit_of(run))

    if os.path.exists(os.path.join(run.dir, "config.yaml")):
        cmd = [train, "--resume", run.dir, "--steps", str(run.steps), "--no-progress"]
    else:
        cmd = [train, "--env", run.env, "--method", run.method, "--seed", str(run.seed), "--steps",
               str(run.steps), "--out", run.dir, "--no-progress"] + run.overrides
    # The run ends with this process even if it is killed itself (SIGKILL leaves no chance to stop it).
    setpriv = shutil.which("setpriv")
    shown = " ".join(cmd)
    if setpriv:
        cmd = [setpriv, "--pdeathsig", "TERM", "--"] + cmd
    try:
        os.remove(run.failed_file)
    except FileNotFoundError:
        pass
    with open(run.log, "a") as log:
        start = log.tell()
        log.write("=== %s %s: %s\n" % (time.strftime("%Y-%m-%dT%H:%M:%S"), action, shown))
        log.flush()
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    start_new_session=True)
        except OSError as e:
            message = "cannot start %s: %s" % (train, e.strerror)
            record_failure(run, message)
            return False, message
        stopper.add(proc)
        try:
            code = proc.wait()
        finally:
            stopper.remove(proc)
    if code == 0:
        return True, "%s; %s" % (action, last_done_line(run.log, start) or "done")
    if stopper.stopping.is_set():
        return True, "stopped (resumes on the next call)"
    if code < 0:
        return False, "FAILED (killed by signal %d; it resumes on the next call)" % -code
    message = "exit %d: %s" % (code, first_error(run.log, start))
    record_failure(run, message)
    return False, "FAILED (%s)" % message


def record_failure(run, message):
    os.makedirs(os.path.dirname(run.failed_file), exist_ok=True)
    with open(run.failed_file, "w") as f:
        f.write(message + "\n")


# ---------------------------------------------------------------------------------------------- subcommands


def train_path(train=None):
    """The hlt_train to use, as an absolute path: `train` if given, else $HLT_BUILD_DIR/experiments/hlt_train,
    else the repository's build/experiments/hlt_train (whether it is an executable is the caller's check)."""
    if train:
        path = train
    elif os.environ.get("HLT_BUILD_DIR"):
        path = os.path.join(os.environ["HLT_BUILD_DIR"], "experiments", "hlt_train")
    else:
        path = os.path.join(REPO, "build", "experiments", "hlt_train")
    return os.path.abspath(path)


def is_executable(path):
    return os.path.isfile(path) and os.access(path, os.X_OK)


def train_binary(args):
    path = train_path(args.train)
    if not is_executable(path):
        raise SweepError("%s is not an executable hlt_train (build it with ./scripts/build.sh, or give "
                         "--train or HLT_BUILD_DIR)" % path)
    return path


def cmd_run(args):
    sweep = Sweep(args.sweep)
    out = os.path.abspath(args.out)
    runs = sweep.runs(out)
    train = train_binary(args)
    if args.jobs < 1:
        raise SweepError("--jobs must be at least 1")
    stopper = Stopper()
    stopper.install()
    pending = list(runs)
    results = {}
    lock = threading.Lock()

    def worker():
        while not stopper.stopping.is_set():
            with lock:
                if not pending:
                    return
                run = pending.pop(0)
            try:
                ok, message = run_one(run, train, stopper)
            except Exception as e:  # a bug or an I/O error: reported for this run, the others go on
                ok, message = False, "FAILED (%s: %s)" % (type(e).__name__, e)
            with lock:
                results[run.index] = ok
                print("%s: %s" % (run.name, message), flush=True)

    print("%s: %d run(s) of %s into %s, %d at a time" % (PROG, len(runs), sweep.name, out, args.jobs),
          flush=True)
    threads = [threading.Thread(target=worker, daemon=True) for _ in range(min(args.jobs, len(runs)))]
    for t in threads:
        t.start()
    for t in threads:
        while t.is_alive():
            t.join(0.2)
            if stopper.stopping.is_set():
                stopper.kill_survivors(10.0)
    if stopper.stopping.is_set():
        return stopper.exit_code()
    failed = sum(1 for ok in results.values() if not ok)
    if failed:
        print("%s: %d of %d run(s) failed (hlt_train's output is in the .out file beside each run directory)"
              % (PROG, failed, len(runs)), file=sys.stderr, flush=True)
        return 1
    return 0


def cmd_task(args):
    sweep = Sweep(args.sweep)
    runs = sweep.runs(os.path.abspath(args.out))
    if not 0 <= args.index < len(runs):
        raise SweepError("--index %d: the sweep has runs 0-%d" % (args.index, len(runs) - 1))
    run = runs[args.index]
    train = train_binary(args)
    stopper = Stopper()
    stopper.install()
    restarts = os.environ.get("SLURM_RESTART_COUNT", "0")
    print("%s task %d: %s (%d agent steps) on %s, job %s, restart %s" % (
        PROG, run.index, run.name, run.steps, os.uname().nodename,
        os.environ.get("SLURM_JOB_ID", "-"), restarts), flush=True)
    try:
        ok, message = run_one(run, train, stopper, lock_wait=args.lock_wait)
    except Exception as e:
        ok, message = False, "FAILED (%s: %s)" % (type(e).__name__, e)
    print("%s: %s" % (run.name, message), flush=True)
    if stopper.stopping.is_set():
        return stopper.exit_code()
    if not ok:
        tail = tail_lines(run.log, 5)
        if tail:
            print("last lines of %s:\n%s" % (run.log, tail), flush=True)
    return 0 if ok else 1


def tail_lines(path, n):
    try:
        with open(path, errors="replace") as f:
            return "".join(f.readlines()[-n:]).rstrip()
    except OSError:
        return ""


def array_spec(indices):
    """[0,1,2,5,7,8] -> '0-2,5,7-8'."""
    parts, i = [], 0
    while i < len(indices):
        j = i
        while j + 1 < len(indices) and indices[j + 1] == indices[j] + 1:
            j += 1
        parts.append(str(indices[i]) if i == j else "%d-%d" % (indices[i], indices[j]))
        i = j + 1
    return ",".join(parts)


def queued_tasks(out):
    """Array index -> Slurm state of this sweep's tasks still in the queue (empty without Slurm)."""
    jobs_file = os.path.join(out, "slurm", "jobs")
    try:
        with open(jobs_file) as f:
            job_ids = [line.split()[0] for line in f if line.strip()]
    except OSError:
        return {}
    if not job_ids or not shutil.which("squeue"):
        return {}
    try:
        proc = subprocess.run(["squeue", "-h", "-r", "-j", ",".join(job_ids), "-o", "%K %T"],
                              capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return {}
    states = {}
    for line in proc.stdout.splitlines():
        fields = line.split()
        if len(fields) == 2 and fields[0].isdigit():
            states[int(fields[0])] = fields[1].lower()
    return states


def cmd_submit(args):
    sweep = Sweep(args.sweep)
    out = os.path.abspath(args.out)
    runs = sweep.runs(out)
    train = train_binary(args)
    if args.wait and not args.poll > 0:
        raise SweepError("--poll must be positive")
    if not shutil.which("sbatch"):
        raise SweepError("sbatch not found: submit needs a Slurm client (Debian: slurm-client)")
    if args.all:
        indices = [r.index for r in runs]
    else:
        indices = [r.index for r in runs if run_state(r)[0] not in ("done", "running")]
    if not indices:
        print("%s: nothing to submit: every run of %s is done or running" % (PROG, sweep.name))
        return 0
    slurm_dir = os.path.join(out, "slurm")
    os.makedirs(slurm_dir, exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    # The tasks read a frozen copy, so editing the sweep file later cannot shift their indices.
    frozen = os.path.join(slurm_dir, "sweep-%s.yaml" % stamp)
    n = 1
    while os.path.exists(frozen):
        n += 1
        frozen = os.path.join(slurm_dir, "sweep-%s.%d.yaml" % (stamp, n))
    shutil.copyfile(sweep.path, frozen)
    script = frozen[:-len(".yaml")] + ".sh"
    with open(script, "w") as f:
        f.write("#!/bin/bash\n"
                "# Slurm array task of hlt sweep %s: one run per array index (experiments/hlt_sweep.py).\n"
                "exec %s %s task %s --out %s --index \"$SLURM_ARRAY_TASK_ID\" --train %s\n" % (
                    sweep.name, sys.executable, os.path.abspath(__file__), shq(frozen), shq(out), shq(train)))
    os.chmod(script, 0o755)
    cmd = ["sbatch", "--parsable", "--array=" + array_spec(indices), "--requeue", "--open-mode=append",
           "--job-name=hlt-" + sweep.name, "--output=" + os.path.join(slurm_dir, "%A_%a.out"),
           "--chdir=" + out]
    for flag, value in (("--partition", args.partition), ("--time", args.time),
                        ("--cpus-per-task", args.cpus_per_task), ("--mem", args.mem)):
        if value is not None:
            cmd.append("%s=%s" % (flag, value))
    cmd.append(script)
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SweepError("sbatch failed (exit %d): %s" % (proc.returncode, proc.stderr.strip()))
    job = proc.stdout.strip().split(";")[0]
    note_job(slurm_dir, job, indices, stamp)
    print("%s: submitted job %s: %d task(s) (array %s), logs in %s/%s_<index>.out" % (
        PROG, job, len(indices), array_spec(indices), slurm_dir, job), flush=True)
    if not args.wait:
        return 0
    # Requeued tasks go back to pending and stay part of the job, so waiting ends when no task is active.
    while active_tasks(job):
        time.sleep(args.poll)
    lines, counts = status_report(sweep, out, runs)
    print("\n".join(lines))
    return 0 if counts.get("done", 0) == len(runs) else 1


ACTIVE = {"PENDING", "RUNNING", "CONFIGURING", "COMPLETING", "REQUEUED", "REQUEUE_HOLD", "REQUEUE_FED",
          "RESIZING", "SUSPENDED", "SIGNALING", "STAGE_OUT", "STOPPED", "RESV_DEL_HOLD"}


def active_tasks(job):
    """How many of the job's tasks are not finished (a failing squeue counts as 'still active' for a while:
    a busy controller may time out)."""
    for attempt in range(10):
        proc = subprocess.run(["squeue", "-h", "-r", "-j", job, "-o", "%T"], capture_output=True, text=True)
        if proc.returncode == 0:
            return sum(1 for state in proc.stdout.split() if state in ACTIVE)
        if "Invalid job id" in proc.stderr:
            return 0  # gone from the queue: finished long ago
        time.sleep(min(30, 2 ** attempt))
    raise SweepError("squeue keeps failing: %s" % proc.stderr.strip())


def shq(s):
    return "'" + s.replace("'", "'\\''") + "'"


def note_job(slurm_dir, job, indices, stamp):
    with open(os.path.join(slurm_dir, "jobs"), "a") as f:
        f.write("%s %s %s\n" % (job, stamp, array_spec(indices)))


def status_report(sweep, out, runs):
    queued = queued_tasks(out)
    width = max(len(r.name) for r in runs)
    lines = ["%-*s  %-8s  %s" % (width, "run", "state", "progress (agent steps; iterations for imitation)")]
    counts = {}
    for run in runs:
        state, detail = run_state(run)
        slurm = queued.get(run.index)
        if slurm == "pending" and state not in ("running", "done"):
            state, detail = "queued", "Slurm task pending" + ("; " + detail if detail else "")
        counts[state] = counts.get(state, 0) + 1
        progress = "%d/%d" % (logged_agent_steps(run), run.steps)
        lines.append(("%-*s  %-8s  %-13s %s" % (width, run.name, state, progress, detail)).rstrip())
    order = ["done", "running", "queued", "partial", "killed", "failed", "missing"]
    lines.append("%s: %d run(s): %s" % (sweep.name, len(runs), ", ".join(
        "%d %s" % (counts[s], s) for s in order if s in counts)))
    return lines, counts


def cmd_status(args):
    sweep = Sweep(args.sweep)
    out = os.path.abspath(args.out)
    lines, _ = status_report(sweep, out, sweep.runs(out))
    print("\n".join(lines))
    return 0


def main(argv=None):
    if yaml is None:
        sys.exit("hlt_sweep: needs PyYAML (Debian: apt-get install python3-yaml)")
    parser = argparse.ArgumentParser(prog="hlt_sweep.py", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="run|submit|status")

    def common(p):
        p.add_argument("sweep", help="the sweep's YAML file")
        p.add_argument("--out", required=True, help="results directory: DIR/<env>/<method>/seed<seed>")
        p.add_argument("--train", help="hlt_train (default $HLT_BUILD_DIR/experiments/hlt_train, else "
                                        "build/experiments/hlt_train in the repository)")

    p = sub.add_parser("run", help="run the sweep on a local process pool")
    common(p)
    p.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    p = sub.add_parser("submit", help="submit the sweep as one Slurm job array (one task per run)")
    common(p)
    p.add_argument("--partition")
    p.add_argument("--time", help="time limit per task, e.g. 4:00:00")
    p.add_argument("--cpus-per-task", type=int)
    p.add_argument("--mem", help="memory per task, e.g. 4G")
    p.add_argument("--wait", action="store_true", help="wait until every task ended, then print the status "
                                                       "(exit 1 unless every run is done)")
    p.add_argument("--poll", type=float, default=10.0, help="seconds between queue checks with --wait")
    p.add_argument("--all", action="store_true", help="a task for every run, done or not (default: only runs "
                                                      "that are not done or running)")
    p = sub.add_parser("status", help="list every run with its state and progress")
    common(p)
    p = sub.add_parser("task", help=argparse.SUPPRESS)  # one array task: what submit's script calls
    common(p)
    p.add_argument("--index", type=int, required=True)
    p.add_argument("--lock-wait", type=float, default=60.0,
                   help="seconds to wait for a run still locked by an earlier incarnation of the task")
    args = parser.parse_args(argv)
    try:
        return {"run": cmd_run, "submit": cmd_submit, "status": cmd_status, "task": cmd_task}[args.command](args)
    except SweepError as e:
        print("%s: error: %s" % (PROG, e), file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # submit --wait or status: nothing of ours runs (a submitted job stays queued)
        print("%s: interrupted" % PROG, file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
