#!/bin/sh
# The final networks (10 demonstrations) of hybrid imitation runs on the Ant, 5 episodes of 400 steps from
# reset seed 500 each: the hybrid as trained (*_hybrid.txt), the same planner with lambda 1e6 (*_uniform.txt:
# the predicted returns carry no weight; the weights are the samples' policy densities), and the policy's
# mean alone (*_policy.txt). PREFIX names the files; RUNS is the tree the runs were trained into:
#   PREFIX=dart RUNS=results/ant_dart sh run.sh   (this folder's ant_tuning/sweep.yaml)
#   PREFIX=ctl RUNS=results/ant_horizon_tuning sh run.sh   (ant_horizon_9dfa8e6/tuning_seeds100-104/sweep.yaml)
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for s in ${SEEDS:-100 101 102 103 104}; do
  C="--env ant --policy checkpoint:$RUNS/ant/hybrid-imitation/seed$s/checkpoint.pt --max-steps 400 --seed 500 --episodes 5"
  $B $C --controller stochastic_hybrid > ${PREFIX}_s${s}_hybrid.txt 2>&1
  $B $C --controller stochastic_hybrid planner.lambda=1000000 > ${PREFIX}_s${s}_uniform.txt 2>&1
  $B $C --controller policy > ${PREFIX}_s${s}_policy.txt 2>&1
done
