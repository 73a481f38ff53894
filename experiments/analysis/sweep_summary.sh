#!/bin/sh
# Per-seed tables of the stochastic hybrid's cart-pole sweeps (evaluation return, policy alone, planner alone
# at 1k-5k agent steps) and issue 11 part 1's per-seed conditions (claims.py), one block per sweep folder.
# Usage (from anywhere): sweep_summary.sh RESULTS_FOLDER SWEEP...  (folders missing from RESULTS_FOLDER are
# skipped)
here="$(cd "$(dirname "$0")" && pwd)"
cd "$1" || exit 1
shift
for v in "$@"; do
  [ -d "$v" ] || continue
  echo "== $v: $(head -1 "$v/sweep.yaml" | sed 's/^# //')"
  for tag in eval/return_mean eval/policy_return_mean eval/planner_return_mean; do
    echo "-- $tag"
    /usr/bin/python3 "$here/seed_table.py" "$v/cartpole_swingup/hybrid-stochastic" --tag $tag \
      --at 4000,8000,12000,16000,20000 --label 1k,2k,3k,4k,5k
  done
  echo "-- drops below 850 after 880; evaluations more than 10 below the better component (agent step, return[, component])"
  /usr/bin/python3 "$here/../results/cartpole_issue11_8d20757/claims.py" "$v"
  echo
done
