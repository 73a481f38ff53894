#!/usr/bin/env bash
# Trains several methods over several seeds on one environment, one run directory each:
#   experiments/sweep.sh --env cartpole_swingup --methods "sac hybrid-stochastic" --seeds "0 1 2" \
#       --steps 10000 --out results/cartpole_swingup [--jobs 2] [key=value ...]
#   experiments/sweep.sh --status --out results/cartpole_swingup [--methods ...] [--seeds ...]
# Runs that already finished are skipped and killed ones are resumed, so the sweep itself can be re-run; a
# run that another process is writing (its directory is locked) is left alone and reported as running.
# Every failure is reported, the other runs go on, and the sweep exits 1 if any run failed. Interrupting
# the sweep (Ctrl-C, SIGTERM) stops its runs too; they resume on the next call.
set -uo pipefail
cd "$(dirname "$0")/.."
env_name=cartpole_swingup
methods="sac hybrid-stochastic hybrid-deterministic mppi mpc-deterministic"
seeds="0 1 2"
steps=""
out=""
jobs=1
status_only=0
overrides=()
while [ $# -gt 0 ]; do
  case "$1" in
    --env) env_name=$2; shift 2 ;;
    --methods) methods=$2; shift 2 ;;
    --seeds) seeds=$2; shift 2 ;;
    --steps) steps=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --status) status_only=1; shift ;;
    *=*) overrides+=("$1"); shift ;;
    *) echo "sweep.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
out=${out:-results/$env_name}
train=${HLT_BUILD_DIR:-build}/experiments/hlt_train
[ -x "$train" ] || { echo "sweep.sh: $train not built (run ./scripts/build.sh)" >&2; exit 2; }

# A run's state from its directory: missing, running (its lock is held), finished (final.pt, not running),
# killed (started, not running, no final.pt).
run_state() {
  local dir=$1
  if [ ! -f "$dir/config.yaml" ]; then echo missing; return; fi
  if [ -f "$dir/.lock" ] && ! flock -n "$dir/.lock" true 2>/dev/null; then echo running; return; fi
  if [ -f "$dir/final.pt" ]; then echo finished; else echo killed; fi
}

progress() {
  local dir=$1 last
  last=$(grep ',train/agent_steps,' "$dir/scalars.csv" 2>/dev/null | tail -n 1 | cut -d, -f4)
  echo "${last:-0}"
}

if [ "$status_only" = 1 ]; then
  for method in $methods; do
    for seed in $seeds; do
      dir="$out/$method/seed$seed"
      printf '%-24s seed %-4s %-9s %s agent steps\n' "$method" "$seed" "$(run_state "$dir")" "$(progress "$dir")"
    done
  done
  exit 0
fi

# One run: new, resumed, or left alone when another process is writing it. Prints one line of outcome.
run_one() {
  local method=$1 seed=$2 dir="$out/$method/seed$seed"
  local step_args=()
  [ -n "$steps" ] && step_args=(--steps "$steps")
  mkdir -p "$(dirname "$dir")"
  local state code=0
  state=$(run_state "$dir")
  if [ "$state" = running ]; then
    echo "$method seed $seed: running elsewhere (left alone)"
    return 0
  fi
  if [ "$state" != missing ]; then
    "$train" --resume "$dir" "${step_args[@]}" --no-progress > "$dir.out" 2>&1 || code=$?
  else
    "$train" --env "$env_name" --method "$method" --seed "$seed" "${step_args[@]}" --out "$dir" --no-progress \
      "${overrides[@]}" > "$dir.out" 2>&1 || code=$?
  fi
  if [ "$code" -ne 0 ]; then
    echo "$method seed $seed: FAILED (exit $code): $(grep -m1 'error:' "$dir.out" || tail -n 1 "$dir.out")"
    return 1
  fi
  echo "$method seed $seed: $(grep '^done:' "$dir.out" | tail -n 1)"
}

pids=()
stop_runs() {
  echo "sweep.sh: interrupted; stopping its runs (they resume on the next call)" >&2
  [ ${#pids[@]} -gt 0 ] && kill "${pids[@]}" 2>/dev/null
  wait
  exit 130
}
trap stop_runs INT TERM

failed=0
running=0
for method in $methods; do
  for seed in $seeds; do
    run_one "$method" "$seed" &
    pids+=($!)
    running=$((running + 1))
    if [ "$running" -ge "$jobs" ]; then
      wait -n || failed=$((failed + 1))
      running=$((running - 1))
    fi
  done
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=$((failed + 1))
  running=$((running - 1))
done
if [ "$failed" -gt 0 ]; then
  echo "sweep.sh: $failed run(s) failed (see the .out file beside each run directory)" >&2
  exit 1
fi
