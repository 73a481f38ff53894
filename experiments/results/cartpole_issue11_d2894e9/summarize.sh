#!/bin/sh
# summary.txt of this folder: per-seed tables (evaluation return, policy alone, planner alone at 1k-5k agent
# steps) and the issue's per-seed conditions (claims.py) for every sweep folder here. Run from the repository.
cd "$(dirname "$0")"
for v in mu20_100 mu20_110 e5_100 e5_110 e5_115 e5p03_100 e5_09 e5_20; do
  [ -d $v ] || continue
  echo "== $v: $(head -1 $v/sweep.yaml | sed 's/^# //')"
  for tag in eval/return_mean eval/policy_return_mean eval/planner_return_mean; do
    echo "-- $tag"
    /usr/bin/python3 ../../analysis/seed_table.py $v/cartpole_swingup/hybrid-stochastic --tag $tag \
      --at 4000,8000,12000,16000,20000 --label 1k,2k,3k,4k,5k
  done
  echo "-- drops below 850 after 880; evaluations more than 10 below the better component (agent step, return[, component])"
  /usr/bin/python3 ../cartpole_issue11_8d20757/claims.py $v
  echo
done
