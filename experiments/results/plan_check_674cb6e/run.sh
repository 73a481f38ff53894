#!/bin/sh
# hlt_rollout --plan-check (674cb6e): how well each run's learned models rank its stochastic planner's own
# samples, against their replay on the simulator, over the run's final networks (checkpoint.pt). Every 5th
# step of 1 episode (Ant: 400 steps; cart-pole: 250; block stacking: 2 episodes of 200), reset seed 500.
# RUNS: the results trees the runs were trained into (README.txt says by which sweep each); output: one .txt
# per run and horizon in the current directory.
R=${HLT_SOURCE_DIR:-$(cd "$(dirname "$0")/../../.." && pwd)}
B=${HLT_ROLLOUT:-${HLT_BUILD_DIR:-$R/build}/experiments/hlt_rollout}
RUNS=${RUNS:-results}
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
check() {  # name env run-dir episodes extra...
  name=$1 env=$2 run=$3 episodes=$4; shift 4
  [ -f $name.txt ] && return
  [ -f $run/checkpoint.pt ] || { echo "skipped $name: no $run/checkpoint.pt"; return; }
  $B --env $env --policy checkpoint:$run/checkpoint.pt --controller stochastic_hybrid --seed 500 \
    --episodes $episodes --plan-check 5 "$@" > $name.tmp 2>&1 && mv $name.tmp $name.txt
}
for s in 100 101 102 103 104; do
  check ant_k1_td_s$s ant $RUNS/ant_horizon_tuning/ant/hybrid-imitation/seed$s 1 --max-steps 400
  check ant_k5_td_s$s ant $RUNS/ant_k5/ant/hybrid-imitation/seed$s 1 --max-steps 400
  check ant_k1_next_s$s ant $RUNS/ant_g0next/ant/hybrid-imitation/seed$s 1 --max-steps 400
  check ant_k5_next_s$s ant $RUNS/ant_k5next/ant/hybrid-imitation/seed$s 1 --max-steps 400
done
for s in 100 102; do
  check ant_k1_td_s${s}_h60 ant $RUNS/ant_horizon_tuning/ant/hybrid-imitation/seed$s 1 --max-steps 400 planner.horizon=60
  check ant_k5_next_s${s}_h60 ant $RUNS/ant_k5next/ant/hybrid-imitation/seed$s 1 --max-steps 400 planner.horizon=60
done
for s in 100 101 102 103; do  # (the K 1 run of seed 103 was stopped before its end: not checked)
  check cartpole_k1_s$s cartpole_swingup $RUNS/cartpole_ctl/cartpole_swingup/hybrid-stochastic/seed$s 1
  check cartpole_k5_s$s cartpole_swingup $RUNS/cartpole_k5/cartpole_swingup/hybrid-stochastic/seed$s 1
done
check stack_k1_s100 block_stack $RUNS/stack_state/block_stack/hybrid-imitation/seed100 2
# (stacking's checks take about 5 minutes each; these four were run)
for s in 100 101; do
  check stack_k5_s$s block_stack $RUNS/stack_k5/block_stack/hybrid-imitation/seed$s 2
done
for s in 3 4; do
  check stack_k5_s$s block_stack $RUNS/stack_k5_seeds0-4/block_stack/hybrid-imitation/seed$s 2
done
