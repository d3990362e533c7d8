#!/usr/bin/env bash
# The generalisation windows of the reconstructor issue: scenes and paths `adaptive` was
# not tuned on, every equal-budget method at 100K, 400K and 800K samples/s, 256x256,
# 60 Hz, seed 1. Each window is run twice (the adaptive variants, then the other
# methods), and only the two summary.json files are kept; cells.py compares them.
# Run from the repository root: BART=../shared/scenes/bart bash docs/results/generalisation/run.sh
set -euo pipefail
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
here=docs/results/generalisation
paths=assets/camera_paths
ours=adaptive,adaptive-no-reprojection
others=framed-60hz,framed-full,traditional-frameless,point-tracking,taa,late-warp,taa-warp
tmp=$(mktemp -d)
run() {
  local name=$1; shift
  mkdir -p "$here/$name"
  "$bin" eval "$@" --rate 100k,400k,800k --method "$ours" --out "$tmp/$name-a"
  "$bin" eval "$@" --rate 100k,400k,800k --method "$others" --out "$tmp/$name-o"
  cp "$tmp/$name-a/summary.json" "$here/$name/adaptive.json"
  cp "$tmp/$name-o/summary.json" "$here/$name/others.json"
}
run demo --scene toycar
run room --scene room --camera-path "$paths/room_still.csv" --warmup 4 --duration 0.5 --ideal-spp 64
run m5 --scene "$bart/museum/museum5.aff" --start 4 --duration 1
run gl --scene "$bart/kitchen/kitchen.aff" --camera-path "$paths/kitchen_glance.csv" --start 1 --duration 2.5
run m4 --scene "$bart/museum/museum4.aff" --start 2.5 --duration 1
run m3 --scene "$bart/museum/museum3.aff" --start 2 --duration 1
for w in demo room m5 gl m4 m3; do
  NOABL=1 python3 "$here/cells.py" "$w=$here/$w/adaptive.json+$here/$w/others.json" | tail -n 3
done
