#!/usr/bin/env python3
"""What a block_stack episode did, from hlt_rollout --csv files: when the fingers first closed, how high the
block was lifted, where it ended against the base, whether the gripper was open at the end.

  hlt_rollout --env block_stack --policy checkpoint:RUN/final.pt --episodes 5 --seed 1000 --csv OUT.csv
  experiments/analysis/stack_failures.py OUT.csv [...]
"""
import csv
import sys

# Observation layout (envs/robot/block_stack.h) after the csv's episode and step columns.
EE, BLOCK, BASE, GRIP = 2, 5, 8, 11

for path in sys.argv[1:]:
    episodes = {}
    with open(path) as f:
        rows = csv.reader(f)
        header = next(rows)
        action0 = header.index("action_0")
        for row in rows:
            v = [float(x) for x in row[: action0 + 5]]
            episodes.setdefault(int(v[0]), []).append(v)
    for e, steps in sorted(episodes.items()):
        closed = [int(s[1]) for s in steps if s[GRIP] < 0.9]
        lift = max(s[BLOCK + 2] for s in steps) - 0.025
        last = steps[-1]
        dxy = ((last[BLOCK] - last[BASE]) ** 2 + (last[BLOCK + 1] - last[BASE + 1]) ** 2) ** 0.5
        dz = last[BLOCK + 2] - last[BASE + 2] - 0.05
        ret = sum(s[action0 + 4] for s in steps)
        first = closed[0] if closed else "never"
        print(f"{path} episode {e}: return {ret:.1f}, fingers first closed at step {first}, "
              f"block lifted {100 * lift:.1f} cm at most, ends {100 * dxy:.1f} cm from the base's axis "
              f"and {100 * dz:+.1f} cm off the stacking height, gripper {'open' if last[GRIP] > 0.9 else 'closed'}")
