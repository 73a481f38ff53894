# Per env: mean eval return over seeds at every evaluation for each method; check the paper's claim after 20% of
# the budget: each hybrid above SAC and above its model-based baseline at every evaluation.
import csv, glob, statistics as st, sys
root = sys.argv[1]
budget = {'hopper': 50000, 'half_cheetah': 40000}
base = {'hybrid-stochastic': 'mppi', 'hybrid-deterministic': 'mpc-deterministic'}
for env in ['hopper', 'half_cheetah']:
    curves = {}
    for f in glob.glob(f'{root}/{env}/*/seed*/scalars.csv'):
        method = f.split('/')[-3]
        cfg = open(f.replace('scalars.csv', 'config.yaml')).read()
        fs = 4 if 'frame_skip: 4' in cfg else 5
        v = {}
        for r in csv.DictReader(open(f)):
            if r['tag'] == 'eval/return_mean':
                v[round(int(r['step']) / fs / 1000) * 1000] = float(r['value'])
        curves.setdefault(method, []).append(v)
    print(f'== {env}')
    means = {}
    for m, runs in sorted(curves.items()):
        steps = sorted(set.intersection(*[set(v) for v in runs]))
        means[m] = {s: st.mean(v[s] for v in runs) for s in steps}
        print(f'{m:22s} n={len(runs)} ' + ' '.join(f'{s//1000}k:{means[m][s]:.0f}' for s in steps))
        finals = [v[steps[-1]] for v in runs]
        print(f'{"":22s} final {steps[-1]}: {st.mean(finals):.1f} +- {st.pstdev(finals):.1f}  per seed {[round(x,1) for x in finals]}')
    for h, b in base.items():
        if h not in means: continue
        for other in ['sac', b]:
            if other not in means: continue
            bad = [s for s in means[h] if s >= 0.2 * budget[env] and s > 0 and s in means[other] and means[h][s] <= means[other][s]]
            print(f'{h} vs {other}: {"above at every evaluation after 20%" if not bad else "not above at " + str(bad)}')
