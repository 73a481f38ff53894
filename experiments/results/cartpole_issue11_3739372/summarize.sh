#!/bin/sh
# summary.txt of this folder: per-seed tables (evaluation return, policy alone, planner alone at 1k-5k agent
# steps) and the issue's per-seed conditions (claims.py) for every sweep folder here. Run from the repository.
cd "$(dirname "$0")"
for v in mu10_100 mu10_110 mu10_09 mu10_20 def_30 kg_20 sig01_100 sig01_110 sig01_09 sig01_20 pn_100 pn_110 prior_100 ps0_100 ps0_110; do
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
