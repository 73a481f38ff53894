#!/bin/sh
# Block stacking's learned models fitted offline (hlt_model_fit, hybrid imitation's settings for block_stack,
# 3000 updates) to 3 scripted demonstrations and scored on 5 others: the reward model (regressed, gamma 0) on
# r(s, a) and on r(s', a) against the rewards' spread. Run from an empty directory; output in model_fit_stack.txt.
B=${HLT_BUILD_DIR:-/work/main/build}/experiments
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
$B/hlt_rollout --env block_stack --policy scripted:block_stack --episodes 3 --seed 11 --demos train3.hltd
$B/hlt_rollout --env block_stack --policy scripted:block_stack --episodes 5 --seed 12 --demos test5.hltd
for input in state next_state; do
  echo "== model.reward_input=$input"
  $B/hlt_model_fit --env block_stack --method hybrid-imitation --train train3.hltd --test test5.hltd --updates 3000 \
    --report-every 1000 model.reward_input=$input | grep -v "rms "
done
