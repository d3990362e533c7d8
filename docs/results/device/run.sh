#!/usr/bin/env bash
# The figures the open issues ask of a machine with a GPU and 16 cores, in one run of
# under 10 minutes, for a session that is lent one (the device tool). The machine has no
# network: build the release binary here first and carry it, e.g.
#   cargo build --release --bin frameless && strip -o target/frameless-stripped target/release/frameless
# then, on the device: FRAMELESS=target/frameless-stripped bash docs/results/device/run.sh
# Results go to $OUT (the device tool's folder), one file or folder per figure:
# - machine.txt: cores, memory, GPU;
# - bench_live_recon.json: the reconstructor's cost per image at live rates, one core
#   (issue 45's bench table);
# - bench_gpu.json: `frameless bench --recon gpu` (the GPU reconstructor's figures, or
#   why it could not measure them);
# - live_<size>_<cores>/: `frameless live` of adaptive against traditional frameless at
#   640x480 and 1280x720 on 4, 8 and 16 cores (issue 45's scaling: new images/s,
#   samples/s, the image thread's share), one run each, 4-spp ideal images to keep the
#   whole under the time limit;
# - live_1920x1080_all/: the 1920x1080 live case at 30 Hz on every core.
set -uo pipefail
bin="${FRAMELESS:-target/release/frameless}"
out="${OUT:-/tmp/device-out}"
cache="$(mktemp -d)"
mkdir -p "$out"
[ -x "$bin" ] || { echo "error: $bin not found: build and carry the release binary" >&2; exit 1; }

{
  echo "cores: $(nproc)"
  free -g | head -2
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>&1 || echo "nvidia-smi: none"
  ls /usr/share/vulkan/icd.d/ 2>&1
} > "$out/machine.txt"

# One core: the reconstructor's cost per image (about 4 minutes here, less there).
timeout 300 taskset -c 0 "$bin" bench --live-recon --json > "$out/bench_live_recon.json" 2> "$out/bench_live_recon.log"

# The GPU reconstructor, where wgpu finds the GPU (a missing Vulkan driver is reported).
timeout 120 "$bin" bench --recon gpu --json > "$out/bench_gpu.json" 2> "$out/bench_gpu.log"

# Scaling of live adaptive against traditional frameless.
for size in 640x480 1280x720; do
  for n in 4 8 16; do
    [ "$n" -le "$(nproc)" ] || continue
    timeout 100 taskset -c "0-$((n - 1))" "$bin" --threads "$n" live --scene toycar \
      --size "$size" --refresh-hz 30 --start 1 --seconds 2 --repeat 1 --ideal-spp 4 \
      --method adaptive,traditional-frameless --cache-dir "$cache" \
      --out "$out/live_${size}_${n}" > "$out/live_${size}_${n}.log" 2>&1
  done
done
# Issue 45's new live case: 1920x1080 at 30 Hz on every core, against the best others.
timeout 150 "$bin" --threads "$(nproc)" live --scene toycar --size 1920x1080 --refresh-hz 30 \
  --start 1 --duration 2 --repeat 1 --ideal-spp 4 \
  --method adaptive,traditional-frameless,late-warp --cache-dir "$cache" \
  --out "$out/live_1920x1080_all" > "$out/live_1920x1080_all.log" 2>&1
echo "done: $out"
