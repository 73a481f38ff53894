# Per evaluation episode of the hybrid (and its policy alone): return, first agent step with cos theta > 0.95,
# whether the pole falls back (cos < 0.9 after being up), and whether the cart is at the rail's end
# (|x| >= 0.99) while the pole is up or falling back after that point.
import csv, collections, glob, os, sys
root = sys.argv[1]
for step in (16000, 20000):
    print('== agent step', step // 4)
    for comp in ('', '_policy'):
        tot = collections.Counter()
        for d in sorted(glob.glob(root + '/cartpole_swingup/hybrid-stochastic/seed*/'), key=lambda p: int(p.rstrip('/').split('seed')[-1])):
            f = d + 'eval_traces/step%d%s.csv' % (step, comp)
            if not os.path.exists(f): continue
            eps = collections.defaultdict(list)
            for r in csv.DictReader(open(f)):
                eps[int(r['episode'])].append(r)
            out = []
            for e, rows in sorted(eps.items()):
                ret = sum(float(r['reward']) for r in rows)
                cos = [float(r['obs_2']) for r in rows]
                x = [float(r['obs_0']) for r in rows]
                up = next((i for i, c in enumerate(cos) if c > 0.95), None)
                fell = up is not None and any(c < 0.9 for c in cos[up:])
                fall_at = next((i for i in range(up, len(cos)) if cos[i] < 0.9), None) if fell else None
                rail = fell and any(abs(v) >= 0.99 for v in x[max(up, fall_at - 12):fall_at + 1])
                tag = '%d/%s%s' % (ret, up, '/x' + ('R' if rail else '') if fell else '')
                out.append(tag)
                tot['episodes'] += 1
                if ret < 860: tot['below 860'] += 1
                if fell: tot['fell back'] += 1
                if rail: tot['fell back at the rail'] += 1
                if up is not None and up >= 28: tot['up late (>= 28)'] += 1
            print('%s seed%s: %s' % (comp or 'hybrid', d.rstrip('/').split('seed')[-1], ' '.join(out)))
        print(comp or 'hybrid', dict(tot))
