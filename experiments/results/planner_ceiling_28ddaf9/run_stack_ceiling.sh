#!/bin/sh
# The stochastic hybrid's planner (block_stack config: H 40, K 40 + 20, lambda 1, averaged before the squash)
# on a copy of the simulator, with behaviour cloning's policy after 3 demonstrations; 100-step episodes.
B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for s in 100 101 102; do
  $B --env block_stack --policy checkpoint:stack_bc3_s$s/checkpoint.pt --episodes 10 --max-steps 100 --seed 500 > stack_mean_s$s.txt 2>&1
  $B --env block_stack --policy checkpoint:stack_bc3_s$s/checkpoint.pt --controller stochastic_hybrid --plan-on simulator --episodes 2 --max-steps 100 --seed 500 > stack_sim_s$s.txt 2>&1
done
