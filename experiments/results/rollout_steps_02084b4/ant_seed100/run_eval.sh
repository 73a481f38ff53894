#!/bin/sh
# Ant, seed 100, 4 demonstrations, the dynamics model trained with model.rollout_steps 5 (k5: the paper's TD
# reward model; k5next: the reward model regressed on the reached state): the hybrid's planner on its learned
# models at H 20 and H 60, and at H 60 with planner.clamp_to_data, 5 episodes from reset seed 500 (the starts
# of reward_model_bf60d34/ant_seed100). Run from an empty directory; runs/ holds the two runs' logs.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../../.." && pwd)}
B=${HLT_BUILD_DIR:-$R/build}/experiments
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
for v in k5next k5; do
  extra="model.rollout_steps=5"
  [ $v = k5next ] && extra="$extra model.reward_gamma=0 model.reward_input=next_state"
  run=${v}_s100
  [ -f $run/final.pt ] || $B/hlt_train --env ant --method hybrid-imitation --seed 100 --steps 4 --out $run --no-progress imitation.eval_episodes=10 $extra
  C="--env ant --policy checkpoint:$run/checkpoint.pt --controller stochastic_hybrid --max-steps 400 --seed 500"
  $B/hlt_rollout $C --episodes 5 > ${run}_learned_h20.txt 2>&1
  $B/hlt_rollout $C --episodes 5 planner.horizon=60 > ${run}_learned_h60.txt 2>&1
  $B/hlt_rollout $C --episodes 5 planner.horizon=60 planner.clamp_to_data=true > ${run}_learned_h60_clamp.txt 2>&1
done
