#!/usr/bin/env bash
# Regenerates the real-time measurements in this folder (README.md says what they mean).
# Usage: docs/results/realtime/run.sh /path/to/bart [seconds]
# Needs a release build (cargo build --release) and python3 for the tables.
set -euo pipefail
BART=${1:?usage: run.sh /path/to/bart [seconds]}
SECS=${2:-8}
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=${FRAMELESS_BIN:-$HERE/../../../target/release/frameless}
KITCHEN=$BART/kitchen/kitchen.aff
OUT=${OUT:-$HERE/runs}
rm -rf "$OUT"
mkdir -p "$OUT"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$OUT/load.txt"
# Table 1 shape: sampling threads vs. sampling / reconstruction time and FPS, kitchen
# 256x256 with its camera moving (from t = 0), adaptive method.
for n in 1 2 4 8; do
  "$BIN" view --headless --seconds "$SECS" --scene "$KITCHEN" --size 256x256 \
    --sampling-threads "$n" --images 2 --out "$OUT/kitchen_t$n"
done
# Throughput targets: kitchen 256x256 at 60 Hz, toycar 640x480 at 30 Hz, each method,
# with the camera turned 20 degrees half way (--camera-step) to time the latency.
for m in adaptive traditional-frameless framed late-warp taa taa-warp; do
  "$BIN" view --headless --seconds "$SECS" --scene "$KITCHEN" --size 256x256 \
    --method "$m" --images 1 --camera-step "$(awk "BEGIN { print $SECS / 2 }")" --out "$OUT/kitchen_$m"
  "$BIN" view --headless --seconds "$SECS" --scene toycar --size 640x480 --start 1 \
    --refresh-hz 30 --method "$m" --images 1 --camera-step "$(awk "BEGIN { print $SECS / 2 }")" \
    --out "$OUT/toycar640_$m"
done
# The adaptive image budget off (--image-budget 0): every image reconstructs the whole
# ring, as before session 10.
"$BIN" view --headless --seconds "$SECS" --scene "$KITCHEN" --size 256x256 \
  --method adaptive --image-budget 0 --images 1 --out "$OUT/kitchen_adaptive-nobudget"
"$BIN" view --headless --seconds "$SECS" --scene toycar --size 640x480 --start 1 \
  --refresh-hz 30 --method adaptive --image-budget 0 --images 1 --out "$OUT/toycar640_adaptive-nobudget"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/load.txt"
python3 "$HERE/table.py" "$OUT"
