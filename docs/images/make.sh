#!/usr/bin/env bash
# Regenerates the still images in this folder. Usage: docs/images/make.sh /path/to/bart
# (the folder holding kitchen/ and museum/). Run from the repository root.
set -euo pipefail
BART=${1:?usage: docs/images/make.sh /path/to/bart}
F="cargo run --release --quiet --"
OPT="--size 400x300 --spp 16"
for t in 0 5 10 15; do
  $F still --scene "$BART/kitchen/kitchen.aff" --time $t $OPT --out docs/images/kitchen_t$t.png
done
for t in 5 7 9; do
  $F still --scene "$BART/kitchen/kitchen.aff" --camera-path docs/images/kitchen_fixed_camera.csv --time $t $OPT --out docs/images/kitchen_fixed_t$t.png
done
$F still --scene "$BART/kitchen/kitchen.aff" --camera-path docs/images/kitchen_plate_camera.csv --time 12 $OPT --out docs/images/kitchen_plate.png
$F still --scene "$BART/museum/museum5.aff" --time 2 $OPT --out docs/images/museum5_t2.png
for s in toycar room terrain; do
  $F still --scene $s --time 2 $OPT --out docs/images/$s.png
done
