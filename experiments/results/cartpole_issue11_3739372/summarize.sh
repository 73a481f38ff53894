#!/bin/sh
# summary.txt of this folder (../../analysis/sweep_summary.sh on every sweep folder here). Run from anywhere.
d="$(dirname "$0")"
"$d/../../analysis/sweep_summary.sh" "$d" mu10_100 mu10_110 mu10_09 mu10_20 def_30 kg_20 sig01_100 sig01_110 \
  sig01_09 sig01_20 pn_100 pn_110 prior_100 ps0_100 ps0_110
