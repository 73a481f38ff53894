#!/bin/sh
# The final (5k-agent-step) networks of the stochastic hybrid's cart-pole settings of 3739372 ("kg":
# methods/hybrid-stochastic/cartpole_swingup.yaml before 27779e1 added 10 model updates and 688d6ab five
# dynamics models, hence train.model_updates=5 model.ensemble=1 here) for the seeds whose last evaluations
# fail a catch (6, 104, 109: a good policy alone) or lean on the planner (23, 26: a poorer policy), each
# planned on its learned models, on the simulator's dynamics with the learned reward, and with the evaluation
# rule changed: policy samples only (the paper's Alg. 2), Theorem 2's policy prior on every sample, plan noise
# 0.1, the policy's mean as one rollout. 10 episodes from reset seed 1000.
# Run from the repository with OPENBLAS_CORETYPE=SkylakeX; writes into $OUT (default /tmp/issue11_diag5k).
set -e
OUT=${OUT:-/tmp/issue11_diag5k}
mkdir -p "$OUT"
for s in 6 104 109 23 26; do
  [ -f "$OUT/s$s/final.pt" ] || build/experiments/hlt_train --env cartpole_swingup --method hybrid-stochastic \
    --seed $s --steps 5000 --out "$OUT/s$s" --no-progress train.model_updates=5 model.ensemble=1 > /dev/null
  for v in "learned" "simulator-dynamics" "learned planner.plan_samples=0" "learned planner.plan_prior=true" \
           "learned mppi.sigma=0.1" "learned planner.mean_rollout=true"; do
    case $s in 23|26) case "$v" in *prior*|*sigma*|*mean_rollout*) continue ;; esac ;; esac
    set -- $v
    p=$1; shift
    echo "seed $s, plan on $p $*: $(build/experiments/hlt_rollout --env cartpole_swingup \
      --policy checkpoint:$OUT/s$s/checkpoint.pt --controller stochastic_hybrid --plan-on $p --episodes 10 \
      --seed 1000 --frame-skip 4 "$@" | tail -1)"
  done
done
