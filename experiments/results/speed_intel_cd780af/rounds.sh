#!/bin/bash
# rounds.sh BIN OUT ROUNDS: every benchmark in its own process, pinned to core 1, ROUNDS rounds in turn,
# 3 repetitions each; prints "round name median".
BIN=$1; OUT=$2; R=${3:-3}
names="DeterministicHybrid/n:5/ DeterministicHybridFloor/n:5/ DeterministicHybrid/n:26/ DeterministicHybridFloor/n:26/
StochasticHybrid/n:5/ StochasticHybridFloor/n:5/ StochasticHybrid/n:26/ StochasticHybridFloor/n:26/
MPPI/n:5/ MPPIFloor/n:5/ MPPI/n:26/ MPPIFloor/n:26/
SacUpdate/n:5/ SacUpdateFloor/n:5/ ModelUpdate/n:5/ ModelUpdateFloor/n:5/ AgentStepFloor/n:5/"
for r in $(seq 1 $R); do
  for n in $names; do
    taskset -c 1 $BIN --benchmark_filter="^$n" --benchmark_repetitions=3 --benchmark_min_time=0.3 \
      --benchmark_report_aggregates_only=true 2>/dev/null | awk -v r=$r '/_median/ {print r, $1, $2, $3}'
  done
done | tee $OUT
