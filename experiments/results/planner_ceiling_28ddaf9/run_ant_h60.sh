#!/bin/sh
# The Ant planner on the simulator with H 60 on two more tuning seeds' 4-demonstration policies (2 episodes each).
B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for s in 101 104; do
  $B --env ant --policy checkpoint:ant_bc4_s$s/checkpoint.pt --controller stochastic_hybrid --plan-on simulator --episodes 2 --max-steps 400 --seed 500 planner.horizon=60 > ant_sim_h60_s$s.txt 2>&1
done
