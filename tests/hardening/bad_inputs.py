#!/usr/bin/python3
"""The bad-input catalogue of issue 14: every way a careless user can call hlt's executables, one case each.

  tests/hardening/bad_inputs.py --build build            # the current build
  tests/hardening/bad_inputs.py --build OLD --source OLDREPO   # an older build (missing tools are listed)

Each case runs one executable of the build directory (or experiments/hlt_sweep.py of --source) with a time
limit and classifies what happened:
  crash    killed by a signal, exit 134/139, 'terminate called', a LibTorch/OpenCV/Python stack trace or a
           sanitizer report
  silent   exit 0 where the case must fail, a successful case whose result is wrong, or a file that must
           stay untouched changed (files are hashed before and after)
  unclear  a non-zero exit whose message lacks a word the case requires (the key, file or flag at fault),
           or whose exit code is not the documented one (2 for bad input, 1 for a sweep with failed runs)
  hang     a case that must succeed still running at the time limit (one that must fail and is still
           running has taken the bad input: silent)
  refused  a valid request that fails (a case that must succeed exits non-zero)
  ok       none of the above
  missing  the executable is not in the build (not counted)
It prints one line per case, then the counts; exit 1 unless crash = silent = unclear = hang = refused = 0.
--filter REGEX runs the cases whose id matches; --verbose shows the output of every case that is not ok.
Python 3's standard library only. The full-disk cases mount a 64 KiB tmpfs (root only; skipped otherwise).
"""

import argparse
import hashlib
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))

# A small, fast configuration: pendulum episodes are 50 agent steps with frame skip 4.
SMALL = ["--env", "pendulum", "--method", "sac", "--seed", "3", "train.update_after=64", "train.batch_size=32",
         "model.hidden=32", "model.reward_hidden=32", "sac.q_hidden=[32,32]", "planner.samples=8",
         "eval.episodes=1", "--no-progress"]

# Signs of a crash in a message, whatever the exit code.
CRASH_SIGNS = ["terminate called", "most recent call first", "frame #0", "Exception raised from",
               "Segmentation fault", "core dumped", "Assertion `", "AddressSanitizer", "LeakSanitizer",
               "runtime error:", "Traceback (most recent call last)", "Fatal Python error"]
COUNTED = ["crash", "silent", "unclear", "hang", "refused"]


class Missing(Exception):
    pass


class Result:
    def __init__(self, code, output, timed_out, seconds):
        self.code, self.output, self.timed_out, self.seconds = code, output, timed_out, seconds

    def crash_sign(self):
        if not self.timed_out and (self.code < 0 or self.code in (134, 139)):
            return "exit %d" % self.code
        for s in CRASH_SIGNS:
            if s in self.output:
                return repr(s)
        return None


class Catalogue:
    def __init__(self, build, source, work, mount_ok):
        self.build, self.source, self.work, self.mount_ok = build, source, work, mount_ok
        # A sanitized build is slower, and ASan's shadow memory does not fit under an address-space limit.
        self.sanitized = False
        try:
            with open(os.path.join(build, "CMakeCache.txt")) as f:
                self.sanitized = re.search(r"^HLT_SANITIZE:STRING=\S", f.read(), re.M) is not None
        except OSError:
            pass
        self.cases = []
        self._fixture = None

    # --- running -----------------------------------------------------------------------------------------
    def tool(self, name):
        if name == "hlt_sweep.py":
            path = os.path.join(self.source, "experiments", "hlt_sweep.py")
            if not os.path.isfile(path):
                raise Missing(path)
            return ["/usr/bin/python3", path]
        path = os.path.join(self.build, "experiments", name)
        if not os.access(path, os.X_OK):
            raise Missing(path)
        return [path]

    def run(self, name, args, timeout=60, mem_limit=None, cwd=None):
        argv = self.tool(name) + [str(a) for a in args]
        if self.sanitized:
            timeout *= 3
            mem_limit = None

        def limits():
            if mem_limit:
                resource.setrlimit(resource.RLIMIT_AS, (mem_limit, mem_limit))
            os.setsid()

        start = time.monotonic()
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                cwd=cwd or self.work, preexec_fn=limits)
        try:
            out, _ = proc.communicate(timeout=timeout)
            timed_out = False
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, _ = proc.communicate()
            timed_out = True
        except BaseException:  # interrupted: the case's process group goes with us
            os.killpg(proc.pid, signal.SIGKILL)
            raise
        return Result(proc.returncode, out.decode(errors="replace"), timed_out, time.monotonic() - start)

    def fresh(self, name):
        d = os.path.join(self.work, name)
        shutil.rmtree(d, ignore_errors=True)
        return d

    def finished_run(self, name):
        """A copy of a finished 100-step pendulum SAC run (checkpoint.pt at step 100, final.pt)."""
        if self._fixture is None:
            d = self.fresh("fixture_run")
            r = self.run("hlt_train", SMALL + ["--steps", 100, "checkpoint.every=50", "eval.every=0", "--out", d])
            if r.code != 0:
                raise RuntimeError("cannot make the fixture run: " + r.output)
            self._fixture = (d, r)
        d = self.fresh(name)
        shutil.copytree(self._fixture[0], d)
        lock = os.path.join(d, ".lock")
        if os.path.exists(lock):
            os.remove(lock)
        return d


def digest(paths):
    out = {}
    for p in paths:
        try:
            with open(p, "rb") as f:
                out[p] = hashlib.sha256(f.read()).hexdigest()
        except OSError:
            out[p] = None
    return out


def verdict(r, must_fail=True, words=(), protect_before=None, protect_after=None, check=None, code=2):
    """(category, detail) of one result. A failure must exit with `code` (the README's exit codes: 2 for bad
    input or a failed run), else it is unclear too: scripts read the code, not the message."""
    sign = r.crash_sign()
    if sign:
        return "crash", sign
    changed = []
    if protect_before is not None:
        changed = [os.path.basename(p) for p in protect_before if protect_before[p] != protect_after[p]]
    if r.timed_out:
        if changed:
            return "silent", "changed: %s; still running after %.0f s" % (", ".join(changed), r.seconds)
        if must_fail:  # bad input is refused up front; a tool still busy has taken it (trains, loops)
            return "silent", "took the input: still running after %.0f s" % r.seconds
        return "hang", "still running after %.0f s" % r.seconds
    if changed:
        return "silent", "changed: " + ", ".join(changed)
    if must_fail:
        if r.code == 0:
            return "silent", "exit 0"
        lacking = [w for w in words if w.lower() not in r.output.lower()]
        if lacking:
            return "unclear", "exit %d, message lacks %s" % (r.code, ", ".join(repr(w) for w in lacking))
        if code is not None and r.code != code:
            return "unclear", "exit %d instead of %d" % (r.code, code)
        return "ok", "exit %d" % r.code
    if r.code != 0:
        return "refused", "exit %d" % r.code
    problem = check() if check else None
    if isinstance(problem, tuple):
        return problem
    if problem:
        return "silent", problem
    return "ok", "exit 0"


def first_line(text):
    lines = [l for l in text.strip().splitlines() if l.strip()]
    return lines[-1][:150] if lines else ""


# ------------------------------------------------------------------------------------------------------------
# The cases. Each is (id, tool, issue row, function(cat) -> (category, detail, output)).
CASES = []


def case(cid, tool, row):
    def register(fn):
        CASES.append((cid, tool, row, fn))
        return fn
    return register


def fails(tool, args, words, protect=(), timeout=60, mem_limit=None, setup=None, code=2):
    """A case that must fail with a message holding `words` and leave `protect` untouched."""
    def fn(cat):
        if setup:
            setup(cat)
        a = args(cat) if callable(args) else args
        paths = [p(cat) if callable(p) else p for p in protect]
        before = digest(paths)
        w = words(cat) if callable(words) else words
        r = cat.run(tool, a, timeout=timeout, mem_limit=mem_limit)
        return verdict(r, True, w, before, digest(paths), code=code) + (r.output,)
    return fn


def write(path, text, mode="w"):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, mode) as f:
        f.write(text)
    return path


def tmp(cat, name):
    return os.path.join(cat.work, name)


def flip_byte(path, where):
    with open(path, "r+b") as f:
        data = bytearray(f.read())
        i = int(len(data) * where)
        data[i] ^= 0x10
        f.seek(0)
        f.write(data)


def truncate(path, fraction):
    with open(path, "rb") as f:
        data = f.read()
    with open(path, "wb") as f:
        f.write(data[: int(len(data) * fraction)])


RUN_FILES = ("scalars.csv", "config.yaml", "checkpoint.pt", "final.pt")


def run_files(name):
    return [lambda cat, f=f: os.path.join(cat.work, name, f) for f in RUN_FILES]


def register_simple(tool, row, cid, args, words, **kw):
    case(cid, tool, row)(fails(tool, args, words, **kw))


# --- hlt_train: flags and config values -----------------------------------------------------------------------
T = "hlt_train"
register_simple(T, "flags", "train.unknown_flag", ["--stepz", "10"], ["--stepz"])
register_simple(T, "flags", "train.steps_not_a_number", ["--steps", "ten"], ["--steps", "ten"])
register_simple(T, "flags", "train.steps_negative", lambda c: SMALL + ["--steps", "-5", "--out", tmp(c, "neg")],
                ["--steps"])
register_simple(T, "unknown names", "train.unknown_env", ["--env", "moonwalk"], ["moonwalk", "pendulum"])
register_simple(T, "unknown names", "train.unknown_method", ["--env", "pendulum", "--method", "magic"],
                ["magic", "hybrid-stochastic"])
register_simple(T, "unknown names", "train.unknown_key", ["--env", "pendulum", "planer.samples=3"],
                ["planer.samples", "planner.samples"])
register_simple(T, "values", "train.value_out_of_range", ["--env", "pendulum", "planner.samples=-3"],
                ["planner.samples"])
register_simple(T, "NaN/Inf", "train.value_nan", ["--env", "pendulum", "sac.lr=nan"], ["sac.lr"])
register_simple(T, "NaN/Inf", "train.value_inf", ["--env", "pendulum", "sac.lr=inf"], ["sac.lr"])
register_simple(T, "NaN/Inf", "train.value_minus_inf", ["--env", "pendulum", "sac.tau=-inf"], ["sac.tau"])
register_simple(T, "values", "train.value_wrong_type", ["--env", "pendulum", "train.batch_size=abc"],
                ["train.batch_size"])
register_simple(T, "values", "train.override_without_value", ["--env", "pendulum", "planner.samples"],
                ["planner.samples"])
register_simple(T, "values", "train.list_value_malformed", ["--env", "pendulum", "sac.q_hidden=[32,"],
                ["sac.q_hidden"])

register_simple(T, "values", "train.reward_input_unknown",
                ["--env", "pendulum", "--method", "hybrid-stochastic", "model.reward_input=next"],
                ["model.reward_input"])
register_simple(T, "values", "train.next_state_reward_with_td_target",
                ["--env", "pendulum", "--method", "hybrid-stochastic", "model.reward_input=next_state"],
                ["model.reward_gamma"])
register_simple(T, "values", "train.next_state_reward_deterministic",
                ["--env", "pendulum", "--method", "hybrid-deterministic", "model.reward_input=next_state",
                 "model.reward_gamma=0"], ["model.reward_input"])
register_simple(T, "values", "train.demo_noise_negative",
                ["--env", "ant", "--method", "bc", "imitation.expert=constant:0", "imitation.demo_noise=-0.1"],
                ["imitation.demo_noise"])
register_simple(T, "values", "train.ensemble_deterministic",
                ["--env", "pendulum", "--method", "hybrid-deterministic", "model.ensemble=3"],
                ["model.ensemble must be 1"])
register_simple(T, "values", "train.disagreement_penalty_single_model",
                ["--env", "pendulum", "--method", "hybrid-stochastic", "planner.disagreement_penalty=1"],
                ["model.ensemble > 1"])
register_simple(T, "values", "train.hard_mining_with_sequences",
                ["--env", "pendulum", "--method", "hybrid-stochastic", "model.hard_mining=2",
                 "model.rollout_steps=3"],
                ["model.hard_mining 2", "model.rollout_steps 1"])
register_simple(T, "values", "train.plan_noise_from_policy_without_plan_samples",
                ["--env", "pendulum", "--method", "hybrid-stochastic", "planner.plan_noise_from_policy=true",
                 "planner.plan_samples=0"],
                ["planner.plan_noise_from_policy", "planner.plan_samples is 0"])
register_simple(T, "values", "train.sac_bc_weight_negative",
                ["--env", "pendulum", "--method", "sac", "sac.bc_weight=-1"],
                ["sac.bc_weight"])
register_simple(T, "values", "train.rollout_steps_longer_than_episodes",
                lambda c: ["--env", "pendulum", "--method", "mppi", "--steps", "300", "train.update_after=250",
                           "model.rollout_steps=300", "--no-progress", "--out", tmp(c, "rollout")],
                ["model.rollout_steps", "300 consecutive transitions"])

# --- hlt_train: config files -------------------------------------------------------------------------------------
register_simple(T, "YAML", "train.config_malformed",
                lambda c: ["--config", write(tmp(c, "malformed.yaml"), "train: [1, 2\n")],
                ["malformed.yaml"])
register_simple(T, "YAML", "train.config_self_alias",
                lambda c: ["--config", write(tmp(c, "alias.yaml"), "train: &t\n  x: *t\n")], ["alias.yaml"])
register_simple(T, "YAML", "train.config_is_directory", lambda c: ["--config", c.work], ["directory"])
register_simple(T, "YAML", "train.config_missing", lambda c: ["--config", tmp(c, "no_such.yaml")],
                ["no_such.yaml"])
register_simple(T, "YAML", "train.config_unknown_key",
                lambda c: ["--config", write(tmp(c, "typo.yaml"), "planner:\n  smaples: 3\n")],
                ["planner.smaples"])
register_simple(T, "NaN/Inf", "train.config_nan_value",
                lambda c: ["--config", write(tmp(c, "nan.yaml"), "sac:\n  lr: .nan\n")], ["sac.lr"])
register_simple(T, "YAML", "train.config_not_a_mapping",
                lambda c: ["--config", write(tmp(c, "list.yaml"), "- 1\n- 2\n")], ["list.yaml"])
register_simple(T, "YAML", "train.config_binary_garbage",
                lambda c: ["--config", write(tmp(c, "garbage.yaml"), b"\x00\xff\xfe\x01" * 64, "wb")],
                ["garbage.yaml"])


@case("train.env_flag_beats_config", T, "6 --env precedence")
def _(cat):
    out = cat.fresh("precedence")
    cfg = write(tmp(cat, "acrobot.yaml"), "env: acrobot\n")
    r = cat.run(T, SMALL + ["--config", cfg, "--steps", 5, "eval.every=0", "--out", out])

    def check():
        with open(os.path.join(out, "config.yaml")) as f:
            text = f.read()
        return None if re.search(r"^env: \"?pendulum", text, re.M) else "trained the file's env, not --env's"
    return verdict(r, False, check=check) + (r.output,)


# --- hlt_train: run directories ----------------------------------------------------------------------------------
register_simple(T, "files", "train.out_not_writable", ["--env", "pendulum", "--out", "/proc/hlt_no/run"],
                ["/proc/hlt_no/run"])
register_simple(T, "files", "train.out_is_a_file",
                lambda c: SMALL + ["--steps", 5, "--out", write(tmp(c, "a_file"), "x")], ["a_file"],
                protect=[lambda c: tmp(c, "a_file")])
register_simple(T, "files", "train.resume_missing_dir", lambda c: ["--resume", tmp(c, "no_such_run")],
                ["no_such_run"])
register_simple(T, "files", "train.resume_not_a_run", lambda c: ["--resume", c.work], ["config.yaml"])


@case("train.summary_counts_steps", T, "6 closing summary")
def _(cat):
    cat.finished_run("summary")
    r = cat._fixture[1]

    def check():
        if "done: 100 agent steps (400 environment steps)" not in r.output:
            return "summary: " + first_line(r.output)
        if re.search(r"return -?nan", r.output):
            return "unclear", "the summary reports a NaN return when no evaluation ran"

        return None
    return verdict(r, False, check=check) + (r.output,)


def resume_with_broken_checkpoint(name, damage):
    def setup(cat):
        d = cat.finished_run(name)
        damage(os.path.join(d, "checkpoint.pt"))
    return fails(T, lambda c: ["--resume", tmp(c, name), "--steps", 150, "--no-progress"], ["checkpoint.pt"],
                 protect=run_files(name), setup=setup)


case("train.checkpoint_truncated", T, "4 corrupt checkpoints")(
    resume_with_broken_checkpoint("ckpt_truncated", lambda p: truncate(p, 0.4)))
case("train.checkpoint_empty", T, "4 corrupt checkpoints")(
    resume_with_broken_checkpoint("ckpt_empty", lambda p: truncate(p, 0)))
case("train.checkpoint_garbage", T, "4 corrupt checkpoints")(
    resume_with_broken_checkpoint("ckpt_garbage", lambda p: write(p, b"PK\x03\x04" + os.urandom(4000), "wb")))
case("train.checkpoint_bit_flip", T, "6 bit flips")(
    resume_with_broken_checkpoint("ckpt_flip", lambda p: flip_byte(p, 0.5)))
case("train.checkpoint_bit_flip_late", T, "6 bit flips")(
    resume_with_broken_checkpoint("ckpt_flip_late", lambda p: flip_byte(p, 0.8)))


@case("train.resume_smaller_steps", T, "4 resume")
def _(cat):
    cat.finished_run("smaller")
    return fails(T, lambda c: ["--resume", tmp(c, "smaller"), "--steps", 40, "--no-progress"], ["100", "--steps"],
                 protect=run_files("smaller"))(cat)


@case("train.resume_finished_without_checkpoint", T, "4 resume")
def _(cat):
    d = cat.finished_run("no_ckpt")
    os.remove(os.path.join(d, "checkpoint.pt"))
    return fails(T, ["--resume", d, "--no-progress"], ["checkpoint.pt"], protect=run_files("no_ckpt"))(cat)


@case("train.resume_writes_missing_final", T, "4 resume")
def _(cat):
    d = cat.finished_run("no_final")
    os.remove(os.path.join(d, "final.pt"))
    before = digest([os.path.join(d, "scalars.csv")])
    r = cat.run(T, ["--resume", d, "--no-progress"])

    def check():
        if not os.path.isfile(os.path.join(d, "final.pt")):
            return "final.pt not written"
        if digest(list(before)) != before:
            return "scalars.csv changed"
        return None
    return verdict(r, False, check=check) + (r.output,)


@case("train.stale_temporaries_removed", T, "6 stale temporaries")
def _(cat):
    d = cat.finished_run("stale")
    stale = write(os.path.join(d, "checkpoint.pt.tmp.99999"), "half a checkpoint")
    r = cat.run(T, ["--resume", d, "--steps", 150, "--no-progress"])

    def check():
        if os.path.exists(stale):
            return "stale checkpoint.pt.tmp.99999 left"
        if "done: 150 agent steps" not in r.output:
            return "summary: " + first_line(r.output)
        return None
    return verdict(r, False, check=check) + (r.output,)


@case("train.out_over_final_pt", T, "4 resume")
def _(cat):
    d = cat.fresh("only_final")
    os.makedirs(d)
    src = cat.finished_run("only_final_src")
    shutil.copy(os.path.join(src, "final.pt"), d)
    return fails(T, SMALL + ["--steps", 10, "--out", d], ["final.pt"], protect=[os.path.join(d, "final.pt")])(cat)


@case("train.out_over_a_run", T, "4 resume")
def _(cat):
    cat.finished_run("over_run")
    return fails(T, lambda c: SMALL + ["--steps", 10, "--out", tmp(c, "over_run")], ["already"],
                 protect=run_files("over_run"))(cat)


@case("train.resume_live_run", T, "3 lock")
def _(cat):
    d = cat.fresh("live")
    argv = cat.tool(T) + SMALL + ["--steps", "100000", "eval.every=0", "--out", d]
    live = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=os.setsid)
    try:
        deadline = time.monotonic() + 60
        while not os.path.exists(os.path.join(d, "scalars.csv")) and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)
        cfg = os.path.join(d, "config.yaml")
        before = digest([cfg])
        r = cat.run(T, ["--resume", d, "--no-progress"], timeout=20)
        after = digest([cfg])
    finally:
        os.killpg(live.pid, signal.SIGKILL)
        live.wait()
    return verdict(r, True, ["in use", str(live.pid)], before, after) + (r.output,)


@case("train.full_disk", T, "1 full disk")
def _(cat):
    if not cat.mount_ok:
        return "skip", "cannot mount a tmpfs", ""
    mnt = cat.fresh("disk_train")
    os.makedirs(mnt)
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", mnt], check=True)
    try:
        d = os.path.join(mnt, "run")
        r = cat.run(T, SMALL + ["--steps", 3000, "eval.every=500", "checkpoint.every=500", "--out", d], timeout=90)
        left = sorted(f for f in os.listdir(d) if ".tmp." in f) if os.path.isdir(d) else []
        res = verdict(r, True, ["No space left on device"])
        if res[0] == "ok" and left:
            res = ("silent", "temporaries left on the full disk: " + ", ".join(left))
        return res + (r.output,)
    finally:
        subprocess.run(["umount", mnt])


register_simple(T, "2 memory", "train.replay_capacity_too_big",
                lambda c: ["--env", "ant", "--steps", 1, "train.replay_capacity=100000000", "--out", tmp(c, "big")],
                ["train.replay_capacity"], mem_limit=8 << 30)


@case("train.replay_capacity_under_ulimit", T, "2 memory")
def _(cat):
    if cat.sanitized:
        return "skip", "no address-space limit under ASan", ""
    return fails(T, ["--env", "ant", "--steps", 1, "train.replay_capacity=30000000", "--out", tmp(cat, "big2")],
                 ["train.replay_capacity"], mem_limit=4 << 30)(cat)


@case("train.divergence", T, "5 divergence")
def _(cat):
    d = cat.fresh("diverged")
    r = cat.run(T, SMALL + ["--steps", 1500, "sac.lr=1", "sac.initial_alpha=10000", "eval.every=0",
                            "checkpoint.every=100", "--out", d], timeout=120)
    res = verdict(r, True, ["diverged"])
    if res[0] in ("ok", "unclear") and os.path.exists(os.path.join(d, "final.pt")):
        res = ("silent", "final.pt written by a diverged run")
    return res + (r.output,)


# --- hlt_rollout ---------------------------------------------------------------------------------------------------
R = "hlt_rollout"
register_simple(R, "flags", "rollout.unknown_flag", ["--env", "pendulum", "--bogus"], ["--bogus"])
register_simple(R, "unknown names", "rollout.unknown_env", ["--env", "moonwalk"], ["moonwalk"])
register_simple(R, "flags", "rollout.no_env", [], ["--env"])
register_simple(R, "unknown names", "rollout.unknown_policy", ["--env", "pendulum", "--policy", "magic"],
                ["magic"])
register_simple(R, "NaN/Inf", "rollout.constant_nan", ["--env", "pendulum", "--policy", "constant:nan"], ["nan"])
register_simple(R, "NaN/Inf", "rollout.constant_inf", ["--env", "pendulum", "--policy", "constant:inf"], ["inf"])
register_simple(R, "values", "rollout.constant_wrong_size", ["--env", "pendulum", "--policy", "constant:1,2,3"],
                ["constant"])
register_simple(R, "values", "rollout.constant_not_a_number", ["--env", "pendulum", "--policy", "constant:abc"],
                ["abc"])
register_simple(R, "values", "rollout.frame_skip_zero", ["--env", "pendulum", "--frame-skip", 0], ["--frame-skip"])
register_simple(R, "values", "rollout.episodes_negative", ["--env", "pendulum", "--episodes", -1], ["--episodes"])
register_simple(R, "values", "rollout.width_zero",
                lambda c: ["--env", "pendulum", "--width", 0, "--strip", tmp(c, "s.png")], ["--width"])
register_simple(R, "values", "rollout.max_steps_negative", ["--env", "pendulum", "--max-steps", -3], ["--max-steps"])
register_simple(R, "values", "rollout.strip_frames_zero",
                lambda c: ["--env", "pendulum", "--strip", tmp(c, "s.png"), "--strip-frames", 0], ["--strip-frames"])
register_simple(R, "files", "rollout.video_bad_extension",
                lambda c: ["--env", "pendulum", "--max-steps", 5, "--video", tmp(c, "v.xyz")], ["v.xyz"])
register_simple(R, "files", "rollout.video_unwritable",
                ["--env", "pendulum", "--max-steps", 5, "--video", "/proc/hlt_no/v.mp4"], ["/proc/hlt_no"])
register_simple(R, "files", "rollout.csv_is_a_directory",
                lambda c: ["--env", "pendulum", "--max-steps", 5, "--csv", c.work], lambda c: [c.work])
register_simple(R, "files", "rollout.demos_unwritable",
                ["--env", "pendulum", "--max-steps", 5, "--demos", "/proc/hlt_no/d.hltd"], ["/proc/hlt_no"])
register_simple(R, "files", "rollout.checkpoint_missing",
                lambda c: ["--env", "pendulum", "--policy", "checkpoint:" + tmp(c, "none.pt")], ["none.pt"])
register_simple(R, "files", "rollout.checkpoint_is_directory",
                lambda c: ["--env", "pendulum", "--policy", "checkpoint:" + c.work], lambda c: [c.work])


def rollout_broken(name, damage):
    def fn(cat):
        d = cat.finished_run(name)
        p = os.path.join(d, "final.pt")
        damage(p)
        return fails(R, ["--env", "pendulum", "--policy", "checkpoint:" + p], ["final.pt"], protect=[p])(cat)
    return fn


case("rollout.checkpoint_truncated", R, "4 corrupt checkpoints")(rollout_broken("r_trunc", lambda p: truncate(p, .5)))
case("rollout.checkpoint_garbage", R, "4 corrupt checkpoints")(
    rollout_broken("r_garbage", lambda p: write(p, os.urandom(3000), "wb")))
case("rollout.checkpoint_bit_flip", R, "6 bit flips")(rollout_broken("r_flip", lambda p: flip_byte(p, 0.5)))


@case("rollout.checkpoint_other_env", R, "unknown names")
def _(cat):
    d = cat.finished_run("r_other")
    return fails(R, ["--env", "acrobot", "--policy", "checkpoint:" + os.path.join(d, "final.pt")],
                 ["pendulum", "acrobot"])(cat)


register_simple(R, "files", "rollout.expert_missing",
                lambda c: ["--env", "ant", "--policy", "expert:" + tmp(c, "no_expert.txt")], ["no_expert.txt"])
register_simple(R, "files", "rollout.expert_malformed",
                lambda c: ["--env", "ant", "--policy", "expert:" + write(tmp(c, "expert.txt"), "layers 2\n1 2 x\n")],
                ["expert.txt"])


@case("rollout.recording_streams_frames", R, "2 memory")
def _(cat):
    # Three recorded 200-step episodes at 480x360 are 311 MB of frames: under a 2.5 GB address-space limit (LibTorch
    # and OpenBLAS reserve most of it) they fit only when streamed to the encoder.
    v = os.path.join(cat.fresh("record"), "v.avi")
    os.makedirs(os.path.dirname(v))
    r = cat.run(R, ["--env", "pendulum", "--episodes", 3, "--record-episodes", 3, "--video", v], timeout=120,
                mem_limit=int(2.5 * (1 << 30)))

    def check():
        return None if os.path.isfile(v) and os.path.getsize(v) > 10000 else "no video written"
    return verdict(r, False, check=check) + (r.output,)


@case("rollout.full_disk", R, "1 full disk")
def _(cat):
    if not cat.mount_ok:
        return "skip", "cannot mount a tmpfs", ""
    mnt = cat.fresh("disk_rollout")
    os.makedirs(mnt)
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", mnt], check=True)
    try:
        r = cat.run(R, ["--env", "pendulum", "--episodes", 5, "--csv", os.path.join(mnt, "steps.csv")])
        return verdict(r, True, ["steps.csv"]) + (r.output,)
    finally:
        subprocess.run(["umount", mnt])


# --- hlt_model_fit ---------------------------------------------------------------------------------------------------
F = "hlt_model_fit"


def pendulum_demos(cat, name="d.hltd"):
    """Two random-policy pendulum episodes recorded as demonstrations (once per catalogue run)."""
    path = tmp(cat, name)
    if not os.path.exists(path):
        cat.run("hlt_rollout", ["--env", "pendulum", "--episodes", 2, "--frame-skip", 4, "--demos", path])
    return path


def fit_args(extra, train=None):
    return lambda c: ["--env", "pendulum", "--train", train(c) if train else pendulum_demos(c), "--test",
                      pendulum_demos(c), "--updates", 5] + extra


register_simple(F, "flags", "model_fit.unknown_flag", fit_args(["--bogus"]), ["--bogus"])
register_simple(F, "flags", "model_fit.no_test", lambda c: ["--env", "pendulum", "--train", pendulum_demos(c)],
                ["--test"])
register_simple(F, "unknown names", "model_fit.unknown_env",
                lambda c: ["--env", "moonwalk", "--train", pendulum_demos(c), "--test", pendulum_demos(c)],
                ["moonwalk"])
register_simple(F, "values", "model_fit.updates_zero", fit_args(["--updates", 0]), ["--updates"])
register_simple(F, "values", "model_fit.bad_override", fit_args(["model.hidden=0"]), ["model.hidden"])
register_simple(F, "values", "model_fit.override_nan", fit_args(["model.lr=nan"]), ["model.lr"])
register_simple(F, "values", "model_fit.horizons_malformed", fit_args(["--horizons", "20,,60"]), ["--horizons"])
register_simple(F, "values", "model_fit.horizons_zero", fit_args(["--horizons", "0"]), ["--horizons"])
register_simple(F, "files", "model_fit.train_missing", fit_args([], lambda c: tmp(c, "none.hltd")), ["none.hltd"])
register_simple(F, "files", "model_fit.other_env",
                lambda c: ["--env", "acrobot", "--train", pendulum_demos(c), "--test", pendulum_demos(c)],
                ["pendulum"])


def broken_demos(name, damage):
    def path(c):
        p = tmp(c, name)
        shutil.copyfile(pendulum_demos(c), p)
        damage(p)
        return p
    return path


register_simple(F, "4 corrupt files", "model_fit.train_truncated",
                fit_args([], broken_demos("t.hltd", lambda p: truncate(p, .5))), ["t.hltd"])
register_simple(F, "4 corrupt files", "model_fit.train_garbage",
                fit_args([], broken_demos("g.hltd", lambda p: write(p, os.urandom(3000), "wb"))), ["g.hltd"])


# --- hlt_bench -------------------------------------------------------------------------------------------------------
B = "hlt_bench"
register_simple(B, "flags", "bench.unknown_flag", ["--bogus"], ["--bogus"])
register_simple(B, "unknown names", "bench.filter_matches_nothing", ["--benchmark_filter=NoSuchBenchmark"],
                ["NoSuchBenchmark"])
register_simple(B, "values", "bench.bad_regex", ["--benchmark_filter=("], ["("])
register_simple(B, "NaN/Inf", "bench.min_time_nan", ["--benchmark_filter=BM_EnvStep/pendulum$",
                                                     "--benchmark_min_time=nan"], ["--benchmark_min_time"])
register_simple(B, "values", "bench.min_time_negative", ["--benchmark_filter=BM_EnvStep/pendulum$",
                                                        "--benchmark_min_time=-1"], ["--benchmark_min_time"])
register_simple(B, "values", "bench.repetitions_negative", ["--benchmark_filter=BM_EnvStep/pendulum$",
                                                           "--benchmark_repetitions=-2"], ["--benchmark_repetitions"])
register_simple(B, "values", "bench.repetitions_not_a_number", ["--benchmark_repetitions=abc"], ["repetitions"])
register_simple(B, "files", "bench.out_unwritable",
                ["--benchmark_filter=BM_EnvStep/pendulum$", "--benchmark_min_time=0.01",
                 "--benchmark_out=/proc/hlt_no/b.json"], ["/proc/hlt_no/b.json"])


# --- hlt_perceive ---------------------------------------------------------------------------------------------------------
P = "hlt_perceive"


def tags(cat):
    return os.path.join(REPO, "experiments", "configs", "perception", "sawyer_tags.yaml")


def camera_yaml(cat):
    return os.path.join(REPO, "experiments", "configs", "perception", "camera_640x480.yaml")


def perceive(extra):
    return lambda c: ["--input", "synthetic:3", "--quiet", "--tags", tags(c), "--csv", tmp(c, "p.csv")] + (
        extra(c) if callable(extra) else extra)


register_simple(P, "flags", "perceive.unknown_flag", perceive(["--bogus"]), ["--bogus"])
register_simple(P, "flags", "perceive.no_input", lambda c: ["--tags", tags(c)], ["--input"])
register_simple(P, "NaN/Inf", "perceive.fps_nan", perceive(["--fps", "nan"]), ["--fps"])
register_simple(P, "NaN/Inf", "perceive.fps_inf", perceive(["--fps", "inf"]), ["--fps"])
register_simple(P, "NaN/Inf", "perceive.decimate_nan", perceive(["--decimate", "nan"]), ["--decimate"])
register_simple(P, "NaN/Inf", "perceive.plane_height_nan", perceive(["--plane-height", "nan"]), ["--plane-height"])
register_simple(P, "values", "perceive.hsv_malformed", perceive(["--hsv-low", "1,2"]), ["--hsv-low"])
register_simple(P, "values", "perceive.synthetic_count_bad",
                lambda c: ["--input", "synthetic:abc", "--tags", tags(c), "--csv", tmp(c, "p.csv")], ["synthetic:abc"])
register_simple(P, "files", "perceive.input_missing",
                lambda c: ["--input", tmp(c, "no_video.mp4"), "--tags", tags(c), "--csv", tmp(c, "p.csv"),
                           "--calibration", camera_yaml(c)], ["no_video.mp4"])
register_simple(P, "files", "perceive.tags_missing",
                lambda c: ["--input", "synthetic:3", "--tags", tmp(c, "no_tags.yaml")], ["no_tags.yaml"])
register_simple(P, "YAML", "perceive.tags_malformed",
                lambda c: ["--input", "synthetic:3", "--tags", write(tmp(c, "bad_tags.yaml"), "tags: [1, 2\n")],
                ["bad_tags.yaml"])
register_simple(P, "YAML", "perceive.tags_self_alias",
                lambda c: ["--input", "synthetic:3", "--tags", write(tmp(c, "alias_tags.yaml"), "tags: &t\n  - *t\n")],
                ["alias_tags.yaml"])
register_simple(P, "YAML", "perceive.tags_is_directory", lambda c: ["--input", "synthetic:3", "--tags", c.work],
                ["directory"])
register_simple(P, "files", "perceive.csv_unwritable",
                lambda c: ["--input", "synthetic:3", "--quiet", "--tags", tags(c), "--csv", "/proc/hlt_no/p.csv"],
                ["/proc/hlt_no/p.csv"])

CALIB = """%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ {fx}, 0., {cx}, 0., {fy}, {cy}, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
"""


def calibration(name, fx=600, fy=600, cx=320, cy=240):
    return lambda c: perceive(["--calibration", write(tmp(c, name), CALIB.format(fx=fx, fy=fy, cx=cx, cy=cy))])(c)


register_simple(P, "6 camera calibration", "perceive.calibration_principal_point_outside",
                calibration("cal_pp.yaml", cx=1e6, cy=-1e6), ["cal_pp.yaml"])
register_simple(P, "6 camera calibration", "perceive.calibration_huge_focal",
                calibration("cal_focal.yaml", fx=1e12, fy=1e12), ["cal_focal.yaml"])
register_simple(P, "6 camera calibration", "perceive.calibration_negative_focal",
                calibration("cal_neg.yaml", fx=-600), ["cal_neg.yaml"])
register_simple(P, "NaN/Inf", "perceive.calibration_nan", calibration("cal_nan.yaml", fx=".nan"), ["cal_nan.yaml"])
register_simple(P, "files", "perceive.calibration_missing",
                perceive(lambda c: ["--calibration", tmp(c, "no_cal.yaml")]), ["no_cal.yaml"])
register_simple(P, "YAML", "perceive.calibration_malformed",
                perceive(lambda c: ["--calibration", write(tmp(c, "cal_bad.yaml"), "camera_matrix: [1, 2\n")]),
                ["cal_bad.yaml"])


@case("perceive.empty_input_keeps_csv", P, "6 CSV truncated")
def _(cat):
    d = cat.fresh("perceive_empty")
    os.makedirs(os.path.join(d, "frames"))
    csv = write(os.path.join(d, "states.csv"), "frame,valid\n0,1\n")
    det = write(os.path.join(d, "states_detections.csv"), "frame,id\n0,3\n")
    return fails(P, ["--input", os.path.join(d, "frames"), "--tags", tags(cat), "--csv", csv, "--calibration",
                     camera_yaml(cat)], ["frames"], protect=[csv, det])(cat)


@case("perceive.full_disk", P, "1 full disk")
def _(cat):
    if not cat.mount_ok:
        return "skip", "cannot mount a tmpfs", ""
    mnt = cat.fresh("disk_perceive")
    os.makedirs(mnt)
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", mnt], check=True)
    try:
        r = cat.run(P, ["--input", "synthetic:300", "--quiet", "--tags", tags(cat), "--csv",
                        os.path.join(mnt, "states.csv")], timeout=120)
        return verdict(r, True, ["states"]) + (r.output,)
    finally:
        subprocess.run(["umount", mnt])


# --- hlt_calibrate ----------------------------------------------------------------------------------------------------------
C = "hlt_calibrate"
CB = ["--cols", 9, "--rows", 6]
register_simple(C, "flags", "calibrate.missing_required", ["--images", "/tmp"], ["--cols"])
register_simple(C, "flags", "calibrate.nothing_to_do", CB + ["--square", 0.025], ["--images"])
register_simple(C, "NaN/Inf", "calibrate.square_nan", lambda c: CB + ["--square", "nan", "--images", c.work],
                ["--square"])
register_simple(C, "NaN/Inf", "calibrate.square_inf", lambda c: CB + ["--square", "inf", "--images", c.work],
                ["--square"])
register_simple(C, "values", "calibrate.square_negative", lambda c: CB + ["--square", -1, "--images", c.work],
                ["--square"])
register_simple(C, "files", "calibrate.images_missing",
                lambda c: CB + ["--square", 0.025, "--images", tmp(c, "no_images"), "--out", tmp(c, "c.yaml")],
                ["no_images"])


def bmp(path, w=64, h=48):
    """A uniform grey 24-bit BMP: an image without a checkerboard."""
    row = bytes([128] * (w * 3)) + b"\0" * ((4 - w * 3 % 4) % 4)
    pixels = row * h
    header = b"BM" + (54 + len(pixels)).to_bytes(4, "little") + b"\0\0\0\0" + (54).to_bytes(4, "little")
    info = (40).to_bytes(4, "little") + w.to_bytes(4, "little") + h.to_bytes(4, "little") + (1).to_bytes(2, "little")
    info += (24).to_bytes(2, "little") + b"\0" * 4 + len(pixels).to_bytes(4, "little") + b"\0" * 16
    return write(path, header + info + pixels, "wb")


@case("calibrate.images_empty", C, "files")
def _(cat):
    d = cat.fresh("cal_empty")
    os.makedirs(d)
    return fails(C, CB + ["--square", 0.025, "--images", d, "--out", os.path.join(d, "c.yaml")], ["cal_empty"])(cat)


@case("calibrate.images_without_board", C, "values")
def _(cat):
    d = cat.fresh("cal_blank")
    for i in range(3):
        bmp(os.path.join(d, "blank%d.bmp" % i))
    out = write(os.path.join(d, "c.yaml"), "previous calibration\n")
    return fails(C, CB + ["--square", 0.025, "--images", d, "--out", out], ["board"], protect=[out])(cat)


register_simple(C, "files", "calibrate.render_demo_unwritable", CB + ["--square", 0.025, "--render-demo",
                                                                      "/proc/hlt_no/demo"], ["/proc/hlt_no/demo"])

# --- hlt_perception_eval --------------------------------------------------------------------------------------------------------
E = "hlt_perception_eval"
register_simple(E, "flags", "perception_eval.unknown_flag", ["--bogus"], ["--bogus"])
register_simple(E, "NaN/Inf", "perception_eval.decimate_nan", ["--decimate", "nan"], ["--decimate"])
register_simple(E, "values", "perception_eval.seeds_zero", ["--seeds", 0], ["--seeds"])

# --- experiments/hlt_sweep.py ------------------------------------------------------------------------------------------------------
S = "hlt_sweep.py"
GOOD_SWEEP = "envs: [pendulum]\nmethods: [sac]\nseeds: [0]\nsteps: 20\noverrides:\n  all:\n    eval.every: 0\n"


def sweep(name, text, extra=()):
    def args(cat):
        f = write(tmp(cat, name), text) if text is not None else tmp(cat, name)
        return ["run", f, "--out", tmp(cat, name + "_out"), "--train",
                os.path.join(cat.build, "experiments", "hlt_train")] + list(extra)
    return args


register_simple(S, "flags", "sweep.unknown_command", ["frobnicate"], ["frobnicate"])
register_simple(S, "files", "sweep.file_missing", sweep("no_sweep.yaml", None), ["no_sweep.yaml"])
register_simple(S, "YAML", "sweep.malformed", sweep("s_bad.yaml", "envs: [pendulum\n"), ["s_bad.yaml"])
register_simple(S, "YAML", "sweep.self_alias", sweep("s_alias.yaml", GOOD_SWEEP + "x: &a\n  y: *a\nmethods: &m [*m]\n"),
                ["s_alias.yaml"])
register_simple(S, "YAML", "sweep.is_directory", lambda c: ["run", c.work, "--out", tmp(c, "o")], ["directory"])
# The sweep tool leaves environment names to hlt_train: a failed run, exit 1.
register_simple(S, "unknown names", "sweep.unknown_env", sweep("s_env.yaml", GOOD_SWEEP.replace("pendulum", "moonwalk")),
                ["moonwalk"], code=1)
register_simple(S, "unknown names", "sweep.unknown_field", sweep("s_field.yaml", GOOD_SWEEP + "seedz: 3\n"), ["seedz"])
register_simple(S, "values", "sweep.bad_seed_range", sweep("s_seeds.yaml", GOOD_SWEEP.replace("[0]", "3-1")),
                ["seeds"])
register_simple(S, "NaN/Inf", "sweep.steps_nan", sweep("s_steps.yaml", GOOD_SWEEP.replace("20", ".nan")), ["steps"])
register_simple(S, "values", "sweep.jobs_zero", sweep("s_jobs.yaml", GOOD_SWEEP, ["--jobs", 0]), ["--jobs"])
register_simple(S, "files", "sweep.train_missing",
                lambda c: ["run", write(tmp(c, "s_ok.yaml"), GOOD_SWEEP), "--out", tmp(c, "s_ok_out"), "--train",
                           tmp(c, "no_hlt_train")], ["no_hlt_train"])
register_simple(S, "values", "sweep.failing_run_reported",
                sweep("s_fail.yaml", GOOD_SWEEP.replace("eval.every: 0", "sac.lr: .nan")), ["sac.lr"], timeout=60,
                code=1)




@case("sweep.rerun_during_sweep", S, "3 lock")
def _(cat):
    # The same sweep started again while its run trains: the live run is left alone and said to be running.
    text = GOOD_SWEEP.replace("steps: 20", "steps: 100000")
    argv = cat.tool(S) + sweep("s_live.yaml", text)(cat)
    first = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=os.setsid)
    d = os.path.join(tmp(cat, "s_live.yaml_out"), "pendulum", "sac", "seed0")
    try:
        deadline = time.monotonic() + 60
        while not os.path.exists(os.path.join(d, "scalars.csv")) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        cfg = [os.path.join(d, "config.yaml")]
        before = digest(cfg)
        r = cat.run(S, sweep("s_live.yaml", text)(cat), timeout=20)
        after = digest(cfg)
    finally:
        os.killpg(first.pid, signal.SIGTERM)
        try:
            first.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(first.pid, signal.SIGKILL)
            first.wait()
    category, detail = verdict(r, False, (), before, after)
    if category in ("ok", "refused") and "running elsewhere" not in r.output:
        category, detail = "unclear", "exit %d, message lacks 'running elsewhere'" % r.code
    elif category == "refused":
        category, detail = "ok", "exit %d, live run left alone" % r.code
    return category, detail, r.output


# ------------------------------------------------------------------------------------------------------------
def can_mount(work):
    d = os.path.join(work, "mount_probe")
    os.makedirs(d, exist_ok=True)
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", d], stderr=subprocess.DEVNULL,
                        stdout=subprocess.DEVNULL).returncode == 0
    if ok:
        subprocess.run(["umount", d])
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", required=True, help="build directory (holds experiments/hlt_train etc.)")
    ap.add_argument("--source", default=REPO, help="repository whose experiments/hlt_sweep.py is tested")
    ap.add_argument("--filter", default="", help="only cases whose id matches this regular expression")
    ap.add_argument("--verbose", action="store_true", help="print the output of every case that is not ok")
    ap.add_argument("--keep", action="store_true", help="keep the work directory")
    args = ap.parse_args()
    # SIGTERM (ctest's timeout, kill) unwinds like Ctrl-C: running cases are killed, the work directory removed.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    build = os.path.abspath(args.build)
    work = tempfile.mkdtemp(prefix="hlt_bad_inputs_")
    cat = Catalogue(build, os.path.abspath(args.source), work, can_mount(work))
    if not cat.mount_ok:
        print("note: cannot mount a 64 KiB tmpfs here (needs root): the full-disk cases are skipped")
    counts = {}
    start = time.monotonic()
    try:
        for cid, tool, row, fn in CASES:
            if args.filter and not re.search(args.filter, cid):
                continue
            t0 = time.monotonic()
            try:
                category, detail, output = fn(cat)
            except Missing as e:
                category, detail, output = "missing", "not built: " + str(e), ""
            counts[category] = counts.get(category, 0) + 1
            print("%-8s %-46s %-22s %5.1fs  %s" % (category, cid, row, time.monotonic() - t0, detail), flush=True)
            if category != "ok" and category not in ("missing", "skip"):
                print("         " + first_line(output))
                if args.verbose:
                    print("\n".join("         | " + l for l in output.strip().splitlines()[-15:]))
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print("\n%d cases in %.0f s against %s" % (sum(counts.values()), time.monotonic() - start, build))
    for c in ["ok"] + COUNTED + ["skip", "missing"]:
        print("  %-8s %d" % (c, counts.get(c, 0)))
    bad = sum(counts.get(c, 0) for c in COUNTED)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
