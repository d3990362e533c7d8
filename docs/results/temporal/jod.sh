#!/usr/bin/env bash
# ColorVideoVDP's JOD beside RMS, FLIP and the sustained and transient errors: the
# first second of each of Table 1's four animations at 400K (every method Table 1
# runs), scored by `python -m frameless.vdp` (the extra frameless[vdp]) and kept as
# each folder's summary.json and vdp.json. Run from the repository root with a Python
# that has `frameless[vdp]` installed:
#   BART=../shared/scenes/bart PYTHON=/path/to/venv/bin/python bash docs/results/temporal/jod.sh
# PARTS (default "table1 m5 m4 gl demo room m3") picks what runs; T1_DURATION (default
# 1) is the length of Table 1's windows, kept in jod_<T1_DURATION>s/ (3 is Table 1's
# own: about 50 minutes on 2 cores).
set -euo pipefail
parts=" ${PARTS:-table1 m5 m4 gl demo room m3} "
want() { [[ "$parts" == *" $1 "* ]]; }
bart="${BART:-../shared/scenes/bart}"
bin="${FRAMELESS:-target/release/frameless}"
py="${PYTHON:-python3}"
t1="${T1_DURATION:-1}"
here=docs/results/temporal/jod_${t1}s
paths=assets/camera_paths
want table1 && "$bin" table1 --bart "$bart" --rate 400k --duration "$t1" --strips none --out "$here"
want table1 && for a in interactive bart toycar still; do
  cam=()
  if [ "$a" != bart ]; then cam=(--camera-path "$paths/kitchen_$a.csv"); fi
  "$py" -m frameless.vdp "$here/$a" --scene "$bart/kitchen/kitchen.aff" "${cam[@]}"
  "$bin" report "$here/$a"
done
# The generalisation windows of ../generalisation/run.sh at 100K and 400K: museum5
# t = 4–5 s (held out from tuning), museum4 t = 2.5–3.5 s, the kitchen glance
# t = 1–3.5 s, the README demo (built-in toycar, t = 0–1 s), the still room and museum3
# t = 2–3 s; that script's evaluations again (the seed fixes every image), scored the
# same way, each window's summary and vdp.json kept in its folder (about 5, 5 and 19
# minutes on 2 cores for the first three).
methods=framed-60hz,framed-full,traditional-frameless,point-tracking,taa,late-warp,taa-warp,adaptive,adaptive-paper,adaptive-no-reprojection
tmp=$(mktemp -d)
window() {
  local name=$1; shift
  want "$name" || return 0
  mkdir -p "docs/results/temporal/$name"
  "$bin" eval "$@" --rate 100k,400k --method "$methods" --out "$tmp/$name"
  local scene=() cam=()
  while [ $# -gt 0 ]; do
    case $1 in --scene) scene=(--scene "$2"); shift;; --camera-path) cam=(--camera-path "$2"); shift;; esac
    shift
  done
  "$py" -m frameless.vdp "$tmp/$name" "${scene[@]}" "${cam[@]}"
  cp "$tmp/$name/summary.json" "$tmp/$name/summary.md" "$tmp/$name/vdp.json" "docs/results/temporal/$name/"
}
window m5 --scene "$bart/museum/museum5.aff" --start 4 --duration 1
window m4 --scene "$bart/museum/museum4.aff" --start 2.5 --duration 1
window gl --scene "$bart/kitchen/kitchen.aff" --camera-path "$paths/kitchen_glance.csv" --start 1 --duration 2.5
window demo --scene toycar
window room --scene room --camera-path "$paths/room_still.csv" --warmup 4 --duration 0.5 --ideal-spp 64
window m3 --scene "$bart/museum/museum3.aff" --start 2 --duration 1
python3 docs/results/temporal/tables.py docs/results/temporal > docs/results/temporal/tables.md
