#!/bin/sh
# hlt_rollout --plan-check on the final networks (checkpoint.pt) of the ensemble runs and their controls: how
# well the planner's models rank its own samples against their replay on the simulator. Every 5th step of one
# episode from reset seed 500 (Ant: 400 steps; cart-pole: 250). RUNS: where the sweeps of this folder were
# run (RUNS/ant_ctl, RUNS/ant_e5, RUNS/cp_e5, ... as in their sweep.yaml's command); output: one .txt per run
# in the current directory.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
RUNS=${RUNS:-results}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
check() {  # name env run-dir extra...
  name=$1 env=$2 run=$3; shift 3
  [ -f $name.txt ] && return
  [ -f $run/checkpoint.pt ] || { echo "skipped $name: no $run/checkpoint.pt"; return; }
  $B --env $env --policy checkpoint:$run/checkpoint.pt --controller stochastic_hybrid --seed 500 \
    --episodes 1 --plan-check 5 "$@" > $name.tmp 2>&1 && mv $name.tmp $name.txt
}
for v in ${ANT_VARIANTS:-ctl e5 e5p1}; do
  for s in 100 101 102 103 104; do
    check ant_${v}_s$s ant $RUNS/ant_$v/ant/hybrid-imitation/seed$s --max-steps 400
  done
done
for v in ${CP_VARIANTS:-ctl110 e5_110}; do
  for s in 110 111 112 113; do
    check cartpole_${v}_s$s cartpole_swingup $RUNS/cp_$v/cartpole_swingup/hybrid-stochastic/seed$s
  done
done
for v in ${CP100_VARIANTS:-ctl100 e5}; do
  for s in 100 101 102 103; do
    check cartpole_${v}_s$s cartpole_swingup $RUNS/cp_$v/cartpole_swingup/hybrid-stochastic/seed$s
  done
done
