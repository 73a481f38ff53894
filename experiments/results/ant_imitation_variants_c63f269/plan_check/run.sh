# hlt_rollout --plan-check on the final checkpoints of the runs of ../sweep.yaml (RUNS: their results tree),
# one 400-step episode from reset seed 500 per seed, every 5th planning call checked. Run from the repository
# root; summary.txt is experiments/analysis/plan_check_summary.py on this folder.
RUNS=${RUNS:-results/ant_hi_variants}
OUT=$(dirname "$0")
for s in 100 101 102 103 104; do
  OPENBLAS_CORETYPE=SkylakeX build/experiments/hlt_rollout --env ant --policy checkpoint:$RUNS/ant/hybrid-imitation/seed$s/checkpoint.pt \
    --controller stochastic_hybrid --plan-check 5 --episodes 1 --max-steps 400 --seed 500 > $OUT/ant_s$s.txt
done
