#!/usr/bin/env bash
# The README's main command: install what is missing, build, train the default experiment (stochastic
# hybrid learning on the cart-pole swing-up, 4000 agent steps = 16k simulator steps, a few minutes on 2 cores),
# and plot its learning curves. Re-running it resumes or re-plots the same run.
#   HLT_RUN_DIR  where the run goes (default runs/quickstart)
#   HLT_STEPS    agent steps (default 4000)
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
./scripts/build.sh hlt_train hlt_rollout
run_dir=${HLT_RUN_DIR:-runs/quickstart}
steps=${HLT_STEPS:-4000}
out="$run_dir/hybrid-stochastic/seed0"
if [ -f "$out/config.yaml" ]; then
  build/experiments/hlt_train --resume "$out" --steps "$steps"
else
  build/experiments/hlt_train --env cartpole_swingup --method hybrid-stochastic --seed 0 --steps "$steps" \
    --out "$out"
fi
/usr/bin/python3 experiments/hlt_plot.py "$run_dir" --out "$run_dir/learning_curve.png" \
  --tags eval/return_mean,eval/policy_return_mean,eval/planner_return_mean \
  --title "cart-pole swing-up, stochastic hybrid learning"
build/experiments/hlt_rollout --env cartpole_swingup --policy "checkpoint:$out/final.pt" --episodes 1 \
  --strip "$run_dir/policy_strip.png" > /dev/null
echo "results: $out/scalars.csv (log), $out/config.yaml (resolved config), $out/final.pt (networks)"
echo "figure:  $run_dir/learning_curve.png; policy frames: $run_dir/policy_strip.png"
