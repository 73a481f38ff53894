#!/bin/sh
# The stochastic hybrid's planner on a copy of the simulator, with behaviour cloning's policy after 4 demonstrations.
B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for s in 100 101 102 103 104; do
  $B --env ant --policy checkpoint:ant_bc4_s$s/checkpoint.pt --episodes 5 --max-steps 400 --seed 500 > ant_mean_s$s.txt 2>&1
  $B --env ant --policy checkpoint:ant_bc4_s$s/checkpoint.pt --controller stochastic_hybrid --plan-on simulator --episodes 5 --max-steps 400 --seed 500 > ant_sim_s$s.txt 2>&1
done
