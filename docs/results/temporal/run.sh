#!/usr/bin/env bash
# Sustained and transient errors (lag told apart from flicker) beside RMS and FLIP:
# Table 1's four animations at 400K, and four generalisation windows at 100K and 400K,
# every equal-budget method (Table 1: its default methods); then tables.py writes the tables of README.md.
# Run from the repository root: BART=../shared/scenes/bart bash docs/results/temporal/run.sh
set -euo pipefail
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
here=docs/results/temporal
paths=assets/camera_paths
methods=framed-60hz,framed-full,traditional-frameless,point-tracking,taa,late-warp,taa-warp,adaptive,adaptive-paper,adaptive-no-reprojection
tmp=$(mktemp -d)
"$bin" table1 --bart "$bart" --rate 400k --strips none --out "$here/table1_400k"
gen() {
  local name=$1; shift
  mkdir -p "$here/$name"
  "$bin" eval "$@" --rate 100k,400k --method "$methods" --out "$tmp/$name"
  cp "$tmp/$name/summary.json" "$tmp/$name/summary.md" "$here/$name/"
}
gen m5 --scene "$bart/museum/museum5.aff" --start 4 --duration 1
gen m4 --scene "$bart/museum/museum4.aff" --start 2.5 --duration 1
gen gl --scene "$bart/kitchen/kitchen.aff" --camera-path "$paths/kitchen_glance.csv" --start 1 --duration 2.5
python3 "$here/tables.py" "$here" > "$here/tables.md"
