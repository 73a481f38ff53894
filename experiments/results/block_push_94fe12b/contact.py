"""Per evaluation episode of a block_push run made with eval.trace=true: the block's distance to the target at
the start and the end (m), the tool's closest approach to the block's centre (m), and the number of steps with
the tool within 5 cm of the block's centre (touching it: the tool's centre touches the block at 4 cm).
    python3 contact.py RUN_DIR [RUN_DIR ...]"""
import csv, glob, math, os, sys

for run in sys.argv[1:]:
    files = sorted(glob.glob(os.path.join(run, "eval_traces", "step*.csv")),
                   key=lambda p: (len(p), p))
    for f in files:
        episodes = {}
        for row in csv.DictReader(open(f)):
            episodes.setdefault(int(row["episode"]), []).append(row)
        cells = []
        for rows in episodes.values():
            tool = [math.hypot(float(r["obs_0"]), float(r["obs_1"])) for r in rows]
            target = [math.hypot(float(r["obs_3"]), float(r["obs_4"])) for r in rows]
            touching = sum(d < 0.05 for d in tool)
            cells.append(f"{target[0]:.2f}->{target[-1]:.2f} closest {min(tool):.2f} touching {touching}")
        print(run, os.path.basename(f), " | ".join(cells))
