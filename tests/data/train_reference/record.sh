#!/usr/bin/env bash
# Records this folder's reference logs with the hlt_train given (README.md here says what they are). Run it
# with a build of the code the comparison is against, e.g. after a merge that changes the learners'
# arithmetic: a build of the branch merged into, before the merge.
#   tests/data/train_reference/record.sh path/to/hlt_train [output dir, default this folder]
set -euo pipefail
train=${1:?usage: record.sh HLT_TRAIN [OUT]}
out=${2:-$(cd "$(dirname "$0")" && pwd)}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
args=(--env pendulum --seed 3 train.update_after=64 train.batch_size=32 model.hidden=32 model.reward_hidden=32
      'sac.q_hidden=[32,32]' planner.samples=8 eval.episodes=1 --no-progress eval.every=100 checkpoint.every=100)
for method in sac hybrid-stochastic hybrid-deterministic mppi mpc-deterministic; do
  "$train" "${args[@]}" --method "$method" --steps 400 --out "$work/$method" > /dev/null
  awk -F, 'NR > 1 && $3 !~ /^time\// {print $2 "," $3 "," $4}' "$work/$method/scalars.csv" > "$out/$method.csv"
done
# old_checkpoint/ stays as an older version of the code wrote it; what this code logs when it resumes it:
cp -r "$(dirname "$0")/old_checkpoint" "$work/old"
"$train" --resume "$work/old" --steps 400 --no-progress > /dev/null 2>&1
awk -F, 'NR > 1 && $3 !~ /^time\// {print $2 "," $3 "," $4}' "$work/old/scalars.csv" > "$out/old_checkpoint_resumed.csv"
# config.yaml's first line: "# blas: <OpenBLAS config>, core <core> (<origin>); vector: <instruction set>".
blas=$(head -1 "$work/sac/config.yaml")
vector=${blas##*; vector: }
config=${blas#\# blas: }
config=${config%%, core *}
core=${blas##*, core }
core=${core%% *}
printf 'core %s\nconfig %s\nvector %s\n' "$core" "$config" "$vector" > "$out/kernel.txt"
echo "recorded into $out with $train"
