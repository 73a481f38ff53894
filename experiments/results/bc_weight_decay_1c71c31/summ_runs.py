"""Mean evaluation return of Ant imitation runs over 1-10 demonstrations: per seed, at 4 and 10, per count.
Usage: summ_runs.py DIR... (each DIR holds seed<N>/scalars.csv, e.g. seeds0-4/ant/bc)."""
import csv, glob, os, sys
for path in sys.argv[1:]:
    per = {}
    for d in sorted(glob.glob(os.path.join(path, 'seed*'))):
        v = {}
        for r in csv.reader(open(os.path.join(d, 'scalars.csv'))):
            if r[2] == 'imitation/eval_return_mean': v[int(r[1])] = float(r[3])
        per[os.path.basename(d)] = v
    allc = [sum(v.values()) / len(v) for v in per.values()]
    at = lambda c: sum(v.get(c, 0) for v in per.values()) / len(per)
    print(f"{path}: all {sum(allc) / len(allc):.1f} ({', '.join(f'{x:.0f}' for x in allc)})  @4 {at(4):.0f} "
          f"@10 {at(10):.0f} | {' '.join(f'{at(c):.0f}' for c in range(1, 11))}")
