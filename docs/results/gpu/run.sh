#!/usr/bin/env bash
# The GPU reconstructor against the CPU one (the reference) on Table 1's Toycar and
# Interactive windows of the BART kitchen at 400K samples/s, and on museum3 with its
# own camera (a scene nothing was tuned on): the same run of `adaptive` rendered with
# `--recon cpu` and `--recon gpu`, its frames compared (compare.py), and `eval` of both
# for the mean RMS and FLIP against the ideal images. Run from the repository root:
#   BART=../shared/scenes/bart bash docs/results/gpu/run.sh
set -euo pipefail
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
out="${OUT:-docs/results/gpu}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
kitchen="$bart/kitchen/kitchen.aff"
paths=assets/camera_paths
windows=(
  "toycar|--scene $kitchen --camera-path $paths/kitchen_toycar.csv --start 9.5 --duration 3"
  "interactive|--scene $kitchen --camera-path $paths/kitchen_interactive.csv --start 5 --duration 3"
  "museum3|--scene $bart/museum/museum3.aff --start 2 --duration 3"
)
for w in "${windows[@]}"; do
  name="${w%%|*}"
  read -r -a args <<< "${w#*|}"
  for recon in cpu gpu; do
    "$bin" render --method adaptive --rate 400k "${args[@]}" --recon "$recon" --out "$work/$name-$recon"
    "$bin" eval --method adaptive --rate 400k "${args[@]}" --recon "$recon" --out "$work/eval-$name-$recon"
    mkdir -p "$out/$name-$recon"
    cp "$work/eval-$name-$recon/summary.json" "$work/eval-$name-$recon/summary.md" "$out/$name-$recon/"
  done
  python3 docs/results/gpu/compare.py "$work/$name-cpu" "$work/$name-gpu" > "$out/$name-frames.txt"
  tail -n 1 "$out/$name-frames.txt"
done
