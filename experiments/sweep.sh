#!/usr/bin/env bash
# Trains several methods over several seeds on one environment, one run directory each:
#   experiments/sweep.sh --env cartpole_swingup --methods "sac hybrid-stochastic" --seeds "0 1 2" \
#       --steps 10000 --out results/cartpole_swingup [--jobs 2] [key=value ...]
# Runs that already finished are skipped and killed ones are resumed, so the sweep itself can be re-run.
set -euo pipefail
cd "$(dirname "$0")/.."
env_name=cartpole_swingup
methods="sac hybrid-stochastic hybrid-deterministic mppi mpc-deterministic"
seeds="0 1 2"
steps=""
out=""
jobs=1
overrides=()
while [ $# -gt 0 ]; do
  case "$1" in
    --env) env_name=$2; shift 2 ;;
    --methods) methods=$2; shift 2 ;;
    --seeds) seeds=$2; shift 2 ;;
    --steps) steps=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    *=*) overrides+=("$1"); shift ;;
    *) echo "sweep.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
out=${out:-results/$env_name}
train=${HLT_BUILD_DIR:-build}/experiments/hlt_train
[ -x "$train" ] || { echo "sweep.sh: $train not built (run ./scripts/build.sh)" >&2; exit 2; }

run_one() {
  local method=$1 seed=$2 dir="$out/$method/seed$seed"
  local step_args=()
  [ -n "$steps" ] && step_args=(--steps "$steps")
  if [ -f "$dir/config.yaml" ]; then
    "$train" --resume "$dir" "${step_args[@]}" --no-progress > "$dir.out" 2>&1
  else
    mkdir -p "$(dirname "$dir")"
    "$train" --env "$env_name" --method "$method" --seed "$seed" "${step_args[@]}" --out "$dir" --no-progress \
      "${overrides[@]}" > "$dir.out" 2>&1
  fi
  echo "$method seed $seed: $(tail -n 2 "$dir.out" | head -n 1)"
}

running=0
for method in $methods; do
  for seed in $seeds; do
    run_one "$method" "$seed" &
    running=$((running + 1))
    if [ "$running" -ge "$jobs" ]; then
      wait -n
      running=$((running - 1))
    fi
  done
done
wait
