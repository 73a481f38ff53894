#!/bin/sh
# hlt_rollout --plan-check on the locomotion runs of locomotion_a3132e7 (their final checkpoint.pt: hopper 80k,
# half-cheetah 50k agent steps), where the models were trained on the data of an exploring learner: every 5th
# step of 1 episode of 1000 steps, reset seed 500. RUNS: the tree locomotion_a3132e7's sweep.yaml trained into.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
RUNS=${RUNS:-results/locomotion_a3132e7}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
check() {  # name env run-dir controller
  [ -f $1.txt ] && return
  [ -f $3/checkpoint.pt ] || { echo "skipped $1: no $3/checkpoint.pt"; return; }
  $B --env $2 --policy checkpoint:$3/checkpoint.pt --controller $4 --seed 500 --episodes 1 --plan-check 5 \
    > $1.tmp 2>&1 && mv $1.tmp $1.txt
}
for s in 0 1 2 3 4; do
  check half_cheetah_hybrid_s$s half_cheetah $RUNS/half_cheetah/hybrid-stochastic/seed$s stochastic_hybrid
  check hopper_hybrid_s$s hopper $RUNS/hopper/hybrid-stochastic/seed$s stochastic_hybrid
done
