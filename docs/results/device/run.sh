#!/usr/bin/env bash
# The figures the open issues ask of a machine with a GPU and 16 cores, in one run of
# under 9 minutes, for a session that is lent one (the device tool). The machine has no
# network and no Vulkan loader: build the release binary here, fetch the loaders once as
# the device tool's README says (into .gl/, ignored), and carry both:
#   cargo build --release --bin frameless && strip -o target/frameless-stripped target/release/frameless
# then, on the device, with carry [".gl", "target/frameless-stripped"]:
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
#   FRAMELESS=target/frameless-stripped bash docs/results/device/run.sh
# Only eight files come back from the device, so everything is written under a work
# folder and packed into $OUT/results.tar.gz (images left out), with run.log beside it:
# - machine.txt: cores, memory, GPU, Vulkan loader;
# - live_<size>_<cores>/: `frameless live` of adaptive against traditional frameless at
#   640x480 and 1280x720 on 4, 8 and 16 cores (the scaling the image-cost issue asks for:
#   new images/s, samples/s, the image thread's share), 4-spp ideals to fit the time;
# - live_1920x1080_all/: 1920x1080 at 30 Hz on every core against the best others;
# - live_<size>_gpurecon/: adaptive with the reconstructor on the GPU (`--recon gpu`),
#   to tell whether the image thread stops being the first bottleneck;
# - bench_gpu.json: `frameless bench --recon gpu`.
# Steps run in order of value and each is cut to what is left of the time budget.
set -uo pipefail
bin="${FRAMELESS:-target/release/frameless}"
out="${OUT:-/tmp/device-out}"
work="$(mktemp -d)"
cache="$work/ideal-cache"
budget="${BUDGET_S:-500}"
mkdir -p "$out" "$cache"
[ -x "$bin" ] || { echo "error: $bin not found: build and carry the release binary" >&2; exit 1; }
start=$SECONDS

# step NAME MAX_SECONDS COMMAND...: run with a timeout of at most what is left.
step() {
  local name="$1" max="$2"; shift 2
  local left=$((budget - (SECONDS - start)))
  local t=$((max < left ? max : left))
  if [ "$t" -lt 15 ]; then echo "skipped $name: time budget spent"; return; fi
  local t0=$SECONDS
  timeout "$t" "$@" > "$work/$name.log" 2>&1
  echo "$name: exit $? in $((SECONDS - t0)) s (limit $t s)"
}

{
  echo "cores: $(nproc)"
  lscpu | grep -E 'Model name|MHz' | head -3
  free -g | head -2
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>&1 || echo "nvidia-smi: none"
  ldconfig -p | grep -i libvulkan || echo "no Vulkan loader"
  ls /usr/share/vulkan/icd.d/ /usr/local/nvidia/share/vulkan/icd.d/ 2>&1
} > "$work/machine.txt"

live() { # live NAME CORES ARGS...
  local name="$1" n="$2"; shift 2
  step "$name" 110 taskset -c "0-$((n - 1))" "$bin" --threads "$n" live --scene toycar \
    --refresh-hz 30 --start 1 --duration 2 --warmup 1 --repeat 1 --ideal-spp 4 \
    --cache-dir "$cache" -o "$work/$name" "$@"
}

for size in 640x480 1280x720; do
  for n in 4 8 16; do
    [ "$n" -le "$(nproc)" ] || continue
    live "live_${size}_${n}" "$n" --size "$size" --method adaptive,traditional-frameless
  done
done
all=$(nproc)
live live_1920x1080_all "$all" --size 1920x1080 --method adaptive,traditional-frameless,late-warp
for size in 1280x720 1920x1080; do
  live "live_${size}_gpurecon" "$all" --size "$size" --method adaptive --recon gpu
done
step bench_gpu 90 "$bin" bench --recon gpu --json
cp "$work/bench_gpu.log" "$work/bench_gpu.json" 2>/dev/null

tar -C "$work" --exclude='*.png' --exclude='ideal-cache' -czf "$out/results.tar.gz" .
echo "done in $((SECONDS - start)) s: $out/results.tar.gz"
