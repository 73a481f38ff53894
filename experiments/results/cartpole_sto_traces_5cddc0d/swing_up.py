#!/usr/bin/env python3
"""swing_up.py RUNS: per seed, from the eval traces of an eval.trace=true run of the cart-pole swing-up, for
each episode of the last evaluation (the hybrid, then its policy alone): return/first-up/over, where
first-up is the agent step at which the pole is first within 18 degrees of upright (cos theta > 0.95) and
over is 'x' if it then falls back below cos theta = 0.9 (an overshoot past the top, not caught), else '-';
then the evaluation returns."""
import csv, glob, os, sys


def first_up(path):
    episodes = {}
    for r in csv.DictReader(open(path)):
        episodes.setdefault(r['episode'], []).append((float(r['obs_2']), float(r['reward'])))
    out = []
    for steps in episodes.values():
        cos = [c for c, _ in steps]
        up = next((i for i, c in enumerate(cos) if c > 0.95), None)
        over = up is not None and min(cos[up:]) < 0.9
        out.append(f"{sum(r for _, r in steps):.0f}/{up}/{'x' if over else '-'}")
    return ' '.join(out)


def last_trace(run, suffix):
    files = glob.glob(os.path.join(run, 'eval_traces', f'step*{suffix}.csv'))
    files = [f for f in files if suffix or '_' not in os.path.basename(f)]
    return max(files, key=lambda f: int(os.path.basename(f)[4:].split('_')[0].split('.')[0]))


for run in sorted(glob.glob(os.path.join(sys.argv[1], 'seed*')), key=lambda p: int(p.split('seed')[-1])):
    rows = list(csv.DictReader(open(os.path.join(run, 'scalars.csv'))))
    ev = [round(float(r['value']), 1) for r in rows if r['tag'] == 'eval/return_mean']
    pol = [round(float(r['value']), 1) for r in rows if r['tag'] == 'eval/policy_return_mean']
    print(f"{os.path.basename(run)}: hybrid {first_up(last_trace(run, ''))} | policy alone "
          f"{first_up(last_trace(run, '_policy'))} | eval {ev}, policy alone at the end {pol[-1]}")
