#!/bin/sh
# The 4k networks of seeds 3 and 6 (defaults; checkpoint.pt, which also holds the SAC critics of the
# terminal value), planned on the learned models, on the simulator's dynamics
# with the learned reward, and on the simulator; then the dynamics model's one-step error at the rail.
# Run from the repository with OPENBLAS_CORETYPE=SkylakeX; writes into $OUT (default /tmp/issue11_diag).
set -e
OUT=${OUT:-/tmp/issue11_diag}
mkdir -p "$OUT"
for s in 3 6; do
  build/experiments/hlt_train --env cartpole_swingup --method hybrid-stochastic --seed $s --steps 4000 \
    --out "$OUT/d$s" --no-progress > /dev/null
  for p in learned simulator-dynamics simulator; do
    for o in "" "planner.horizon=10" "planner.horizon=20" "planner.terminal_value=0.2" "planner.terminal_value=1"; do
      [ $s = 3 ] && [ -n "$o" ] && continue
      echo "seed $s, plan on $p, $o: $(build/experiments/hlt_rollout --env cartpole_swingup \
        --policy checkpoint:$OUT/d$s/checkpoint.pt --controller stochastic_hybrid --plan-on $p --episodes 10 \
        --seed 1000 --frame-skip 4 $o | tail -1)"
    done
  done
done
build/experiments/hlt_rollout --env cartpole_swingup --policy checkpoint:$OUT/d3/checkpoint.pt \
  --controller stochastic_hybrid --episodes 5 --seed 1000 --frame-skip 4 --csv "$OUT/d3_ep.csv" \
  --models "$OUT/d3/checkpoint.pt" --predictions "$OUT/d3_pred.csv" > /dev/null
/usr/bin/python3 experiments/results/cartpole_issue11_8d20757/rail_error.py "$OUT/d3_ep.csv" "$OUT/d3_pred.csv"
