#!/bin/sh
# Ant, seed 100, 4 demonstrations: the hybrid's planner on its learned models (H 20, H 60) and on the
# simulator's transitions scored by its learned reward model (H 60), for a run directory RUN.
RUN=$1
B=/work/runs/bin/hlt_rollout_rw
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
C="--env ant --policy checkpoint:$RUN/checkpoint.pt --controller stochastic_hybrid --max-steps 400 --seed 500"
taskset -c 0 $B $C --episodes 5 > ${RUN}_learned_h20.txt 2>&1
taskset -c 0 $B $C --episodes 5 planner.horizon=60 > ${RUN}_learned_h60.txt 2>&1
taskset -c 0 $B $C --episodes 3 --plan-on simulator-dynamics planner.horizon=60 > ${RUN}_simdyn_h60.txt 2>&1
