#!/bin/sh
# hlt_rollout --plan-check on the final networks of ant_tuning (as plan_check_674cb6e/run.sh does for the
# other Ant runs). RUNS: the tree ant_tuning/sweep.yaml was trained into (seeds0-4/sweep.yaml with SEEDS="0 1 2 3 4").
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for s in ${SEEDS:-100 101 102 103 104}; do
  $B --env ant --policy checkpoint:$RUNS/ant/hybrid-imitation/seed$s/checkpoint.pt --controller stochastic_hybrid \
    --seed 500 --episodes 1 --max-steps 400 --plan-check 5 > ant_dart_s$s.txt 2>&1
done
