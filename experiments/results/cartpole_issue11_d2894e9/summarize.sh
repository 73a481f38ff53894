#!/bin/sh
# summary.txt of this folder (../../analysis/sweep_summary.sh on every sweep folder here). Run from anywhere.
d="$(dirname "$0")"
"$d/../../analysis/sweep_summary.sh" "$d" mu20_100 mu20_110 e5_100 e5_110 e5_115 e5p03_100 e5_09 e5_20
