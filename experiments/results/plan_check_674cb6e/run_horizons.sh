#!/bin/sh
# hlt_rollout --plan-check on the Ant runs with the reward model of the reached state (ant_g0next, as run.sh),
# planned with H 1 and H 5 instead of the runs' 20, to see how the models' ranking falls with the horizon.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
RUNS=${RUNS:-results}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for h in 1 5; do
  for s in 100 101 102 103 104; do
    $B --env ant --policy checkpoint:$RUNS/ant_g0next/ant/hybrid-imitation/seed$s/checkpoint.pt --controller stochastic_hybrid \
      --seed 500 --episodes 1 --max-steps 400 --plan-check 5 planner.horizon=$h > ant_k1_next_h${h}_s$s.txt 2>&1
  done
done
