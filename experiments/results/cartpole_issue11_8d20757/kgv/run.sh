#!/bin/sh
# kg's four late failures (seeds 6, 104, 109, 119) rerun with every evaluation also made with 200 samples
# (eval.variants; the runs are otherwise identical to kg_09's, kg's and kg_110's). From the repository, with
# OPENBLAS_CORETYPE=SkylakeX; by 35ed058's hlt_train.
for s in 6 104 109 119; do
  build/experiments/hlt_train --env cartpole_swingup --method hybrid-stochastic --seed $s --steps 5000 \
    --out results/kgv/cartpole_swingup/hybrid-stochastic/seed$s --no-progress model.reward_gamma=0 \
    planner.terminal_value=0.2 model.rollout_steps=5 planner.horizon=10 \
    "eval.variants=planner.samples=100 planner.plan_samples=100"
done
