#!/bin/sh
# Block stacking, a tuning seed (argument; 101 and 100 were run, in that order) after 3 demonstrations: hybrid
# imitation's policy alone, its planner on its learned models, and its planner on the simulator's transitions
# scored by its learned reward model.
S=${1:-101}
B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
/work/main/build/experiments/hlt_train --env block_stack --method hybrid-imitation --seed $S --steps 3 --out stack_hi3_s$S imitation.eval_episodes=10 imitation.expert=scripted:block_stack > stack_hi3_s$S.log 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s$S/checkpoint.pt --episodes 10 --max-steps 100 --seed 500 > stack_hi_mean_s$S.txt 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s$S/checkpoint.pt --controller stochastic_hybrid --episodes 10 --max-steps 100 --seed 500 > stack_hi_learned_s$S.txt 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s$S/checkpoint.pt --controller stochastic_hybrid --plan-on simulator-dynamics --episodes 2 --max-steps 100 --seed 500 > stack_hi_simdyn_s$S.txt 2>&1
