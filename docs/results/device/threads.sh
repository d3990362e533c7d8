#!/usr/bin/env bash
# Why adaptive's images slow down on many cores: the reconstructor alone at 1280x720
# on 1, 4 and 8 threads (examples/live_recon: the camera turning with the ring
# re-splatted, turning with sums carried, and still), then `view --headless` at
# 1280x720, 30 Hz with the sampling and reconstruction threads split in several ways.
# Build and carry, as for run.sh:
#   cargo build --release --bin frameless --example live_recon
#   strip -o target/frameless-stripped target/release/frameless
#   strip -o target/live_recon-stripped target/release/examples/live_recon
# then on the device: bash docs/results/device/threads.sh > $OUT/threads.log 2>&1
set -uo pipefail
bin="${FRAMELESS:-target/frameless-stripped}"
ex="${LIVE_RECON:-target/live_recon-stripped}"
cd "$(mktemp -d)" || exit 1
repo="$OLDPWD"
for t in 1 4 8; do
  for mode in ring carried still; do
    arg=""; [ "$mode" = ring ] || arg="$mode"
    echo -n "live_recon 1280x720 4M/s 30Hz ring 2spp $mode threads=$t: "
    RAYON_NUM_THREADS=$t timeout 60 "$repo/$ex" 1280 720 4e6 30 2 $arg
  done
done
for split in 16:8 16:1 15:1 12:4 8:8; do
  s="${split%:*}"; r="${split#*:}"
  echo "view headless 1280x720 30Hz sampling=$s recon=$r:"
  timeout 40 "$repo/$bin" view --headless --size 1280x720 --refresh-hz 30 --duration 3 \
    --method adaptive --sampling-threads "$s" --recon-threads "$r" 2>&1 | grep -v '^wrote'
  python3 -c 'import json; p = json.load(open("view-out/stats.json")).get("pipeline", {}); print("  pass_ms:", {k: round(v, 1) for k, v in p.get("pass_ms", {}).items()}, "placed_mean:", round(p.get("placed_mean", 0)))' 2>&1
done
