#!/bin/sh
# Block stacking's dynamics model fitted offline with the open-loop loss (model.rollout_steps K) against the
# one-step loss: hlt_model_fit with hybrid imitation's settings for block_stack, 3000 updates, 3 scripted
# demonstrations, scored on 5 others k steps ahead against "no change". Run from an empty directory.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_BUILD_DIR:-$R/build}/experiments
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
[ -f train3.hltd ] || $B/hlt_rollout --env block_stack --policy scripted:block_stack --episodes 3 --seed 11 --demos train3.hltd
[ -f test5.hltd ] || $B/hlt_rollout --env block_stack --policy scripted:block_stack --episodes 5 --seed 12 --demos test5.hltd
for K in 1 5 10 20; do
  echo "== 3000 updates, model.rollout_steps=$K"
  /usr/bin/time -f "%e s" $B/hlt_model_fit --env block_stack --method hybrid-imitation --train train3.hltd --test test5.hltd \
    --updates 3000 --report-every 1000 --horizons 1,5,20,40 model.rollout_steps=$K 2>&1 | grep -v "rms "
done
