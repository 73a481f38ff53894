#!/bin/bash
# methods.sh BIN OUTDIR: each method 2000 agent steps on the cart-pole, seed 0, eval off, one thread on core 1;
# prints the median time/agent_step_ms and time/act_ms over the episodes.
BIN=$1; OUT=$2
for m in hybrid-stochastic hybrid-deterministic mppi mpc-deterministic sac; do
  rm -rf $OUT/$m; taskset -c 1 $BIN --env cartpole_swingup --method $m --seed 0 --steps 2000 --out $OUT/$m --no-progress eval.every=0 >/dev/null 2>&1
  python3 -c "
import csv,statistics
rows=list(csv.DictReader(open('$OUT/$m/scalars.csv')))
def med(t):
    v=[float(r['value']) for r in rows if r['tag']==t]
    return round(statistics.median(v),3) if v else None
print('$m', 'agent_step_ms', med('time/agent_step_ms'), 'act_ms', med('time/act_ms'), 'update_ms', med('time/update_ms'))"
done
