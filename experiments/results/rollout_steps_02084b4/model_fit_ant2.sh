#!/bin/sh
# Follow-up to model_fit_ant.sh (run in the same directory): K 2 and 3, and K 1 / 5 fitted to 10 demonstrations.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_BUILD_DIR:-$R/build}/experiments
E=$R/agents/experts/ant_pybullet_2017may.txt
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
[ -f train10.hltd ] || $B/hlt_rollout --env ant --policy expert:$E --frame-skip 1 --max-steps 400 --episodes 10 --seed 13 --demos train10.hltd
fit() {
  echo "== ${TRAIN:-train4.hltd}, ${UPDATES:-2000} updates, $*"
  /usr/bin/time -f "%e s" $B/hlt_model_fit --env ant --method hybrid-imitation --train ${TRAIN:-train4.hltd} --test test3.hltd \
    --updates ${UPDATES:-2000} --report-every 1000 --horizons 1,5,20,40,60 "$@" 2>&1 | grep -v "rms "
}
for K in 2 3; do fit model.rollout_steps=$K; done
for K in 1 5; do TRAIN=train10.hltd fit model.rollout_steps=$K; done
UPDATES=5000 fit model.rollout_steps=5
