#!/bin/bash
# usage: rail.sh RUN LABEL [CORE]: RUN's final networks (checkpoint.pt) on 10 episodes from reset seed 1000,
# planned on its learned models, on the simulator's dynamics (with its learned reward model), and with policy
# samples only; per mode rail_failures.py's counts of the cart's impacts at the end of its rail with the pole up.
# Run from the repository root after ./scripts/build.sh; writes its CSVs to $TMPDIR.
R=$1; L=$2; C=${3:-0}
B=build/experiments/hlt_rollout
D=$(dirname "$0"); T=${TMPDIR:-/tmp}/rail_$$; mkdir -p "$T"
mode(){ name=$1; shift
  r=$(OPENBLAS_CORETYPE=SkylakeX taskset -c "$C" $B --env cartpole_swingup --policy checkpoint:$R/checkpoint.pt \
      --controller stochastic_hybrid --episodes 10 --seed 1000 --frame-skip 4 --csv "$T/ep.csv" \
      --models $R/checkpoint.pt --predictions "$T/pred.csv" "$@" 2>&1 | grep "^mean return")
  echo "$L $name: $r"
  /usr/bin/python3 "$D/rail_failures.py" "$T/ep.csv" "$T/pred.csv" | sed 's/^/    /'; }
mode learned
mode simulator-dynamics --plan-on simulator-dynamics
mode policy-samples-only planner.plan_samples=0
rm -rf "$T"
