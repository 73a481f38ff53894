#!/bin/bash
# agent_step.sh BIN OUTDIR: 2000-agent-step hybrid-stochastic cart-pole runs, seed 0, eval off; per kernel,
# one thread pinned to core 1, then train.threads=2 on cores 0-1. Prints the median time/agent_step_ms.
BIN=$1; OUT=$2
med() { python3 -c "
import csv,statistics,sys
v=[float(r['value']) for r in csv.DictReader(open('$1/scalars.csv')) if r['tag']=='time/agent_step_ms']
print('$2', 'median', round(statistics.median(v),3), 'episodes', len(v), 'per episode', [round(x,2) for x in v])"; }
for k in SkylakeX; do
  rm -rf $OUT/t1_$k; OPENBLAS_CORETYPE=$k taskset -c 1 $BIN --env cartpole_swingup --method hybrid-stochastic --seed 0 --steps 2000 --out $OUT/t1_$k --no-progress eval.every=0 >/dev/null 2>&1; med $OUT/t1_$k "$k threads=1"
done
for k in SkylakeX; do
  rm -rf $OUT/t2_$k; OPENBLAS_CORETYPE=$k taskset -c 0,1 $BIN --env cartpole_swingup --method hybrid-stochastic --seed 0 --steps 2000 --out $OUT/t2_$k --no-progress eval.every=0 train.threads=2 >/dev/null 2>&1; med $OUT/t2_$k "$k threads=2"
done
