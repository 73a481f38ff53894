#!/usr/bin/python3
"""The paper's locomotion claim on a results tree: per environment, every method's mean evaluation return over
seeds at each evaluation and its final returns per seed, then whether each hybrid is above SAC and above its
model-based baseline at every evaluation after the first 20 % of the budget.

  experiments/analysis/locomotion_claim.py TREE --budget hopper=80000 --budget half_cheetah=50000

Budgets are in agent steps. The k-th eval/return_mean row of a run is its evaluation at k x eval.every agent
steps, the last one at the budget where that is not a multiple of eval.every (the log's step axis counts
environment steps, which a run whose episodes end early reaches later)."""
import argparse
import csv
import glob
import os
import re
import statistics as st

BASELINE = {'hybrid-stochastic': 'mppi', 'hybrid-deterministic': 'mpc-deterministic'}


def eval_every(config_path):
    m = re.search(r'^eval:\n(?:  .*\n)*?  every: (\d+)', open(config_path).read(), re.M)
    if not m:
        raise SystemExit(f'{config_path}: no eval.every')
    return int(m.group(1))


def curves(tree, env, budget):
    out = {}
    for f in sorted(glob.glob(f'{tree}/{env}/*/seed*/scalars.csv')):
        method = f.split(os.sep)[-3]
        every = eval_every(f.replace('scalars.csv', 'config.yaml'))
        rows = [float(r['value']) for r in csv.DictReader(open(f)) if r['tag'] == 'eval/return_mean']
        out.setdefault(method, []).append({min(k * every, budget): value for k, value in enumerate(rows)})
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('tree')
    p.add_argument('--budget', action='append', required=True, help='ENV=AGENT_STEPS (one per environment)')
    a = p.parse_args()
    for item in a.budget:
        env, _, steps = item.partition('=')
        if not steps.isdigit():
            raise SystemExit(f'--budget {item}: expected ENV=AGENT_STEPS')
        budget = int(steps)
        print(f'== {env}')
        means = {}
        for m, runs in sorted(curves(a.tree, env, budget).items()):
            steps_ = sorted(set.intersection(*[set(v) for v in runs]))
            means[m] = {s: st.mean(v[s] for v in runs) for s in steps_}
            print(f'{m:22s} n={len(runs)} ' + ' '.join(f'{s // 1000}k:{means[m][s]:.0f}' for s in steps_))
            finals = [v[steps_[-1]] for v in runs]
            print(f'{"":22s} final {steps_[-1]}: {st.mean(finals):.1f} +- {st.pstdev(finals):.1f}  '
                  f'per seed {[round(x, 1) for x in finals]}')
        for h, b in BASELINE.items():
            if h not in means:
                continue
            for other in ['sac', b]:
                if other not in means:
                    continue
                bad = [s for s in means[h] if s >= 0.2 * budget and s > 0 and s in means[other]
                       and means[h][s] <= means[other][s]]
                print(f'{h} vs {other}: '
                      + ('above at every evaluation after 20%' if not bad else f'not above at {bad}'))


if __name__ == '__main__':
    main()
