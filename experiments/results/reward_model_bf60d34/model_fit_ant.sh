#!/bin/sh
# The Ant's learned models fitted offline (hlt_model_fit, hybrid imitation's settings, 2000 updates: its four
# iterations of 500) to 4 expert demonstrations and scored on 3 others: the reward model against the rewards'
# spread, and the dynamics model's open-loop predictions k steps ahead against "no change". Run from an
# empty directory; output in model_fit_ant.txt.
B=${HLT_BUILD_DIR:-/work/main/build}/experiments
E=/work/main/agents/experts/ant_pybullet_2017may.txt
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
$B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 4 --seed 11 --demos train4.hltd
$B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 3 --seed 12 --demos test3.hltd
$B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 10 --seed 13 --demos train10.hltd
fit() {
  train=${TRAIN:-train4.hltd}
  echo "== $train, ${UPDATES:-2000} updates, $*"
  $B/hlt_model_fit --env ant --method hybrid-imitation --train $train --test test3.hltd --updates ${UPDATES:-2000} \
    --report-every 1000 --horizons 1,5,20,40,60 "$@" | grep -v "rms "
}
fit
fit planner.clamp_to_data=true
fit model.reward_gamma=0
fit model.reward_gamma=0 model.reward_input=next_state
fit model.reward_gamma=0 model.reward_input=next_state planner.clamp_to_data=true model.weight_decay=0.001
# More data (10 demonstrations) and more updates, with the clamp
TRAIN=train10.hltd fit planner.clamp_to_data=true
UPDATES=5000 fit planner.clamp_to_data=true
TRAIN=train10.hltd UPDATES=5000 fit planner.clamp_to_data=true
