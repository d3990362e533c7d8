#!/usr/bin/env bash
# The committed live tables: every real-time method, three runs each in alternation,
# on the kitchen's three Table 1 windows (256x256, 60 Hz), the built-in toycar at
# 640x480 and 1280x720 at 30 Hz, and museum4 with its own camera while it flies, t = 2.5-5.5 s (a
# scene no method was tuned on; its camera stops at 5.5 s); and toycar at 1920x1080,
# 30 Hz, against traditional frameless and late warp only, with 4-spp ideals (all
# methods, each frame's FLIP at 1080p and 16-spp ideals do not fit a 2-core session).
# Run from the repository root on a quiet machine:
#   BART=../shared/scenes/bart bash docs/results/live/run.sh
set -euo pipefail
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
out="${OUT:-docs/results/live}"
kitchen="$bart/kitchen/kitchen.aff"
paths=assets/camera_paths
run() { local name=$1; shift; "$bin" live --repeat 3 --out "$out/$name" "$@"; }
run kitchen_interactive --scene "$kitchen" --camera-path "$paths/kitchen_interactive.csv" --start 5
run kitchen_bart --scene "$kitchen" --start 4.5
run kitchen_toycar --scene "$kitchen" --camera-path "$paths/kitchen_toycar.csv" --start 9.5
run toycar_640x480 --scene toycar --size 640x480 --refresh-hz 30 --start 1
run toycar_1280x720 --scene toycar --size 1280x720 --refresh-hz 30 --start 1
run museum4 --scene "$bart/museum/museum4.aff" --start 2.5
run toycar_1920x1080 --scene toycar --size 1920x1080 --refresh-hz 30 --start 1 \
  --ideal-spp 4 --method adaptive,traditional-frameless,late-warp
