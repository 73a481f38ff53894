#!/bin/sh
# After run_ant_ceiling.sh: hybrid imitation's own planner (learned models) on the same starts, and two
# planner settings on the simulator (sharper weights; a longer horizon), seed 100's 4-demonstration policy.
while pgrep -f run_ant_ceiling.sh > /dev/null; do sleep 20; done
B=/work/main/build/experiments/hlt_rollout
export OPENBLAS_CORETYPE=SkylakeX OMP_NUM_THREADS=1
/work/main/build/experiments/hlt_train --env ant --method hybrid-imitation --seed 100 --steps 4 --out ant_hi4_s100 imitation.eval_episodes=10 > ant_hi4_s100.log 2>&1
$B --env ant --policy checkpoint:ant_hi4_s100/checkpoint.pt --episodes 5 --max-steps 400 --seed 500 > ant_hi_mean_s100.txt 2>&1
$B --env ant --policy checkpoint:ant_hi4_s100/checkpoint.pt --controller stochastic_hybrid --episodes 5 --max-steps 400 --seed 500 > ant_hi_learned_s100.txt 2>&1
$B --env ant --policy checkpoint:ant_bc4_s100/checkpoint.pt --controller stochastic_hybrid --plan-on simulator --episodes 3 --max-steps 400 --seed 500 planner.lambda=0.1 > ant_sim_lambda0.1_s100.txt 2>&1
$B --env ant --policy checkpoint:ant_bc4_s100/checkpoint.pt --controller stochastic_hybrid --plan-on simulator --episodes 3 --max-steps 400 --seed 500 planner.horizon=60 > ant_sim_h60_s100.txt 2>&1
