#!/bin/sh
# Block stacking, tuning seed 100 after 3 demonstrations: hybrid imitation's planner on its learned models,
# and on the simulator's transitions scored by its learned reward model (run after run_stack_ceiling.sh).

B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
/work/main/build/experiments/hlt_train --env block_stack --method hybrid-imitation --seed 100 --steps 3 --out stack_hi3_s100 imitation.eval_episodes=10 imitation.expert=scripted:block_stack > stack_hi3_s100.log 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s100/checkpoint.pt --episodes 10 --max-steps 100 --seed 500 > stack_hi_mean_s100.txt 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s100/checkpoint.pt --controller stochastic_hybrid --episodes 10 --max-steps 100 --seed 500 > stack_hi_learned_s100.txt 2>&1
$B --env block_stack --policy checkpoint:stack_hi3_s100/checkpoint.pt --controller stochastic_hybrid --plan-on simulator-dynamics --episodes 2 --max-steps 100 --seed 500 > stack_hi_simdyn_s100.txt 2>&1
