#!/bin/sh
# The Ant's dynamics model fitted offline with the open-loop loss (model.rollout_steps K) against the
# one-step loss: hlt_model_fit with hybrid imitation's settings, 2000 updates, 4 expert demonstrations,
# scored on 3 others k steps ahead against "no change". Run from an empty directory.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_BUILD_DIR:-$R/build}/experiments
E=$R/agents/experts/ant_pybullet_2017may.txt
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
[ -f train4.hltd ] || $B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 4 --seed 11 --demos train4.hltd
[ -f test3.hltd ] || $B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 3 --seed 12 --demos test3.hltd
fit() {
  echo "== ${UPDATES:-2000} updates, $*"
  /usr/bin/time -f "%e s" $B/hlt_model_fit --env ant --method hybrid-imitation --train train4.hltd --test test3.hltd \
    --updates ${UPDATES:-2000} --report-every 1000 --horizons 1,5,20,40,60 "$@" 2>&1 | grep -v "rms "
}
for K in 1 5 10 20 40; do
  fit model.rollout_steps=$K
  fit model.rollout_steps=$K planner.clamp_to_data=true
done
