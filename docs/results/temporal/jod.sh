#!/usr/bin/env bash
# ColorVideoVDP's JOD beside RMS, FLIP and the sustained and transient errors: the
# first second of each of Table 1's four animations at 400K (every method Table 1
# runs), scored by `python -m frameless.vdp` (the extra frameless[vdp]) and kept as
# each folder's summary.json and vdp.json. Run from the repository root with a Python
# that has `frameless[vdp]` installed:
#   BART=../shared/scenes/bart PYTHON=/path/to/venv/bin/python bash docs/results/temporal/jod.sh
set -euo pipefail
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
py="${PYTHON:-python3}"
here=docs/results/temporal/jod_1s
paths=assets/camera_paths
"$bin" table1 --bart "$bart" --rate 400k --duration 1 --strips none --out "$here"
for a in interactive bart toycar still; do
  cam=()
  if [ "$a" != bart ]; then cam=(--camera-path "$paths/kitchen_$a.csv"); fi
  "$py" -m frameless.vdp "$here/$a" --scene "$bart/kitchen/kitchen.aff" "${cam[@]}"
  "$bin" report "$here/$a"
done
# museum5 t = 4–5 s, held out from tuning, at 100K and 400K: run.sh's evaluation again
# (the seed fixes every image), scored the same way; its vdp.json is kept beside
# run.sh's summary.json.
methods=framed-60hz,framed-full,traditional-frameless,point-tracking,taa,late-warp,taa-warp,adaptive,adaptive-paper,adaptive-no-reprojection
tmp=$(mktemp -d)
"$bin" eval --scene "$bart/museum/museum5.aff" --start 4 --duration 1 --rate 100k,400k --method "$methods" --out "$tmp/m5"
"$py" -m frameless.vdp "$tmp/m5" --scene "$bart/museum/museum5.aff"
cp "$tmp/m5/vdp.json" docs/results/temporal/m5/vdp.json
